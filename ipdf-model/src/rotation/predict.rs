//! Inference: `F` on whole grids (dense, chunked), hierarchically refined distributions, and
//! the most likely rotation by gradient ascent.
use std::collections::HashMap;

use nalgebra::{UnitQuaternion, Vector3};
use so3_grid::{Grid, cell_count};
use tch::{Kind, Tensor};

use super::ImplicitPdf;
use crate::ModelError;
use crate::encoding::{encode_rotations, rotations_to_tensor};
use crate::head::Head;
use crate::refine::{CellMasses, RefineOptions, refine};
use crate::rotation::views::{crop_views, validate_views};

/// Rotations evaluated per network call. Activations of `CHUNK · H` floats (4 MiB for H = 256)
/// stay in cache between layers: 4,096 took half the time of 32,768 (`make bench`,
/// `evaluate/dense_level4_*`), 1,024 no less than 4,096.
const CHUNK: usize = 4_096;

/// Query terms are cached per grid level up to this size in bytes (level 4 with H = 256 takes
/// 302 MB); larger levels are computed chunk by chunk.
const CACHE_BYTES: usize = 512 << 20;

/// The arithmetic of the head in grid evaluations (the encoder and [`Predictor::argmax`]'s
/// gradient ascent keep the model's own precision).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// The model's parameters as they are (float32 unless converted).
    #[default]
    Model,
    /// bfloat16 matrix products (AMX or AVX-512 BF16 on recent x86 CPUs, tensor cores on GPUs):
    /// about 3× faster on such CPUs; `F` differs from float32 by a few hundredths of a nat.
    BFloat16,
}

/// Options of [`Predictor::argmax`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArgmaxOptions {
    /// The hierarchical evaluation whose densest cells start the ascent.
    pub refine: RefineOptions,
    /// Number of starting cells (the densest ones).
    pub starts: usize,
    /// Gradient-ascent steps per start.
    pub steps: usize,
    /// First step length in radians (decays linearly to 0).
    pub step_size: f64,
}

impl Default for ArgmaxOptions {
    /// The default hierarchical evaluation, 4 starts, 50 steps of at most 0.5°.
    fn default() -> Self {
        Self {
            refine: RefineOptions::default(),
            starts: 4,
            steps: 50,
            step_size: 0.5f64.to_radians(),
        }
    }
}

impl ArgmaxOptions {
    /// Checks that there is at least one start and the step is finite and not negative.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.starts == 0 || !(self.step_size >= 0.0 && self.step_size.is_finite()) {
            return Err(ModelError::option(
                "starts",
                format!(
                    "{} starts, step size {}: need ≥ 1 and a finite step ≥ 0",
                    self.starts, self.step_size
                ),
            ));
        }
        Ok(())
    }
}

/// The most likely rotation found by [`Predictor::argmax`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Argmax {
    /// The rotation.
    pub rotation: UnitQuaternion<f64>,
    /// `F` there (unnormalised log-density).
    pub score: f64,
    /// `F` at the best grid cell it started from.
    pub start_score: f64,
}

/// Evaluates a model's density, or an ensemble's, for one image at a time, caching grids and
/// the query terms of fixed grids across images.
///
/// An ensemble ([`Predictor::ensemble`]) scores a rotation by the mean of its members' `F`:
/// its density is the normalised geometric mean of theirs (log-linear pooling), which keeps
/// where the members agree and lowers where any of them doubts. Members trained from other
/// seeds on the same examples disagree most where one network's answer is chance.
pub struct Predictor<'m> {
    members: Vec<Member<'m>>,
    grids: HashMap<u8, Grid>,
    extra_views: usize,
}

/// One model of a [`Predictor`]: its head in the grid evaluations' precision, and its query
/// terms of whole grid levels.
struct Member<'m> {
    model: &'m ImplicitPdf,
    head: Head,
    query_terms: HashMap<u8, Tensor>,
}

/// The [`Predictor::under_resolution`] above which a grid's level is too coarse for a model:
/// the heaviest cells' mass changes by a factor of 1.35 or more when they are split. Measured on
/// the quick pipeline's nine models (50 validation crops each) from level 2 to 5: where it was
/// 0.34–0.91 (the bowl's three models at level 4) the LLH moved by 0.34–0.67 to the next
/// level; at 0.44–0.66 (the box's and can's at level 3) by 0.04–0.44; at 0.32 by 0.08; below
/// 0.24 by less than 0.03. At level 5 every model's was below 0.29.
pub const UNDER_RESOLUTION_LIMIT: f64 = 0.3;

impl<'m> Predictor<'m> {
    /// A predictor for `model` (evaluated in inference mode) in the model's precision.
    pub fn new(model: &'m ImplicitPdf) -> Self {
        Self::with_precision(model, Precision::Model)
    }

    /// A predictor whose grid evaluations run the head in `precision`.
    pub fn with_precision(model: &'m ImplicitPdf, precision: Precision) -> Self {
        Self::of_members(std::slice::from_ref(model), precision)
    }

    /// A predictor for the ensemble of `models`, whose `F` is the mean of theirs (see
    /// [`Predictor`]). They must read the same crops in the same frame: an empty list, or
    /// members whose input size, rotation frame or device differ, are refused.
    pub fn ensemble(models: &'m [ImplicitPdf], precision: Precision) -> Result<Self, ModelError> {
        let Some(first) = models.first() else {
            return Err(ModelError::option(
                "members",
                "an ensemble needs at least one model",
            ));
        };
        for (i, model) in models.iter().enumerate().skip(1) {
            if let Some(difference) = member_mismatch(first, model) {
                return Err(ModelError::option(
                    "members",
                    format!("member {}: {difference}", i + 1),
                ));
            }
        }
        Ok(Self::of_members(models, precision))
    }

    fn of_members(models: &'m [ImplicitPdf], precision: Precision) -> Self {
        let members = models
            .iter()
            .map(|model| {
                let kind = match precision {
                    Precision::Model => model.kind(),
                    Precision::BFloat16 => Kind::BFloat16,
                };
                Member {
                    model,
                    head: model.head().to_kind(kind),
                    query_terms: HashMap::new(),
                }
            })
            .collect();
        Self {
            members,
            grids: HashMap::new(),
            extra_views: 0,
        }
    }

    /// The same predictor, each crop's image term the mean over the crop and its first `extra`
    /// test-time views ([`crop_views`]; 0: the crop alone). More than
    /// [`MAX_EXTRA_VIEWS`](crate::rotation::MAX_EXTRA_VIEWS) is refused.
    pub fn with_views(mut self, extra: usize) -> Result<Self, ModelError> {
        validate_views(extra)?;
        self.extra_views = extra;
        Ok(self)
    }

    /// The first member, whose crop size, frame and device every member shares.
    fn first(&self) -> &'m ImplicitPdf {
        self.members[0].model
    }

    /// The members' query terms (each `[N, H]`) of rotation matrices `[N, 9]` in the
    /// predictor's precision.
    fn query_terms(&self, rotations: &Tensor) -> Vec<Tensor> {
        self.members
            .iter()
            .map(|member| {
                let model = member.model;
                let encoded = encode_rotations(
                    &rotations.to_kind(model.kind()),
                    model.config().fourier_components,
                );
                tch::no_grad(|| member.head.query_term(&encoded.to_kind(member.head.kind())))
            })
            .collect()
    }

    /// `F` as doubles, the mean over the members, for an image term from
    /// [`Predictor::image_term`] and the members' query terms, in the predictor's precision.
    fn scores(&self, image_term: &Tensor, query_terms: &[Tensor]) -> Tensor {
        tch::no_grad(|| {
            self.member_mean(image_term, |k, member, term| {
                member
                    .head
                    .scores(&term.to_kind(member.head.kind()), &query_terms[k])
                    .to_kind(Kind::Double)
            })
        })
    }

    /// The mean over the members `k` of `f(k, member, its part of image_term)`.
    fn member_mean(
        &self,
        image_term: &Tensor,
        f: impl Fn(usize, &Member, Tensor) -> Tensor,
    ) -> Tensor {
        let mut offset = 0;
        let mut values: Vec<Tensor> = self
            .members
            .iter()
            .enumerate()
            .map(|(k, member)| {
                let term = image_term.narrow(1, offset, member.width());
                offset += member.width();
                f(k, member, term)
            })
            .collect();
        if values.len() == 1 {
            return values.remove(0);
        }
        let kind = values[0].kind();
        Tensor::stack(&values, 0).mean_dim(0, false, kind)
    }

    /// The image term of one crop (`[3, S, S]` or `[1, 3, S, S]`, values in `[0, 1]`): each
    /// member's `[1, H]`, averaged over the crop's views ([`Predictor::with_views`]), side by
    /// side.
    pub fn image_term(&self, image: &Tensor) -> Result<Tensor, ModelError> {
        let batch = if image.dim() == 3 {
            image.unsqueeze(0)
        } else {
            image.shallow_clone()
        };
        if batch.dim() != 4 || batch.size()[0] != 1 {
            return Err(ModelError::ImageShape {
                field: "image",
                expected: format!(
                    "one crop [3, {s}, {s}]",
                    s = self.first().config().input_size
                ),
                got: format!("{:?}", image.size()),
            });
        }
        let views = crop_views(&batch, self.extra_views);
        tch::no_grad(|| {
            let terms = self
                .members
                .iter()
                .map(|member| {
                    let terms = member.model.image_term(&views, false)?;
                    Ok(terms.mean_dim(0, true, terms.kind()))
                })
                .collect::<Result<Vec<_>, ModelError>>()?;
            Ok(Tensor::cat(&terms, 1))
        })
    }

    fn grid(&mut self, level: u8) -> Result<&Grid, ModelError> {
        match self.grids.entry(level) {
            std::collections::hash_map::Entry::Occupied(entry) => Ok(entry.into_mut()),
            std::collections::hash_map::Entry::Vacant(entry) => Ok(entry.insert(Grid::new(level)?)),
        }
    }

    /// `F` at the centres of `cells` of a `level` grid, for an image term from
    /// [`Predictor::image_term`].
    pub fn cell_scores(
        &mut self,
        image_term: &Tensor,
        level: u8,
        cells: &[u64],
    ) -> Result<Vec<f64>, ModelError> {
        if let Some(terms) = self.cached_query_terms(level)? {
            let count = cell_count(level);
            if let Some(&bad) = cells.iter().find(|&&index| index >= count) {
                return Err(so3_grid::GridError::CellOutOfRange {
                    level,
                    index: bad,
                    count,
                }
                .into());
            }
            let rows: Vec<i64> = cells.iter().map(|&index| index as i64).collect();
            let mut out = Vec::with_capacity(cells.len());
            for chunk in rows.chunks(CHUNK) {
                let index = Tensor::from_slice(chunk).to_device(self.first().device());
                let parts: Vec<Tensor> = terms
                    .iter()
                    .map(|term| term.index_select(0, &index))
                    .collect();
                let scores = self.scores(image_term, &parts);
                out.extend(Vec::<f64>::try_from(&scores)?);
            }
            return Ok(out);
        }
        let grid = self.grid(level)?;
        let rotations = cells
            .iter()
            .map(|&index| grid.rotation(index))
            .collect::<Result<Vec<_>, _>>()?;
        self.rotation_scores(image_term, &rotations)
    }

    /// The members' query terms (each `[N, H]`) of every cell of the `level` grid, computed on
    /// first use, or `None` when they would take more than [`CACHE_BYTES`].
    fn cached_query_terms(&mut self, level: u8) -> Result<Option<Vec<Tensor>>, ModelError> {
        let count = cell_count(level) as usize;
        let bytes: usize = self
            .members
            .iter()
            .map(|member| count * member.width() as usize * member.head.kind().elt_size_in_bytes())
            .sum();
        if bytes > CACHE_BYTES {
            return Ok(None);
        }
        if !self.members[0].query_terms.contains_key(&level) {
            let rotations = self.grid(level)?.rotations();
            let queries = rotations_to_tensor(&rotations, self.first().device());
            let terms = self.query_terms(&queries);
            for (member, term) in self.members.iter_mut().zip(terms) {
                member.query_terms.insert(level, term);
            }
        }
        Ok(self
            .members
            .iter()
            .map(|member| member.query_terms.get(&level).map(Tensor::shallow_clone))
            .collect())
    }

    /// `F` at arbitrary rotations, for an image term from [`Predictor::image_term`].
    pub fn rotation_scores(
        &self,
        image_term: &Tensor,
        rotations: &[UnitQuaternion<f64>],
    ) -> Result<Vec<f64>, ModelError> {
        let mut out = Vec::with_capacity(rotations.len());
        for chunk in rotations.chunks(CHUNK) {
            let queries = rotations_to_tensor(chunk, self.first().device());
            let scores = self.scores(image_term, &self.query_terms(&queries));
            out.extend(Vec::<f64>::try_from(&scores)?);
        }
        Ok(out)
    }

    /// How far the finest cells of `distribution` (of `image`, from [`Predictor::hierarchical`])
    /// are from resolving the density: over the cells that hold its first half of the mass
    /// (heaviest first, at most 16), the mass-weighted mean of `|ln(m₈ / m)|`, `m` the cell's
    /// mass from the density at its centre and `m₈` the mean of the densities at its 8
    /// children's centres. 0 where the density is flat across each cell; large where a peak
    /// narrower than a cell sits off its centre, which leaves the normaliser, and with it LLH,
    /// MAAD and Recall MAAD, wrong (see [`UNDER_RESOLUTION_LIMIT`]). Costs 9 queries per cell.
    pub fn under_resolution(
        &mut self,
        image: &Tensor,
        distribution: &CellMasses,
    ) -> Result<f64, ModelError> {
        let image_term = self.image_term(image)?;
        self.under_resolution_for(&image_term, distribution)
    }

    /// [`Predictor::under_resolution`] for an image term from [`Predictor::image_term`].
    pub fn under_resolution_for(
        &mut self,
        image_term: &Tensor,
        distribution: &CellMasses,
    ) -> Result<f64, ModelError> {
        let Some(level) = distribution.cells.iter().map(|&(level, _)| level).max() else {
            return Ok(0.0);
        };
        let mut order: Vec<usize> = (0..distribution.cells.len())
            .filter(|&i| distribution.cells[i].0 == level)
            .collect();
        order.sort_by(|&a, &b| distribution.masses[b].total_cmp(&distribution.masses[a]));
        let (mut heavy, mut held) = (Vec::new(), 0.0);
        for i in order.into_iter().take(16) {
            heavy.push(i);
            held += distribution.masses[i];
            if held >= 0.5 {
                break;
            }
        }
        // Each heavy cell's centre, then its 8 children's, from the cached grids.
        let mut rotations = Vec::with_capacity(heavy.len() * 9);
        for &i in &heavy {
            let index = distribution.cells[i].1;
            rotations.push(self.grid(level)?.rotation(index)?);
            for child in so3_grid::children(level, index)? {
                rotations.push(self.grid(level + 1)?.rotation(child)?);
            }
        }
        let log_density = self.log_densities_for(image_term, &rotations, distribution)?;
        let (mut sum, mut weights) = (0.0, 0.0);
        for (k, &i) in heavy.iter().enumerate() {
            let values = &log_density[9 * k..9 * k + 9];
            let children = values[1..]
                .iter()
                .map(|f| (f - values[0]).exp())
                .sum::<f64>()
                / 8.0;
            sum += distribution.masses[i] * children.ln().abs();
            weights += distribution.masses[i];
        }
        Ok(if weights > 0.0 { sum / weights } else { 0.0 })
    }

    /// `ln p(R | I)` at each of `rotations`, for the normaliser of a distribution of the same
    /// image (from [`Predictor::hierarchical`]): `F(R) − ln Z`. This is the log-likelihood of
    /// the Implicit-PDF reference, which evaluates `F` at the ground truth itself rather than at
    /// the centre of the grid cell holding it, so a coarse distribution whose normaliser is right
    /// gives the same value as a dense one.
    pub fn log_densities(
        &mut self,
        image: &Tensor,
        rotations: &[UnitQuaternion<f64>],
        distribution: &CellMasses,
    ) -> Result<Vec<f64>, ModelError> {
        let image_term = self.image_term(image)?;
        self.log_densities_for(&image_term, rotations, distribution)
    }

    /// [`Predictor::log_densities`] for an image term from [`Predictor::image_term`].
    pub fn log_densities_for(
        &mut self,
        image_term: &Tensor,
        rotations: &[UnitQuaternion<f64>],
        distribution: &CellMasses,
    ) -> Result<Vec<f64>, ModelError> {
        let scores = self.rotation_scores(image_term, rotations)?;
        Ok(scores
            .into_iter()
            .map(|f| f - distribution.log_normaliser)
            .collect())
    }

    /// `F` at every cell centre of the `level` grid, `[N]` (double), chunked; the grid's query
    /// term is computed once and kept while it fits the cache.
    pub fn grid_scores(&mut self, image_term: &Tensor, level: u8) -> Result<Tensor, ModelError> {
        let Some(terms) = self.cached_query_terms(level)? else {
            let cells: Vec<u64> = (0..cell_count(level)).collect();
            let scores = self.cell_scores(image_term, level, &cells)?;
            return Ok(Tensor::from_slice(&scores));
        };
        let count = cell_count(level) as i64;
        let chunks: Vec<Tensor> = (0..count)
            .step_by(CHUNK)
            .map(|start| {
                let length = (count - start).min(CHUNK as i64);
                let parts: Vec<Tensor> = terms
                    .iter()
                    .map(|term| term.narrow(0, start, length))
                    .collect();
                self.scores(image_term, &parts)
            })
            .collect();
        Ok(Tensor::cat(&chunks, 0))
    }

    /// The normalised distribution over the cells of the `level` grid (masses in cell order,
    /// summing to 1; each cell's density is `mass · N / π²`).
    pub fn probabilities(&mut self, image: &Tensor, level: u8) -> Result<Vec<f64>, ModelError> {
        let image_term = self.image_term(image)?;
        self.probabilities_for(&image_term, level)
    }

    /// [`Predictor::probabilities`] for an image term from [`Predictor::image_term`].
    pub fn probabilities_for(
        &mut self,
        image_term: &Tensor,
        level: u8,
    ) -> Result<Vec<f64>, ModelError> {
        let scores = self.grid_scores(image_term, level)?;
        let masses = scores.softmax(0, Kind::Double);
        Ok(Vec::<f64>::try_from(&masses)?)
    }

    /// The distribution refined hierarchically (see [`refine`]): dense at
    /// `options.start_level`, then only the cells holding most of the mass down to
    /// `options.level`.
    pub fn hierarchical(
        &mut self,
        image: &Tensor,
        options: &RefineOptions,
    ) -> Result<CellMasses, ModelError> {
        let image_term = self.image_term(image)?;
        self.hierarchical_for(&image_term, options)
    }

    /// [`Predictor::hierarchical`] for an image term from [`Predictor::image_term`].
    pub fn hierarchical_for(
        &mut self,
        image_term: &Tensor,
        options: &RefineOptions,
    ) -> Result<CellMasses, ModelError> {
        let start = options.start_level;
        refine(
            |level, cells| {
                if level == start && cells.len() as u64 == cell_count(level) {
                    let scores = self.grid_scores(image_term, level)?;
                    Ok(Vec::<f64>::try_from(scores)?)
                } else {
                    self.cell_scores(image_term, level, cells)
                }
            },
            options,
        )
    }

    /// The most likely rotation: the densest cells of the hierarchical evaluation, each
    /// followed by gradient ascent on `F` over the tangent space (`R = R₀ · exp([ω]×)`, steps
    /// along the normalised gradient with a linearly decaying length); the best end point.
    pub fn argmax(
        &mut self,
        image: &Tensor,
        options: &ArgmaxOptions,
    ) -> Result<Argmax, ModelError> {
        options.validate()?;
        let image_term = self.image_term(image)?;
        let masses = self.hierarchical_for(&image_term, &options.refine)?;
        self.argmax_from(&image_term, &masses, options)
    }

    /// [`Predictor::argmax`] from the image term (from [`Predictor::image_term`]) and the
    /// hierarchical distribution `masses` of the same crop, already evaluated with
    /// `options.refine`: the same result without evaluating either again.
    pub fn argmax_from(
        &mut self,
        image_term: &Tensor,
        masses: &CellMasses,
        options: &ArgmaxOptions,
    ) -> Result<Argmax, ModelError> {
        options.validate()?;
        let mut starts = Vec::with_capacity(options.starts);
        for position in masses.densest(options.starts) {
            let (level, index) = masses.cells[position];
            starts.push(self.grid(level)?.rotation(index)?);
        }
        let device = self.first().device();
        let bases = rotations_to_tensor(&starts, device).reshape([-1, 3, 3]);
        let count = starts.len() as i64;
        let mut tangent = Tensor::zeros([count, 3], (Kind::Float, device)).set_requires_grad(true);
        let score_at = |tangent: &Tensor| {
            let rotations = bases.matmul(&exp_map(tangent)).reshape([count, 9]);
            self.member_mean(image_term, |_, member, term| {
                member
                    .model
                    .scores(&term, &member.model.query_term(&rotations))
            })
        };
        let start_scores =
            Vec::<f64>::try_from(tch::no_grad(|| score_at(&tangent)).to_kind(Kind::Double))?;
        let mut best_scores = start_scores.clone();
        let mut best_tangents = vec![[0.0f64; 3]; starts.len()];
        for step in 0..options.steps {
            let scores = score_at(&tangent);
            let values = Vec::<f64>::try_from(scores.to_kind(Kind::Double).detach())?;
            let current =
                Vec::<f64>::try_from(tangent.detach().to_kind(Kind::Double).reshape([-1]))?;
            for (i, &value) in values.iter().enumerate() {
                if value > best_scores[i] {
                    best_scores[i] = value;
                    best_tangents[i] = [current[3 * i], current[3 * i + 1], current[3 * i + 2]];
                }
            }
            tangent.zero_grad();
            scores.sum(Kind::Float).backward();
            let length = options.step_size * (1.0 - step as f64 / options.steps as f64);
            tch::no_grad(|| {
                let grad = tangent.grad();
                let norm = grad.norm_scalaropt_dim(2.0, [1].as_slice(), true) + 1e-12;
                let mut t = tangent.shallow_clone();
                let _ = t.g_add_(&(grad / norm * length));
            });
        }
        let final_scores =
            Vec::<f64>::try_from(tch::no_grad(|| score_at(&tangent)).to_kind(Kind::Double))?;
        let final_tangent =
            Vec::<f64>::try_from(tangent.detach().to_kind(Kind::Double).reshape([-1]))?;
        for (i, &value) in final_scores.iter().enumerate() {
            if value > best_scores[i] {
                best_scores[i] = value;
                best_tangents[i] = [
                    final_tangent[3 * i],
                    final_tangent[3 * i + 1],
                    final_tangent[3 * i + 2],
                ];
            }
        }
        let best = (0..starts.len())
            .max_by(|&a, &b| best_scores[a].total_cmp(&best_scores[b]))
            .unwrap_or(0);
        let [x, y, z] = best_tangents[best];
        Ok(Argmax {
            rotation: starts[best] * UnitQuaternion::from_scaled_axis(Vector3::new(x, y, z)),
            score: best_scores[best],
            start_score: start_scores[best],
        })
    }
}

/// How `member` reads other crops than `first` (input size, rotation frame, device), if it
/// does: such models cannot form an ensemble.
pub(crate) fn member_mismatch(first: &ImplicitPdf, member: &ImplicitPdf) -> Option<String> {
    let (a, b) = (first.config(), member.config());
    (a.input_size != b.input_size
        || a.rotation_frame != b.rotation_frame
        || first.device() != member.device())
    .then(|| {
        format!(
            "reads {}-pixel crops in the {} frame on {:?}, the first model {}-pixel crops in \
             the {} frame on {:?}",
            b.input_size,
            b.rotation_frame.name(),
            member.device(),
            a.input_size,
            a.rotation_frame.name(),
            first.device()
        )
    })
}

impl Member<'_> {
    /// The width of its image and query terms.
    fn width(&self) -> i64 {
        self.model.config().head_sizes[0]
    }
}

/// Rotation matrices `[K, 3, 3]` of tangent vectors `[K, 3]` (Rodrigues' formula; the small
/// offset inside the square root keeps the gradient finite at 0).
fn exp_map(tangent: &Tensor) -> Tensor {
    let count = tangent.size()[0];
    let (x, y, z) = (
        tangent.select(1, 0),
        tangent.select(1, 1),
        tangent.select(1, 2),
    );
    let zero = x.zeros_like();
    let hat = Tensor::stack(
        &[&zero, &(-&z), &y, &z, &zero, &(-&x), &(-&y), &x, &zero],
        1,
    )
    .reshape([count, 3, 3]);
    let angle = (tangent
        .square()
        .sum_dim_intlist([1].as_slice(), true, Kind::Float)
        + 1e-12)
        .sqrt()
        .unsqueeze(-1);
    let eye = Tensor::eye(3, (Kind::Float, tangent.device()));
    let hat2 = hat.matmul(&hat);
    eye + hat * (angle.sin() / &angle) + hat2 * ((1.0 - angle.cos()) / angle.square())
}
