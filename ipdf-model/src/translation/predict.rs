//! Inference with a translation model: `F` at any translations, the distribution over the
//! octree of the crop's volume ([`super::TranslationSpace::crop_volume`]) refined where the
//! mass is, `ln p(t | I)`, and the most likely translation by gradient ascent.
use nalgebra::Vector3;
use tch::{Kind, Tensor};

use super::geometry::translations_to_tensor;
use super::model::in_crop_span;
use super::{CropGeometry, TranslationPdf, WorkingVolume};
use crate::ModelError;
use crate::refine::{CellMasses, RefineOptions, refine_on};

/// Translations evaluated per network call.
const CHUNK: usize = 4_096;

/// Options of [`TranslationPredictor::argmax`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TranslationArgmaxOptions {
    /// The cell size (mm) of the hierarchical evaluation whose densest cells start the ascent
    /// ([`TranslationPredictor::refine_options`]).
    pub cell_size: f64,
    /// Number of starting cells (the densest ones).
    pub starts: usize,
    /// Gradient-ascent steps per start.
    pub steps: usize,
    /// First step length in mm (decays linearly to 0).
    pub step_size: f64,
}

impl TranslationArgmaxOptions {
    /// Checks for a finite cell size > 0, at least one start and a finite step ≥ 0.
    pub fn validate(&self) -> Result<(), ModelError> {
        let cell = self.cell_size.is_finite() && self.cell_size > 0.0;
        let step = self.step_size.is_finite() && self.step_size >= 0.0;
        if !cell || self.starts == 0 || !step {
            return Err(ModelError::option(
                "starts",
                format!(
                    "cells of {} mm, {} starts, step size {} mm: need cells > 0, ≥ 1 start and \
                     a finite step ≥ 0",
                    self.cell_size, self.starts, self.step_size
                ),
            ));
        }
        Ok(())
    }
}

impl Default for TranslationArgmaxOptions {
    /// Cells of at most 2 mm, 4 starts, 50 steps of at most 1 mm.
    fn default() -> Self {
        Self {
            cell_size: 2.0,
            starts: 4,
            steps: 50,
            step_size: 1.0,
        }
    }
}

/// The most likely translation found by [`TranslationPredictor::argmax`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TranslationArgmax {
    /// The translation, mm.
    pub translation: Vector3<f64>,
    /// `F` there.
    pub score: f64,
    /// `F` at the centre of the cell it started from.
    pub start_score: f64,
}

impl RefineOptions {
    /// The octree of `volume` evaluated densely at level 4 (4,096 cells), then refined where
    /// 99.99% of the mass is, down to cells of at most `cell_size` mm, in at most
    /// `4,096 + 4,096 · (level − 4)` queries.
    pub fn translation(volume: &super::WorkingVolume, cell_size: f64) -> Self {
        let level = volume.level_for_cell_size(cell_size).max(4);
        Self {
            start_level: 4,
            level,
            keep_mass: 0.9999,
            max_queries: 4_096 * (1 + usize::from(level - 4)),
        }
    }
}

/// Evaluates a translation model for one crop at a time.
pub struct TranslationPredictor<'m> {
    model: &'m TranslationPdf,
}

/// What [`TranslationPredictor`] computes once per crop: the image term `[1, H]` and the crop
/// factors `[1, 5]` ([`TranslationPredictor::crop_terms`]), for its `…_for` methods.
pub struct CropTerms {
    image: Tensor,
    factors: Tensor,
}

impl<'m> TranslationPredictor<'m> {
    /// A predictor for `model`, evaluated in inference mode.
    pub fn new(model: &'m TranslationPdf) -> Self {
        Self { model }
    }

    /// The box a crop's density is evaluated in ([`super::TranslationSpace::crop_volume`]).
    pub fn volume(&self, geometry: &CropGeometry) -> WorkingVolume {
        self.model.space().crop_volume(geometry)
    }

    /// [`RefineOptions::translation`] on a crop's volume: cells of at most `cell_size` mm.
    pub fn refine_options(&self, geometry: &CropGeometry, cell_size: f64) -> RefineOptions {
        RefineOptions::translation(&self.volume(geometry), cell_size)
    }

    /// The network's terms of one crop (`[3, S, S]` or `[1, 3, S, S]`) cut with `geometry`:
    /// computed once, scored against any number of translations.
    pub fn crop_terms(
        &self,
        image: &Tensor,
        geometry: &CropGeometry,
    ) -> Result<CropTerms, ModelError> {
        let batch = if image.dim() == 3 {
            image.unsqueeze(0)
        } else {
            image.shallow_clone()
        };
        let image = tch::no_grad(|| self.model.image_term(&batch, &[*geometry], false))?;
        Ok(CropTerms {
            image,
            factors: self.model.crop_factors(&[*geometry]),
        })
    }

    fn scores_for(
        &self,
        terms: &CropTerms,
        translations: &[Vector3<f64>],
    ) -> Result<Vec<f64>, ModelError> {
        let mut out = Vec::with_capacity(translations.len());
        for chunk in translations.chunks(CHUNK) {
            let queries = translations_to_tensor(chunk, self.model.device());
            let scores = tch::no_grad(|| {
                self.model.scores(
                    &terms.image,
                    &self.model.query_term(&queries, &terms.factors),
                )
            });
            out.extend(Vec::<f64>::try_from(scores.to_kind(Kind::Double))?);
        }
        Ok(out)
    }

    /// `F(t, I)` at each of `translations` (mm) for one crop (`[3, S, S]` or `[1, 3, S, S]`).
    pub fn scores(
        &self,
        image: &Tensor,
        geometry: &CropGeometry,
        translations: &[Vector3<f64>],
    ) -> Result<Vec<f64>, ModelError> {
        let terms = self.crop_terms(image, geometry)?;
        self.scores_for(&terms, translations)
    }

    /// The distribution over the octree of the crop's volume ([`Self::volume`], see
    /// [`refine_on`]; [`Self::refine_options`] for a cell size); masses sum to 1,
    /// `log_normaliser` is `ln ∫_V exp F` with `t` in mm.
    pub fn hierarchical(
        &self,
        image: &Tensor,
        geometry: &CropGeometry,
        options: &RefineOptions,
    ) -> Result<CellMasses, ModelError> {
        let terms = self.crop_terms(image, geometry)?;
        self.hierarchical_for(&terms, geometry, options)
    }

    /// [`Self::hierarchical`] for the crop's terms from [`Self::crop_terms`].
    pub fn hierarchical_for(
        &self,
        terms: &CropTerms,
        geometry: &CropGeometry,
        options: &RefineOptions,
    ) -> Result<CellMasses, ModelError> {
        let volume = self.volume(geometry);
        refine_on(
            &volume,
            |level, cells| {
                let centres = cells
                    .iter()
                    .map(|&index| volume.cell_centre(level, index))
                    .collect::<Result<Vec<_>, _>>()?;
                self.scores_for(terms, &centres)
            },
            options,
        )
    }

    /// `ln p(t | I)` (density per mm³) at each of `translations`, for the normaliser of a
    /// distribution of the same crop from [`TranslationPredictor::hierarchical`]: `F(t) − ln Z`.
    pub fn log_densities(
        &self,
        image: &Tensor,
        geometry: &CropGeometry,
        translations: &[Vector3<f64>],
        distribution: &CellMasses,
    ) -> Result<Vec<f64>, ModelError> {
        let terms = self.crop_terms(image, geometry)?;
        self.log_densities_for(&terms, translations, distribution)
    }

    /// [`Self::log_densities`] for the crop's terms from [`Self::crop_terms`].
    pub fn log_densities_for(
        &self,
        terms: &CropTerms,
        translations: &[Vector3<f64>],
        distribution: &CellMasses,
    ) -> Result<Vec<f64>, ModelError> {
        Ok(self
            .scores_for(terms, translations)?
            .into_iter()
            .map(|f| f - distribution.log_normaliser)
            .collect())
    }

    /// The centres (mm) of the cells of `distribution`, the hierarchical distribution of a crop
    /// cut with `geometry`.
    pub fn cell_centres(
        &self,
        distribution: &CellMasses,
        geometry: &CropGeometry,
    ) -> Result<Vec<Vector3<f64>>, ModelError> {
        let volume = self.volume(geometry);
        distribution
            .cells
            .iter()
            .map(|&(level, index)| volume.cell_centre(level, index))
            .collect()
    }

    /// The most likely translation: the densest cells of the hierarchical evaluation whose
    /// centres project near the crop ([`in_crop_span`]), each followed by gradient ascent on `F`
    /// (steps along the normalised gradient, their length decaying linearly from `step_size` mm
    /// to 0); the best point visited there. An object's centre projects into its crop, so a
    /// peak of `F` in the volume's corners far from the crop's rays, where no training object of
    /// such a crop lay, is not taken.
    pub fn argmax(
        &self,
        image: &Tensor,
        geometry: &CropGeometry,
        options: &TranslationArgmaxOptions,
    ) -> Result<TranslationArgmax, ModelError> {
        options.validate()?;
        let refine = self.refine_options(geometry, options.cell_size);
        let terms = self.crop_terms(image, geometry)?;
        let masses = self.hierarchical_for(&terms, geometry, &refine)?;
        self.argmax_from(&terms, geometry, &masses, options)
    }

    /// [`Self::argmax`] from the crop's terms ([`Self::crop_terms`]) and its hierarchical
    /// distribution `masses`, already evaluated (with [`Self::refine_options`] for
    /// `options.cell_size`): the same result without evaluating either again.
    pub fn argmax_from(
        &self,
        terms: &CropTerms,
        geometry: &CropGeometry,
        masses: &CellMasses,
        options: &TranslationArgmaxOptions,
    ) -> Result<TranslationArgmax, ModelError> {
        options.validate()?;
        let volume = self.volume(geometry);
        let possible = |t: &Vector3<f64>| volume.contains(t) && in_crop_span(geometry, t);
        let by_density = masses
            .densest_in(&volume, masses.cells.len())
            .into_iter()
            .map(|position| {
                let (level, index) = masses.cells[position];
                volume.cell_centre(level, index)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut starts: Vec<_> = by_density
            .iter()
            .filter(|t| possible(t))
            .take(options.starts)
            .copied()
            .collect();
        if starts.is_empty() {
            // No cell centre near the crop (cells wider than its span): the densest anywhere.
            starts = by_density.into_iter().take(options.starts).collect();
        }
        let start_scores = self.scores_for(terms, &starts)?;
        let (mut best, mut best_scores) = (starts.clone(), start_scores.clone());
        let device = self.model.device();
        let mut position = translations_to_tensor(&starts, device)
            .to_kind(Kind::Double)
            .set_requires_grad(true);
        for step in 0..=options.steps {
            let scores = self.model.scores(
                &terms.image,
                &self
                    .model
                    .query_term(&position.to_kind(self.model.kind()), &terms.factors),
            );
            let values = Vec::<f64>::try_from(scores.to_kind(Kind::Double).detach())?;
            let current = Vec::<f64>::try_from(position.detach().reshape([-1]))?;
            for (i, &value) in values.iter().enumerate() {
                let t = Vector3::new(current[3 * i], current[3 * i + 1], current[3 * i + 2]);
                if value > best_scores[i] && possible(&t) {
                    best_scores[i] = value;
                    best[i] = t;
                }
            }
            if step == options.steps {
                break;
            }
            position.zero_grad();
            scores.sum(Kind::Float).backward();
            let length = options.step_size * (1.0 - step as f64 / options.steps as f64);
            tch::no_grad(|| {
                let grad = position.grad();
                let norm = grad.norm_scalaropt_dim(2.0, [1].as_slice(), true) + 1e-12;
                let mut p = position.shallow_clone();
                let _ = p.g_add_(&(grad / norm * length));
            });
        }
        let winner = (0..best.len())
            .max_by(|&a, &b| best_scores[a].total_cmp(&best_scores[b]))
            .unwrap_or(0);
        Ok(TranslationArgmax {
            translation: best[winner],
            score: best_scores[winner],
            start_score: start_scores[winner],
        })
    }
}
