//! Training over epochs, shared by the rotation and translation models: each epoch a seeded
//! permutation of the examples, batches from it, the validation LLH, a checkpoint and
//! `train_log.csv`, all resumable.
use std::path::Path;
use std::time::Instant;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use tch::{Kind, Tensor};

use crate::ModelError;
use crate::checkpoint::write_text_atomically;
use crate::step::StepReport;

/// What [`fit`] trains: a trainer ([`crate::rotation::Trainer`],
/// [`crate::translation::TranslationTrainer`]) and the kind of labelled data it takes batches
/// of.
pub trait FitTarget {
    /// Training and validation data.
    type Data;
    /// The number of examples in `data`.
    fn examples(data: &Self::Data) -> usize;
    /// Steps done so far.
    fn steps_done(&self) -> u64;
    /// The seed of the training options (it also orders the epochs' batches).
    fn seed(&self) -> u64;
    /// One optimisation step on the examples at `indices`.
    fn train_batch(
        &mut self,
        data: &Self::Data,
        indices: &[usize],
    ) -> Result<StepReport, ModelError>;
    /// The mean log-likelihood of `data`'s labels under the model (see
    /// [`crate::rotation::validation_llh`]).
    fn validation_llh(&self, data: &Self::Data, options: &FitOptions) -> Result<f64, ModelError>;
    /// Writes the checkpoint.
    fn save_to(&self, dir: &Path) -> Result<(), ModelError>;
}

/// The name of the training log in a run folder.
pub const TRAIN_LOG: &str = "train_log.csv";
const LOG_HEADER: &str = "epoch,step,loss,learning_rate,validation_llh,seconds,images_per_second";

/// Checks that `images` is a stack `[N ≥ 1, 3, S, S]` of training crops; returns `N`.
pub(crate) fn check_image_stack(images: &Tensor) -> Result<usize, ModelError> {
    let size = images.size();
    if size.len() != 4 || size[1] != 3 || size[2] != size[3] || size[0] == 0 {
        return Err(ModelError::ImageShape {
            field: "images",
            expected: "[N ≥ 1, 3, S, S]".into(),
            got: format!("{size:?}"),
        });
    }
    Ok(size[0] as usize)
}

/// The crops of `images` (float in `[0, 1]` or 8-bit) at `indices`, as floats in `[0, 1]`.
pub(crate) fn select_images(images: &Tensor, indices: &[usize]) -> Tensor {
    let index = Tensor::from_slice(&indices.iter().map(|&i| i as i64).collect::<Vec<_>>());
    let images = images.index_select(0, &index);
    if images.kind() == Kind::Uint8 {
        images.to_kind(Kind::Float) / 255.0
    } else {
        images.to_kind(Kind::Float)
    }
}

/// How long [`fit`] trains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Epochs to reach (a resumed run continues up to this).
    pub epochs: u64,
    /// Steps per epoch.
    pub steps_per_epoch: u64,
    /// Images per step.
    pub batch_size: usize,
    /// Grid level of the validation LLH of rotation models (2: 4,608 cells).
    pub validation_level: u8,
}

/// One line of `train_log.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochReport {
    /// Epoch number, from 1.
    pub epoch: u64,
    /// Steps done at its end.
    pub step: u64,
    /// Mean training loss over the epoch.
    pub loss: f64,
    /// Learning rate of its last step.
    pub learning_rate: f64,
    /// Validation LLH at its end, when validation images were given.
    pub validation_llh: Option<f64>,
    /// Wall time of its steps, in seconds.
    pub seconds: f64,
    /// Training throughput.
    pub images_per_second: f64,
}

/// Trains until `options.epochs` epochs are done, from wherever `trainer` is (a trainer from
/// [`crate::rotation::Trainer::resume`] continues). Each epoch draws a permutation of the
/// images (seeded by the trainer's seed and the epoch), takes `steps_per_epoch` batches from
/// it, then evaluates the validation LLH, saves a checkpoint into `run_dir` and rewrites
/// `run_dir/train_log.csv` (both atomically). `on_step` sees every step (for progress bars).
pub fn fit<T: FitTarget>(
    trainer: &mut T,
    train: &T::Data,
    validation: Option<&T::Data>,
    options: &FitOptions,
    run_dir: &Path,
    mut on_step: impl FnMut(&StepReport),
) -> Result<Vec<EpochReport>, ModelError> {
    if options.steps_per_epoch == 0 || options.batch_size == 0 || options.epochs == 0 {
        return Err(ModelError::option(
            "epochs",
            format!("{options:?}: epochs, steps_per_epoch and batch_size must be ≥ 1"),
        ));
    }
    let mut log = read_log(run_dir, trainer.steps_done() / options.steps_per_epoch);
    let mut reports = Vec::new();
    let first_epoch = trainer.steps_done() / options.steps_per_epoch;
    for epoch in first_epoch..options.epochs {
        let mut order: Vec<usize> = (0..T::examples(train)).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(trainer.seed() ^ 0x5eed_ba7c);
        rng.set_stream(epoch);
        order.shuffle(&mut rng);
        let started = Instant::now();
        let mut loss_sum = 0.0;
        let mut last = None;
        let done_in_epoch = trainer.steps_done() - epoch * options.steps_per_epoch;
        for step in done_in_epoch..options.steps_per_epoch {
            let indices: Vec<usize> = (0..options.batch_size)
                .map(|i| order[(step as usize * options.batch_size + i) % order.len()])
                .collect();
            let report = trainer.train_batch(train, &indices)?;
            loss_sum += report.loss;
            on_step(&report);
            last = Some(report);
        }
        let seconds = started.elapsed().as_secs_f64();
        let steps = (options.steps_per_epoch - done_in_epoch).max(1);
        let validation_llh = match validation {
            Some(data) => Some(trainer.validation_llh(data, options)?),
            None => None,
        };
        let report = EpochReport {
            epoch: epoch + 1,
            step: trainer.steps_done(),
            loss: loss_sum / steps as f64,
            learning_rate: last.map_or(0.0, |r| r.learning_rate),
            validation_llh,
            seconds,
            images_per_second: (steps as usize * options.batch_size) as f64 / seconds.max(1e-9),
        };
        trainer.save_to(run_dir)?;
        log.push(log_line(&report));
        write_log(run_dir, &log)?;
        reports.push(report);
    }
    Ok(reports)
}

fn log_line(report: &EpochReport) -> String {
    format!(
        "{},{},{:.6},{:.6e},{},{:.3},{:.2}",
        report.epoch,
        report.step,
        report.loss,
        report.learning_rate,
        report
            .validation_llh
            .map_or(String::new(), |v| format!("{v:.6}")),
        report.seconds,
        report.images_per_second
    )
}

/// The lines of an existing log for epochs up to `epochs_done` (later lines belong to a run
/// that was killed before its checkpoint).
fn read_log(run_dir: &Path, epochs_done: u64) -> Vec<String> {
    let Ok(text) = std::fs::read_to_string(run_dir.join(TRAIN_LOG)) else {
        return Vec::new();
    };
    text.lines()
        .skip(1)
        .filter(|line| {
            line.split(',')
                .next()
                .and_then(|e| e.parse::<u64>().ok())
                .is_some_and(|e| e <= epochs_done)
        })
        .map(str::to_string)
        .collect()
}

fn write_log(run_dir: &Path, lines: &[String]) -> Result<(), ModelError> {
    let mut text = String::from(LOG_HEADER);
    text.push('\n');
    for line in lines {
        text.push_str(line);
        text.push('\n');
    }
    write_text_atomically(&run_dir.join(TRAIN_LOG), &text)
}
