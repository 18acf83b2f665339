//! Training one Implicit-PDF model of one object on a BOP split (`ipdf train`, and each model of
//! `ipdf pipeline`): a rotation model or a translation model ([`Target`]), on the examples of
//! the chosen label source, validated on the ground truth where the validation split has it, in
//! a run folder that resumes.
use std::path::{Path, PathBuf};

use bop_dataset::BopDataset;
use bop_dataset::Progress;
use ipdf_model::rotation::{
    ImplicitPdf, LabelledImages, QuerySampling, TrainOptions, Trainer, write_ensemble,
};
use ipdf_model::translation::{
    LabelledTranslations, TranslationConfig, TranslationPdf, TranslationSpace,
    TranslationTrainOptions, TranslationTrainer,
};
use ipdf_model::{
    Augmentation, CHECKPOINT_FILE, EpochReport, FitOptions, FitTarget, LearningRateSchedule,
    ModelConfig, default_device, fit, load_backbone, load_translation_backbone,
};
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::run_info::RunInfo;
use crate::training_data::{
    CropSource, ExampleOptions, Examples, LabelSource, choose_object, load_examples,
};

/// Which distribution a model learns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    /// The object's orientation, `p(R | I)` on SO(3).
    Rotation,
    /// The object's translation in the camera frame, `p(t | I)` over the working volume.
    Translation,
    /// Both, as two models: the rotation model in the run folder, the translation model in
    /// its `translation/` folder.
    Pose,
}

impl Target {
    /// `rotation`, `translation` or `pose`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Rotation => "rotation",
            Self::Translation => "translation",
            Self::Pose => "pose",
        }
    }

    /// Every target.
    pub const ALL: [Self; 3] = [Self::Rotation, Self::Translation, Self::Pose];
}

/// The folder of a pose run's translation model.
pub const TRANSLATION_DIR: &str = "translation";

/// What to train, on what, and where to keep it.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainRequest {
    /// The BOP dataset.
    pub dataset: PathBuf,
    /// Its folder of meshes and `models_info.json` (`models`; T-LESS: `models_cad`).
    pub models_dir: String,
    /// The training split.
    pub split: String,
    /// The validation split (skipped when there is no such folder).
    pub val_split: String,
    /// The object by id; `None` with `object_name` `None`: the dataset's only object.
    pub obj_id: Option<u32>,
    /// The object by name (`dataset_info.json`).
    pub object_name: Option<String>,
    /// The label sets trained on.
    pub labels: LabelSource,
    /// Rotation or translation (a pose is one request of each).
    pub target: Target,
    /// The network (its `seed` initialises the weights; its Fourier components encode the
    /// query, a rotation or a translation).
    pub model: ModelConfig,
    /// Epochs.
    pub epochs: u64,
    /// Steps per epoch.
    pub steps_per_epoch: u64,
    /// Images per step.
    pub batch_size: usize,
    /// Peak learning rate (linear warm-up over 5% of the steps, then cosine decay to 0).
    pub learning_rate: f64,
    /// The paper's occlusion augmentation, else colour augmentation only.
    pub occlusion: bool,
    /// Blur half the crops by a Gaussian of σ up to this many crop pixels (0: none).
    pub blur: f64,
    /// What the crops are cut around: masks, or boxes (jittered at training, as a detector's
    /// boxes are imprecise; the validation crops in the boxes as they are).
    pub crop: CropSource,
    /// Query rotations per image and step: the rotated grid of this level.
    pub query_level: u8,
    /// Query translations per image and step (translation models).
    pub translation_queries: usize,
    /// Steps per turn of a continuous symmetry in analytical label sets.
    pub continuous_steps: usize,
    /// Pretrained encoder weights (`.safetensors`, torchvision names).
    pub pretrained: Option<PathBuf>,
    /// Validate each epoch on the validation split's first this many crops (`None`: all).
    pub validation_images: Option<usize>,
    /// The run folder (one with a checkpoint resumes).
    pub out: PathBuf,
    /// Seed of the batches, queries and augmentation.
    pub seed: u64,
}

impl TrainRequest {
    /// The learning rate per step: linear warm-up over 5% of the steps to the peak, then
    /// cosine decay to 0 at the last.
    fn schedule(&self) -> LearningRateSchedule {
        let total = (self.epochs * self.steps_per_epoch).max(1);
        LearningRateSchedule {
            peak: self.learning_rate,
            warmup_steps: total / 20,
            total_steps: total,
        }
    }

    /// The paper's occlusion augmentation, or colour augmentation only; and the blur asked for.
    fn augmentation(&self) -> Augmentation {
        let base = if self.occlusion {
            Augmentation::OCCLUSION
        } else {
            Augmentation::COLOUR
        };
        Augmentation {
            blur_probability: if self.blur > 0.0 { 0.5 } else { 0.0 },
            blur_sigma: self.blur,
            ..base
        }
    }
}

/// What a training run did: the JSON of `ipdf train`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainResult {
    /// The run folder.
    pub run: PathBuf,
    /// The object's name.
    pub object: String,
    /// The object's id.
    pub obj_id: u32,
    /// `single`, `analytical` or `pseudo`.
    pub labels: String,
    /// `rotation` or `translation`.
    pub target: String,
    /// Training crops.
    pub train_images: usize,
    /// Validation crops, when there was a validation split.
    pub validation_images: Option<usize>,
    /// Steps done in all, earlier runs into the folder included.
    pub step: u64,
    /// Epochs run by this call.
    pub epochs_run: usize,
    /// The last epoch's mean loss.
    pub loss: Option<f64>,
    /// The last epoch's validation LLH (rotations: dense level-2 grid; translations: density
    /// per mm³ on the octree refined to 2 mm cells).
    pub validation_llh: Option<f64>,
    /// The last epoch's training speed.
    pub images_per_s: Option<f64>,
    /// Seconds spent training by this call.
    pub seconds: f64,
}

/// Trains (or resumes) the run of `request` (a rotation or a translation model; see
/// [`Target::Pose`] for both); `progress` advances by one per step. A run folder holding a run
/// of other data, another target or another network is refused.
pub fn train_model(request: &TrainRequest, progress: &dyn Progress) -> Result<TrainResult, Error> {
    request.model.validate()?;
    let dataset = BopDataset::open(&request.dataset, &request.models_dir)?;
    let (obj_id, object) = choose_object(&dataset, request.obj_id, request.object_name.as_deref())?;
    let examples = |split: &str, labels: LabelSource| ExampleOptions {
        split: split.to_string(),
        obj_id,
        labels,
        input_size: request.model.input_size as usize,
        min_visible_fraction: 0.1,
        continuous_steps: request.continuous_steps,
        crop: request.crop,
        box_jitter: None,
    };
    let train = load_examples(
        &dataset,
        &ExampleOptions {
            box_jitter: (request.crop == CropSource::Box).then_some(request.seed),
            ..examples(&request.split, request.labels)
        },
    )?;
    let validation = validation_examples(&dataset, request, &examples)?;
    let info = run_info(request, obj_id, &object)?;
    let (step, reports) = match request.target {
        Target::Rotation => {
            let mut trainer = open_trainer(request, &info)?;
            // Labels in the frame the model learns in.
            let frame = request.model.rotation_frame;
            let sets = train.sets_in_frame(&train.label_sets, frame)?;
            let data = LabelledImages::new(train.crops.shallow_clone(), sets)?;
            let validation = validation
                .as_ref()
                .map(|v| {
                    let n = validated(v, request);
                    let sets = v.sets_in_frame(&v.label_sets[..n], frame)?;
                    Ok::<_, Error>(LabelledImages::new(v.crops.narrow(0, 0, n as i64), sets)?)
                })
                .transpose()?;
            let reports = fit_run(&mut trainer, &data, validation.as_ref(), request, progress)?;
            (trainer.step(), reports)
        }
        Target::Translation => {
            let translations = |e: &Examples, n: usize| {
                LabelledTranslations::new(
                    e.crops.narrow(0, 0, n as i64),
                    e.geometry[..n].to_vec(),
                    e.translation_sets[..n].to_vec(),
                )
            };
            let data = translations(&train, train.instances.len())?;
            let mut trainer = open_translation_trainer(request, &info, &data)?;
            let validation = validation
                .as_ref()
                .map(|v| translations(v, validated(v, request)))
                .transpose()?;
            let reports = fit_run(&mut trainer, &data, validation.as_ref(), request, progress)?;
            (trainer.step(), reports)
        }
        Target::Pose => {
            return Err(Error::option(
                "target",
                "a pose is two runs: train the rotation and the translation target",
            ));
        }
    };
    let images = (
        train.instances.len(),
        validation.as_ref().map(|v| validated(v, request)),
    );
    Ok(TrainResult::of(
        request,
        (obj_id, object),
        images,
        step,
        &reports,
    ))
}

/// The `run.json` of `request`'s run of object `obj_id` called `object`.
fn run_info(request: &TrainRequest, obj_id: u32, object: &str) -> Result<RunInfo, Error> {
    Ok(RunInfo {
        dataset: std::path::absolute(&request.dataset)
            .map_err(|e| bop_dataset::FileError::new(&request.dataset, "folder", e.to_string()))?,
        models_dir: request.models_dir.clone(),
        split: request.split.clone(),
        labels: request.labels.name().to_string(),
        target: request.target.name().to_string(),
        obj_id,
        object: object.to_string(),
        occlusion: request.occlusion,
        crop: request.crop,
    })
}

impl TrainResult {
    /// The result of `request`'s run of `object` (id, name) on `images` (training crops,
    /// validation crops where validated), at `step`, from its epochs' `reports`.
    fn of(
        request: &TrainRequest,
        (obj_id, object): (u32, String),
        (train_images, validation_images): (usize, Option<usize>),
        step: u64,
        reports: &[EpochReport],
    ) -> Self {
        let last = reports.last();
        Self {
            run: request.out.clone(),
            object,
            obj_id,
            labels: request.labels.name().to_string(),
            target: request.target.name().to_string(),
            train_images,
            validation_images,
            step,
            epochs_run: reports.len(),
            loss: last.map(|r| r.loss),
            validation_llh: last.and_then(|r| r.validation_llh),
            images_per_s: last.map(|r| r.images_per_second),
            seconds: reports.iter().map(|r| r.seconds).sum(),
        }
    }
}

/// The most members an ensemble of rotation models has.
pub const MAX_MEMBERS: usize = 8;

/// The requests of an ensemble of `members` rotation models on the data of `request`: the
/// first is `request` itself, the `k`-th trains in `member-k` inside its run folder with both
/// seeds (the weights', and the batches', queries' and augmentation's) raised by `k − 1`
/// (wrapping past the largest seed).
/// Anything but a rotation model, or more than [`MAX_MEMBERS`], is refused.
pub fn ensemble_requests(
    request: &TrainRequest,
    members: usize,
) -> Result<Vec<TrainRequest>, Error> {
    if !(1..=MAX_MEMBERS).contains(&members) {
        return Err(Error::option(
            "members",
            format!("{members}: expected 1 to {MAX_MEMBERS}"),
        ));
    }
    if members > 1 && request.target != Target::Rotation {
        return Err(Error::option(
            "members",
            format!("{members}: only rotation models form ensembles"),
        ));
    }
    Ok((1..=members)
        .map(|k| {
            let raise = k as u64 - 1;
            TrainRequest {
                model: ModelConfig {
                    seed: request.model.seed.wrapping_add(raise),
                    ..request.model.clone()
                },
                out: if k == 1 {
                    request.out.clone()
                } else {
                    request.out.join(member_name(k))
                },
                seed: request.seed.wrapping_add(raise),
                ..request.clone()
            }
        })
        .collect())
}

/// Names the `members − 1` other members of [`ensemble_requests`] in the first's run folder
/// `out` ([`ENSEMBLE_FILE`](ipdf_model::rotation::ENSEMBLE_FILE)), once they are trained: every
/// reader of the checkpoint ([`ImplicitPdf::load_ensemble`]) then scores them together. One
/// member removes a stale file.
pub fn name_members(out: &Path, members: usize) -> Result<(), Error> {
    let names: Vec<String> = (2..=members).map(member_name).collect();
    Ok(write_ensemble(out, &names)?)
}

/// The folder of an ensemble's `k`-th member, relative to the first's.
fn member_name(k: usize) -> String {
    format!("member-{k}")
}

/// Trains (or resumes) the [`ensemble_requests`] one after the other ([`train_model`] each),
/// then [`name_members`]; `progress` restarts with each member.
pub fn train_ensemble(
    request: &TrainRequest,
    members: usize,
    progress: &dyn Progress,
) -> Result<Vec<TrainResult>, Error> {
    let results = ensemble_requests(request, members)?
        .iter()
        .map(|member| train_model(member, progress))
        .collect::<Result<Vec<_>, _>>()?;
    name_members(&request.out, members)?;
    Ok(results)
}

/// How many of `validation`'s crops `request` validates on.
fn validated(validation: &Examples, request: &TrainRequest) -> usize {
    let all = validation.instances.len();
    request.validation_images.map_or(all, |n| n.min(all))
}

/// [`fit`] with the request's epochs, steps and batch size; `progress` starts at the steps
/// already done.
fn fit_run<T: FitTarget>(
    trainer: &mut T,
    train: &T::Data,
    validation: Option<&T::Data>,
    request: &TrainRequest,
    progress: &dyn Progress,
) -> Result<Vec<EpochReport>, Error> {
    let options = FitOptions {
        epochs: request.epochs,
        steps_per_epoch: request.steps_per_epoch,
        batch_size: request.batch_size,
        validation_level: 2,
    };
    let total_steps = request.epochs * request.steps_per_epoch;
    progress.set_total(total_steps, trainer.steps_done().min(total_steps));
    Ok(fit(
        trainer,
        train,
        validation,
        &options,
        &request.out,
        |_| progress.advance(1),
    )?)
}

/// Whether the run folder `out` holds a finished run of `total_steps` steps.
pub fn is_trained(out: &Path, total_steps: u64) -> Result<bool, Error> {
    Ok(out.join(CHECKPOINT_FILE).exists()
        && ipdf_model::CheckpointInfo::read(out)?.step >= total_steps)
}

/// Validation measures what every model should learn, the ground-truth symmetry set, where the
/// split has ground truth; otherwise the same kind of labels as training. `None` without a
/// validation folder.
fn validation_examples(
    dataset: &BopDataset,
    request: &TrainRequest,
    examples: &impl Fn(&str, LabelSource) -> ExampleOptions,
) -> Result<Option<Examples>, Error> {
    if !dataset.root.join(&request.val_split).is_dir() {
        return Ok(None);
    }
    let has_truth = dataset
        .scene_ids(&request.val_split)?
        .iter()
        .all(|&id| dataset.scene(&request.val_split, id).gt_path().exists());
    let labels = if has_truth {
        LabelSource::Analytical
    } else {
        request.labels
    };
    Ok(Some(load_examples(
        dataset,
        &examples(&request.val_split, labels),
    )?))
}

/// The trainer of a run folder holding a checkpoint of this run, or of a new run (recorded in
/// `run.json`).
fn open_trainer(request: &TrainRequest, info: &RunInfo) -> Result<Trainer, Error> {
    let device = default_device();
    let out = &request.out;
    if resumes(out, info)? {
        let trainer = Trainer::resume(out, device)?;
        request
            .model
            .check_same(trainer.model().config(), &out.join(CHECKPOINT_FILE))?;
        return Ok(trainer);
    }
    let mut model = ImplicitPdf::new(request.model.clone(), device)?;
    if let Some(path) = &request.pretrained {
        load_backbone(&mut model, path)?;
    }
    let options = TrainOptions {
        schedule: request.schedule(),
        queries: QuerySampling::Grid {
            level: request.query_level,
        },
        augmentation: request.augmentation(),
        seed: request.seed,
        ..TrainOptions::default()
    };
    // Bad options are refused before the run folder is written to.
    options.validate()?;
    start_run(out, info)?;
    Ok(Trainer::new(model, options)?)
}

/// Whether `out` holds a checkpoint of the run `info` describes (then it resumes); an error
/// when it holds one of another run.
fn resumes(out: &Path, info: &RunInfo) -> Result<bool, Error> {
    if !out.join(CHECKPOINT_FILE).exists() {
        return Ok(false);
    }
    let previous = RunInfo::read(out)?;
    if previous != *info {
        return Err(Error::option(
            "out",
            format!(
                "{} holds a run of other data or options ({previous:?}); choose another --out",
                out.display()
            ),
        ));
    }
    Ok(true)
}

/// Creates the run folder `out` and its `run.json`.
fn start_run(out: &Path, info: &RunInfo) -> Result<(), Error> {
    std::fs::create_dir_all(out)
        .map_err(|e| bop_dataset::FileError::new(out, "folder", e.to_string()))?;
    info.write(out)?;
    Ok(())
}

/// The translation trainer of a run folder holding a checkpoint of this run, or of a new run
/// whose working volume is set from `data`'s labels.
fn open_translation_trainer(
    request: &TrainRequest,
    info: &RunInfo,
    data: &LabelledTranslations,
) -> Result<TranslationTrainer, Error> {
    let device = default_device();
    let out = &request.out;
    let network = request.model.clone();
    if resumes(out, info)? {
        let trainer = TranslationTrainer::resume(out, device)?;
        network.check_same(
            &trainer.model().config().network,
            &out.join(CHECKPOINT_FILE),
        )?;
        return Ok(trainer);
    }
    let space = TranslationSpace::from_labels(data.label_sets(), data.geometry())?;
    let mut model = TranslationPdf::new(TranslationConfig { network, space }, device)?;
    if let Some(path) = &request.pretrained {
        load_translation_backbone(&mut model, path)?;
    }
    let options = TranslationTrainOptions {
        schedule: request.schedule(),
        queries: request.translation_queries,
        augmentation: request.augmentation(),
        seed: request.seed,
        ..TranslationTrainOptions::default()
    };
    // Bad options are refused before the run folder is written to.
    options.validate()?;
    start_run(out, info)?;
    Ok(TranslationTrainer::new(model, options)?)
}
