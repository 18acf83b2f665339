//! The paper's scores of a rotation model on examples with ground truth: for each crop, the
//! normalised distribution on the grid (refined hierarchically, or dense), then LLH (mean
//! log-density over the ground-truth symmetry set), MAAD (expected distance of a sample to the
//! nearest ground-truth rotation) and Recall MAAD (mean distance of each ground-truth rotation
//! to the nearest predicted one), averaged over crops.
use bop_dataset::Progress;
use ipdf_metrics::{Distribution, GridCell, RECALL_THRESHOLD, maad, recall_maad};
use ipdf_model::rotation::{ArgmaxOptions, ImplicitPdf, Predictor};
use ipdf_model::{CellMasses, RefineOptions};
use nalgebra::UnitQuaternion;
use so3_grid::Grid;

use crate::Error;
use crate::plots::plot_distribution;
use crate::training_data::{Examples, crop_tensor, to_unit_floats};

/// Mean scores over the crops evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Crops evaluated.
    pub images: usize,
    /// Mean log-likelihood of the ground-truth set (−2.29 for a uniform density).
    pub llh: f64,
    /// Mean absolute angular deviation, degrees.
    pub maad_deg: f64,
    /// Recall mean absolute angular deviation, degrees.
    pub recall_maad_deg: f64,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
    /// How far the grid is from resolving the model's peaks
    /// ([`Predictor::under_resolution`]), the mean over crops.
    pub under_resolution: f64,
}

/// Scores `model` on every crop of `examples`, its distribution evaluated on the cells
/// `grid` describes ([`RefineOptions::to_level`] for the hierarchical evaluation,
/// [`RefineOptions::dense`] for every cell of a level); `progress` advances by one per crop.
/// LLH is the reference implementation's: the density `exp(F(R) − ln Z)` at each ground-truth
/// rotation itself, `Z` from the grid; MAAD and Recall MAAD come from the `metrics` crate on
/// the cells' masses. Fails when the examples have no ground truth.
pub fn evaluate(
    model: &ImplicitPdf,
    examples: &Examples,
    grid: &RefineOptions,
    progress: &dyn Progress,
) -> Result<Scores, Error> {
    Ok(evaluate_rotations(model, examples, grid, 0, Picks::default(), progress)?.scores)
}

/// Each crop's scores beside the means: what [`evaluate_rotations`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationEvaluation {
    /// The means over the crops.
    pub scores: Scores,
    /// Each crop's LLH (mean log-density over its ground-truth set).
    pub llh: Vec<f64>,
    /// Each crop's MAAD, degrees.
    pub maad_deg: Vec<f64>,
    /// Each crop's Recall MAAD, degrees.
    pub recall_maad_deg: Vec<f64>,
    /// Each crop's most likely rotation (empty unless asked for).
    pub argmax: Vec<UnitQuaternion<f64>>,
    /// Each crop's rotation hypotheses, the most likely first (empty unless asked for;
    /// [`ipdf_model::CellMasses::rotation_hypotheses`]).
    pub hypotheses: Vec<Vec<UnitQuaternion<f64>>>,
}

/// Which rotations [`evaluate_rotations`] picks from each crop's distribution beside its scores.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Picks {
    /// The most likely rotation.
    pub argmax: bool,
    /// This many rotation hypotheses (0: none; they start at the most likely rotation)…
    pub hypotheses: usize,
    /// …at least this far apart (radians).
    pub hypothesis_spacing: f64,
}

/// [`evaluate`], with each crop's LLH, MAAD and Recall MAAD, and the rotations `picks` asks
/// for: each crop's most likely rotation ([`Predictor::argmax_from`] on the same distribution),
/// its rotation hypotheses. Each crop's image term is computed once, averaged over the crop
/// and `views` test-time views of it ([`Predictor::with_views`]).
pub fn evaluate_rotations(
    model: &ImplicitPdf,
    examples: &Examples,
    grid: &RefineOptions,
    views: usize,
    picks: Picks,
    progress: &dyn Progress,
) -> Result<RotationEvaluation, Error> {
    let truths = examples.required_truth_sets()?;
    let mut predictor = Predictor::new(model).with_views(views)?;
    let argmax_options = ArgmaxOptions {
        refine: *grid,
        ..ArgmaxOptions::default()
    };
    let (mut queries, mut sum_under) = (0, 0.0);
    let (mut llh, mut rotations, mut hypotheses) = (Vec::new(), Vec::new(), Vec::new());
    let (mut maad_deg, mut recall_maad_deg) = (Vec::new(), Vec::new());
    for (i, truth) in truths.iter().enumerate() {
        let crop = to_unit_floats(&examples.crops.get(i as i64));
        let image_term = predictor.image_term(&crop)?;
        let masses = predictor.hierarchical_for(&image_term, grid)?;
        let densities = predictor.log_densities_for(&image_term, truth, &masses)?;
        llh.push(densities.iter().sum::<f64>() / densities.len().max(1) as f64);
        let distribution = cell_distribution(&masses)?;
        maad_deg.push(maad(&distribution, truth)?);
        recall_maad_deg.push(recall_maad(&distribution, truth, RECALL_THRESHOLD)?);
        sum_under += predictor.under_resolution_for(&image_term, &masses)?;
        queries = queries.max(masses.queries);
        if picks.argmax || picks.hypotheses > 0 {
            let best = predictor
                .argmax_from(&image_term, &masses, &argmax_options)?
                .rotation;
            if picks.hypotheses > 0 {
                hypotheses.push(masses.rotation_hypotheses(
                    best,
                    picks.hypotheses,
                    picks.hypothesis_spacing,
                )?);
            }
            if picks.argmax {
                rotations.push(best);
            }
        }
        progress.advance(1);
    }
    let n = truths.len().max(1) as f64;
    let mean = |values: &[f64]| values.iter().sum::<f64>() / n;
    let scores = Scores {
        images: truths.len(),
        llh: mean(&llh),
        maad_deg: mean(&maad_deg),
        recall_maad_deg: mean(&recall_maad_deg),
        queries_per_image: queries,
        under_resolution: sum_under / n,
    };
    Ok(RotationEvaluation {
        scores,
        llh,
        maad_deg,
        recall_maad_deg,
        argmax: rotations,
        hypotheses,
    })
}

/// The cells and masses of a (hierarchical or dense) evaluation as a `metrics` distribution.
pub fn cell_distribution(masses: &CellMasses) -> Result<Distribution, Error> {
    let cells = masses
        .cells
        .iter()
        .map(|&(level, index)| GridCell { level, index })
        .collect();
    Ok(Distribution::from_cells(cells, masses.masses.clone())?)
}

/// The Implicit-PDF figure of `model`'s distribution for an 8-bit crop (`[3, S, S]`) on the
/// `level` grid, its image term averaged over `views` test-time views, with `truth` drawn
/// over it.
pub fn distribution_figure(
    model: &ImplicitPdf,
    crop: &[u8],
    truth: &[nalgebra::UnitQuaternion<f64>],
    level: u8,
    views: usize,
    title: &str,
) -> Result<image::RgbImage, Error> {
    let size = model.config().input_size as usize;
    let grid = Grid::new(level).map_err(|e| Error::option("level", e.to_string()))?;
    let masses = Predictor::new(model)
        .with_views(views)?
        .probabilities(&crop_tensor(crop, size), level)?;
    plot_distribution(crop, size, &grid.rotations(), &masses, truth, title)
}
