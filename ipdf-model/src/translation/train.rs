//! Training the translation model: label sets of translations, queries drawn around the first
//! label and over the whole working volume, each label in its own importance-sampled normaliser.
use nalgebra::Vector3;
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tch::Tensor;

use super::model::check_translation_sets;
use super::{CropGeometry, TranslationPdf, TranslationSpace};
use crate::ModelError;
use crate::augment::{Augmentation, augment};
use crate::loss::set_nll_with;
use crate::optim::{Adam, LearningRateSchedule};
use crate::step::{StepReport, optimisation_step, validate_optimisation};

/// The spreads of the Gaussian proposals around the first label, as fractions of the reference
/// crop extent `E` (for `E` = 100 mm: 2, 10 and 50 mm): the loss sees alternatives at the
/// scale of the error it should reach, at the scale of the object, and beyond.
const PROPOSAL_SPREADS: [f64; 3] = [0.02, 0.1, 0.5];

/// Options of the translation trainer; the learning-rate schedule, clipping and augmentation
/// mean what they mean for rotations ([`crate::rotation::TrainOptions`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TranslationTrainOptions {
    /// Adam's learning rate per step.
    pub schedule: LearningRateSchedule,
    /// Maximum global L2 norm of the gradient.
    pub clip_norm: f64,
    /// Query translations per image and step, the label's included (4,096).
    pub queries: usize,
    /// Image augmentation (the crop geometry is left as it is).
    pub augmentation: Augmentation,
    /// Standard deviation (mm) of the Gaussian noise added to each label, per axis and step
    /// (1 mm). The label itself sits in its own normaliser, so without noise nothing stops a
    /// peak from growing narrower than any grid can resolve: trained so, the pipeline's bowl
    /// models put their mass on a ridge thinner than the 2 mm scoring cells (validation LLH +49
    /// nats per mm³, argmax 134 mm off). With noise the model learns the labels' density
    /// blurred by it, which 2 mm cells resolve.
    #[serde(default)]
    pub label_noise_mm: f64,
    /// Seed of the queries and augmentation (step `s` uses ChaCha8 stream `s`).
    pub seed: u64,
}

impl Default for TranslationTrainOptions {
    /// Learning rate 1e-3 (100 warm-up steps, cosine to 0 at 2,000), clipping at 5, 4,096
    /// queries, colour jitter, 1 mm label noise, seed 0.
    fn default() -> Self {
        Self {
            schedule: LearningRateSchedule {
                peak: 1e-3,
                warmup_steps: 100,
                total_steps: 2_000,
            },
            clip_norm: 5.0,
            queries: 4_096,
            augmentation: Augmentation::COLOUR,
            label_noise_mm: 1.0,
            seed: 0,
        }
    }
}

impl TranslationTrainOptions {
    /// Checks the ranges of the fields.
    pub fn validate(&self) -> Result<(), ModelError> {
        validate_optimisation(&self.schedule, self.clip_norm, &self.augmentation)?;
        if !(2..=1 << 20).contains(&self.queries) {
            return Err(ModelError::option(
                "queries",
                format!("{}: need 2..=1048576 queries", self.queries),
            ));
        }
        if !(self.label_noise_mm >= 0.0 && self.label_noise_mm.is_finite()) {
            return Err(ModelError::option(
                "label_noise_mm",
                format!(
                    "{}: need a finite standard deviation ≥ 0",
                    self.label_noise_mm
                ),
            ));
        }
        Ok(())
    }
}

/// A translation model being trained: the model, Adam's state and the step count.
pub struct TranslationTrainer {
    model: TranslationPdf,
    options: TranslationTrainOptions,
    adam: Adam,
    step: u64,
}

impl TranslationTrainer {
    /// Starts training `model` from step 0.
    pub fn new(
        model: TranslationPdf,
        options: TranslationTrainOptions,
    ) -> Result<Self, ModelError> {
        Self::at_step(model, options, 0)
    }

    pub(crate) fn at_step(
        model: TranslationPdf,
        options: TranslationTrainOptions,
        step: u64,
    ) -> Result<Self, ModelError> {
        options.validate()?;
        let adam = Adam::new(model.var_store());
        Ok(Self {
            model,
            options,
            adam,
            step,
        })
    }

    /// The options.
    pub fn options(&self) -> &TranslationTrainOptions {
        &self.options
    }

    pub(crate) fn adam(&self) -> &Adam {
        &self.adam
    }

    pub(crate) fn adam_mut(&mut self) -> &mut Adam {
        &mut self.adam
    }

    /// The model.
    pub fn model(&self) -> &TranslationPdf {
        &self.model
    }

    /// The model, ending training.
    pub fn into_model(self) -> TranslationPdf {
        self.model
    }

    /// Steps done so far.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The loss of a batch without updating anything: crops `[B, 3, S, S]` in `[0, 1]`, their
    /// geometry, and one set of translation labels (mm) per crop, each inside the working
    /// volume. Each label's density is `exp F(t) / Z`, `Z` estimated by importance sampling
    /// from `queries − 1` translations drawn from a mixture of the uniform density on the volume
    /// and Gaussians around the first label (see `PROPOSAL_SPREADS`), the label itself counted
    /// among them (see [`crate::rotation::set_nll`]). Draws queries (and augmentation when
    /// `train`) from `rng`.
    pub fn loss(
        &self,
        images: &Tensor,
        geometry: &[CropGeometry],
        label_sets: &[Vec<Vector3<f64>>],
        rng: &mut ChaCha8Rng,
        train: bool,
    ) -> Result<Tensor, ModelError> {
        self.model.check_inputs(images, geometry)?;
        check_translation_sets(label_sets, geometry)?;
        let space = *self.model.space();
        check_in_volume(&space, label_sets)?;
        let (device, kind) = (self.model.device(), self.model.kind());
        let images = if train {
            augment(&images.to_device(device), &self.options.augmentation, rng)
        } else {
            images.to_device(device)
        };
        let batch = label_sets.len() as i64;
        let others = self.options.queries - 1;
        let (queries, query_log_q, outside) = draw_queries(&space, label_sets, others, rng);
        let noise = if train {
            self.options.label_noise_mm
        } else {
            0.0
        };
        let (longest, labels, label_log_q, mask) = padded_labels(&space, label_sets, noise, rng);
        let tensor = |values: Vec<f64>, shape: &[i64]| {
            Tensor::from_slice(&values)
                .reshape(shape)
                .to_device(device)
                .to_kind(kind)
        };
        let k = longest as i64;
        let n = others as i64;
        let factors = self.model.crop_factors(geometry).unsqueeze(1); // [B, 1, 5]
        let image_term = self
            .model
            .image_term(&images, geometry, train)?
            .unsqueeze(1);
        let query_scores = self.model.scores(
            &image_term,
            &self
                .model
                .query_term(&tensor(queries, &[batch, n, 3]), &factors),
        );
        let outside = Tensor::from_slice(&outside)
            .reshape([batch, n])
            .to_device(device);
        let other_terms =
            (query_scores - tensor(query_log_q, &[batch, n])).masked_fill(&outside, -1e9);
        let label_scores = self.model.scores(
            &image_term,
            &self
                .model
                .query_term(&tensor(labels, &[batch, k, 3]), &factors),
        );
        let label_terms = &label_scores - tensor(label_log_q, &[batch, k]);
        let mask = tensor(mask, &[batch, k]);
        let log_count = (self.options.queries as f64).ln();
        Ok(set_nll_with(
            &other_terms,
            &label_scores,
            &label_terms,
            &mask,
            log_count,
        ))
    }

    /// One optimisation step on a batch (see [`TranslationTrainer::loss`]). Randomness comes
    /// from ChaCha8 stream `step` of the options' seed, so a resumed run repeats an
    /// uninterrupted one.
    pub fn train_step(
        &mut self,
        images: &Tensor,
        geometry: &[CropGeometry],
        label_sets: &[Vec<Vector3<f64>>],
    ) -> Result<StepReport, ModelError> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.options.seed);
        rng.set_stream(self.step);
        self.adam.zero_grad();
        let loss = self.loss(images, geometry, label_sets, &mut rng, true)?;
        optimisation_step(
            &mut self.adam,
            &self.options.schedule,
            self.options.clip_norm,
            &mut self.step,
            &loss,
        )
    }
}

/// Refuses a label set with a translation outside the working volume, naming it.
fn check_in_volume(
    space: &TranslationSpace,
    label_sets: &[Vec<Vector3<f64>>],
) -> Result<(), ModelError> {
    for (image, set) in label_sets.iter().enumerate() {
        if let Some(t) = set.iter().find(|t| !space.volume.contains(t)) {
            return Err(ModelError::LabelSet {
                image,
                reason: format!(
                    "translation {:?} mm lies outside the working volume {:?} to {:?} mm",
                    t.as_slice(),
                    space.volume.min,
                    space.volume.max
                ),
            });
        }
    }
    Ok(())
}

/// The label sets padded to the longest (`K`, returned first): per crop `K` translations
/// (mm, flattened `[B·K·3]`), each moved by Gaussian noise of `noise` mm per axis (drawn from
/// `rng`) and kept inside the volume, with their proposal log-densities `[B·K]` and validity
/// mask `[B·K]` (a padded copy of the last label counts 0).
fn padded_labels(
    space: &TranslationSpace,
    label_sets: &[Vec<Vector3<f64>>],
    noise: f64,
    rng: &mut ChaCha8Rng,
) -> (usize, Vec<f64>, Vec<f64>, Vec<f64>) {
    let longest = label_sets.iter().map(Vec::len).max().unwrap_or(1);
    let mut labels = Vec::with_capacity(label_sets.len() * longest * 3);
    let mut label_log_q = Vec::with_capacity(label_sets.len() * longest);
    let mut mask = Vec::with_capacity(label_sets.len() * longest);
    for set in label_sets {
        for k in 0..longest {
            let t = set[k.min(set.len() - 1)] + standard_normal(rng) * noise;
            let t = t
                .sup(&Vector3::from(space.volume.min))
                .inf(&Vector3::from(space.volume.max));
            labels.extend([t.x, t.y, t.z]);
            label_log_q.push(log_proposal(space, &set[0], &t));
            mask.push(if k < set.len() { 1.0 } else { 0.0 });
        }
    }
    (longest, labels, label_log_q, mask)
}

/// `count` queries per image from the proposal around its first label: the flattened
/// translations `[B · count · 3]` (mm), `ln q` at each `[B · count]`, and whether each lies
/// outside the volume (those count for nothing in the normaliser, which integrates over the
/// volume only).
fn draw_queries(
    space: &TranslationSpace,
    label_sets: &[Vec<Vector3<f64>>],
    count: usize,
    rng: &mut impl Rng,
) -> (Vec<f64>, Vec<f64>, Vec<bool>) {
    let volume = &space.volume;
    let mut queries = Vec::with_capacity(label_sets.len() * count * 3);
    let mut log_q = Vec::with_capacity(label_sets.len() * count);
    let mut outside = Vec::with_capacity(label_sets.len() * count);
    for set in label_sets {
        let centre = set[0];
        for _ in 0..count {
            let component = rng.random_range(0..=PROPOSAL_SPREADS.len());
            let t = match PROPOSAL_SPREADS.get(component) {
                Some(spread) => centre + standard_normal(rng) * (spread * space.crop_extent),
                None => {
                    Vector3::from_fn(|axis, _| rng.random_range(volume.min[axis]..volume.max[axis]))
                }
            };
            queries.extend([t.x, t.y, t.z]);
            log_q.push(log_proposal(space, &centre, &t));
            outside.push(!volume.contains(&t));
        }
    }
    (queries, log_q, outside)
}

/// `ln q(t)` of the mixture drawn by [`draw_queries`] around `centre` (per mm³): equal weights
/// on the uniform density over the volume and on isotropic Gaussians of each spread.
fn log_proposal(space: &TranslationSpace, centre: &Vector3<f64>, t: &Vector3<f64>) -> f64 {
    let weight = 1.0 / (PROPOSAL_SPREADS.len() + 1) as f64;
    let uniform = if space.volume.contains(t) {
        1.0 / space.volume.extent().product()
    } else {
        0.0
    };
    let squared = (t - centre).norm_squared();
    let gaussians: f64 = PROPOSAL_SPREADS
        .iter()
        .map(|spread| {
            let sigma = spread * space.crop_extent;
            (-0.5 * squared / (sigma * sigma)).exp()
                / (2.0 * std::f64::consts::PI * sigma * sigma).powf(1.5)
        })
        .sum();
    (weight * (uniform + gaussians)).ln()
}

/// Three independent standard normal values (Box–Muller).
fn standard_normal(rng: &mut impl Rng) -> Vector3<f64> {
    let mut pair = || {
        let u: f64 = 1.0 - rng.random::<f64>();
        let v: f64 = rng.random::<f64>();
        let radius = (-2.0 * u.ln()).sqrt();
        let angle = std::f64::consts::TAU * v;
        (radius * angle.cos(), radius * angle.sin())
    };
    let (a, b) = pair();
    let (c, _) = pair();
    Vector3::new(a, b, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::translation::WorkingVolume;

    #[test]
    fn draws_and_their_log_densities_agree() {
        // Importance sampling with the drawn queries and their `q` recovers the volume:
        // E_q[1(t ∈ V) / q(t)] = |V|, which holds only if `log_proposal` is the density the
        // queries are drawn from.
        let space = TranslationSpace {
            volume: WorkingVolume::new([-100.0, -100.0, 400.0], [100.0, 100.0, 600.0]).unwrap(),
            crop_extent: 50.0,
        };
        let centre = Vector3::new(10.0, -20.0, 480.0);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let count = 200_000;
        let (queries, log_q, outside) = draw_queries(&space, &[vec![centre]], count, &mut rng);
        assert_eq!(queries.len(), 3 * count);
        assert!(log_q.iter().all(|v| v.is_finite()));
        let estimate = log_q
            .iter()
            .zip(&outside)
            .filter(|(_, out)| !**out)
            .map(|(l, _)| (-l).exp())
            .sum::<f64>()
            / count as f64;
        let volume = space.volume.extent().product();
        assert!(
            (estimate / volume - 1.0).abs() < 0.03,
            "{estimate} vs {volume}"
        );
        // A quarter of the queries come from the 1 mm Gaussian, 18% more from the 5 mm one
        // within 10 mm (χ₃ CDF at 2 is 0.74): 44% in all.
        let near = (0..count)
            .filter(|i| {
                (Vector3::new(queries[3 * i], queries[3 * i + 1], queries[3 * i + 2]) - centre)
                    .norm()
                    < 10.0
            })
            .count() as f64
            / count as f64;
        assert!((near - 0.4387).abs() < 0.01, "{near}");
    }

    #[test]
    fn standard_normals_have_unit_variance() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let n = 20_000;
        let (mut sum, mut squares) = (Vector3::zeros(), Vector3::zeros());
        for _ in 0..n {
            let x = standard_normal(&mut rng);
            sum += x;
            squares += x.component_mul(&x);
        }
        assert!((sum / n as f64).amax() < 0.03);
        assert!((squares / n as f64).iter().all(|v| (v - 1.0).abs() < 0.04));
    }
}
