//! One training step and the state that carries over between steps.
use nalgebra::UnitQuaternion;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tch::Tensor;

use super::ImplicitPdf;
use super::loss::{
    LabelLoss, QuerySampler, QuerySampling, check_label_sets, padded_labels, queries_through,
    set_nll,
};
use crate::ModelError;
use crate::augment::{Augmentation, augment};

use crate::optim::{Adam, LearningRateSchedule};
use crate::step::{StepReport, optimisation_step, validate_optimisation};

/// Everything about training that is not the model's shape; stored in checkpoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainOptions {
    /// Adam's learning rate per step.
    pub schedule: LearningRateSchedule,
    /// Maximum global L2 norm of the gradient (larger gradients are scaled down).
    pub clip_norm: f64,
    /// The query rotations of each step.
    pub queries: QuerySampling,
    /// How label sets enter the loss.
    pub label_loss: LabelLoss,
    /// Image augmentation.
    pub augmentation: Augmentation,
    /// Seed of the queries, label draws and augmentation (step `s` uses ChaCha8 stream `s`).
    pub seed: u64,
}

impl Default for TrainOptions {
    /// Learning rate 1e-4 (500 warm-up steps, cosine to 0 at 10,000), clipping at 5, level-2
    /// grid queries (4,608), whole label sets, colour jitter, seed 0.
    fn default() -> Self {
        Self {
            schedule: LearningRateSchedule {
                peak: 1e-4,
                warmup_steps: 500,
                total_steps: 10_000,
            },
            clip_norm: 5.0,
            queries: QuerySampling::Grid { level: 2 },
            label_loss: LabelLoss::WholeSet,
            augmentation: Augmentation::default(),
            seed: 0,
        }
    }
}

impl TrainOptions {
    /// Checks the ranges of the fields.
    pub fn validate(&self) -> Result<(), ModelError> {
        validate_optimisation(&self.schedule, self.clip_norm, &self.augmentation)
    }
}

/// A model being trained: the model, Adam's state and the step count.
pub struct Trainer {
    pub(crate) model: ImplicitPdf,
    pub(crate) options: TrainOptions,
    pub(crate) adam: Adam,
    pub(crate) step: u64,
    sampler: QuerySampler,
}

impl Trainer {
    /// Starts training `model` from step 0.
    pub fn new(model: ImplicitPdf, options: TrainOptions) -> Result<Self, ModelError> {
        Self::at_step(model, options, 0)
    }

    pub(crate) fn at_step(
        model: ImplicitPdf,
        options: TrainOptions,
        step: u64,
    ) -> Result<Self, ModelError> {
        options.validate()?;
        let sampler = QuerySampler::new(options.queries, model.device())?;
        let adam = Adam::new(model.var_store());
        Ok(Self {
            model,
            options,
            adam,
            step,
            sampler,
        })
    }

    /// The model.
    pub fn model(&self) -> &ImplicitPdf {
        &self.model
    }

    /// The model, ending training.
    pub fn into_model(self) -> ImplicitPdf {
        self.model
    }

    /// The options.
    pub fn options(&self) -> &TrainOptions {
        &self.options
    }

    /// Steps done so far.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The loss of a batch without updating anything: crops `[B, 3, S, S]` in `[0, 1]` and one
    /// label set per image. Draws queries (and augmentation when `train`) from `rng`.
    pub fn loss(
        &self,
        images: &Tensor,
        label_sets: &[Vec<UnitQuaternion<f64>>],
        rng: &mut ChaCha8Rng,
        train: bool,
    ) -> Result<Tensor, ModelError> {
        self.model.check_images(images)?;
        check_label_sets(label_sets, images.size()[0] as usize)?;
        let device = self.model.device();
        let kind = self.model.kind();
        let images = if train {
            augment(&images.to_device(device), &self.options.augmentation, rng)
        } else {
            images.to_device(device)
        };
        let queries = self.sampler.sample(rng);
        let (labels, mask) = match self.options.label_loss {
            LabelLoss::OneOfSet => {
                let drawn: Vec<Vec<UnitQuaternion<f64>>> = label_sets
                    .iter()
                    .map(|set| vec![set[rand::RngExt::random_range(rng, 0..set.len())]])
                    .collect();
                padded_labels(&drawn, device, kind)
            }
            LabelLoss::WholeSet => padded_labels(label_sets, device, kind),
        };
        let batch = labels.size()[0];
        let first_labels = labels.select(1, 0).reshape([batch, 3, 3]);
        let shifted = queries_through(&queries, &first_labels); // [B, N, 3, 3]
        let count = shifted.size()[1];
        let image_term = self.model.image_term(&images, train)?.unsqueeze(1);
        let query_scores = self.model.scores(
            &image_term,
            &self.model.query_term(&shifted.reshape([batch, count, 9])),
        );
        let label_scores = if labels.size()[1] == 1 {
            query_scores.narrow(1, 0, 1)
        } else {
            self.model
                .scores(&image_term, &self.model.query_term(&labels))
        };
        Ok(set_nll(&query_scores, &label_scores, &mask))
    }

    /// One optimisation step on a batch (see [`Trainer::loss`]): loss, backward pass, gradient
    /// clipping, Adam with the scheduled learning rate. Randomness comes from ChaCha8 stream
    /// `step` of the options' seed, so a resumed run repeats an uninterrupted one.
    pub fn train_step(
        &mut self,
        images: &Tensor,
        label_sets: &[Vec<UnitQuaternion<f64>>],
    ) -> Result<StepReport, ModelError> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.options.seed);
        rng.set_stream(self.step);
        self.adam.zero_grad();
        let loss = self.loss(images, label_sets, &mut rng, true)?;
        optimisation_step(
            &mut self.adam,
            &self.options.schedule,
            self.options.clip_norm,
            &mut self.step,
            &loss,
        )
    }
}
