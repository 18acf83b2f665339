//! `ipdf train`: an Implicit-PDF model of one object from a BOP dataset, on single, analytical
//! or pseudo label sets, of its rotation, its translation or both; resumes a run folder that
//! holds a checkpoint.
use super::choice::choice;
use std::path::PathBuf;

use anyhow::{Result, bail};
use ipdf::progress::bar;
use ipdf::training::{MAX_MEMBERS, TRANSLATION_DIR, Target, TrainRequest, train_ensemble};
use ipdf::training_data::{CropSource, LabelSource};
use ipdf_model::rotation::RotationFrame;
use ipdf_model::{EncoderKind, ModelConfig};

/// The encoder named on the command line.
pub fn parse_encoder(name: &str) -> Result<EncoderKind, String> {
    EncoderKind::from_name(name).ok_or_else(|| {
        let names: Vec<_> = EncoderKind::ALL.iter().map(|k| k.name()).collect();
        format!("{name}: expected one of {}", names.join(", "))
    })
}

/// Arguments of `ipdf train`.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// BOP dataset folder.
    #[arg(long)]
    pub dataset: PathBuf,
    /// Label sets: the GT pose alone, the GT pose with the symmetries of models_info.json, the
    /// pseudo labels of `ipdf label`, or the reference sets of `ipdf label --reference` (every
    /// pose the labels' acceptance rule accepts: the yardstick of a model trained on pseudo
    /// labels).
    #[arg(long, value_parser = choice::<LabelSource>())]
    pub labels: LabelSource,
    /// What the model learns: the object's rotation, its translation (camera frame, mm), or
    /// both (the rotation model in --out, the translation model in --out/translation).
    #[arg(long, default_value = "rotation", value_parser = choice::<Target>())]
    pub target: Target,
    /// Run folder: checkpoint, run.json, train_log.csv (a folder with a checkpoint resumes).
    #[arg(long)]
    pub out: PathBuf,
    /// Training split.
    #[arg(long, default_value = "train")]
    pub split: String,
    /// Folder of the meshes and models_info.json, inside the dataset (T-LESS: models_cad).
    #[arg(long, default_value = "models")]
    pub models_dir: String,
    /// Validation split: LLH of its ground-truth symmetry sets every epoch (of its labels of
    /// the training kind when it has no ground truth; skipped when there is no such folder).
    #[arg(long, default_value = "val")]
    pub val_split: String,
    /// The object, by id (needed when the dataset has several).
    #[arg(long)]
    pub obj_id: Option<u32>,
    /// The object, by name (`dataset_info.json` of `ipdf synth`).
    #[arg(long, conflicts_with = "obj_id")]
    pub object: Option<String>,
    /// Image encoder: resnet18, resnet18-2, convnext-tiny, efficientnet-lite0, small-cnn,
    /// small-cnn-deep.
    #[arg(long, default_value = "resnet18", value_parser = parse_encoder)]
    pub encoder: EncoderKind,
    /// Side of the square input crop (pixels).
    #[arg(long, default_value_t = 224)]
    pub input_size: usize,
    /// Widths of the head's layers, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "256,256,256,256")]
    pub head: Vec<i64>,
    /// Epochs.
    #[arg(long, default_value_t = 50)]
    pub epochs: u64,
    /// Steps per epoch.
    #[arg(long, default_value_t = 200)]
    pub steps_per_epoch: u64,
    /// Images per step.
    #[arg(long, default_value_t = 64)]
    pub batch_size: usize,
    /// Peak learning rate (linear warm-up over 5% of the steps, then cosine decay to 0).
    #[arg(long, default_value_t = 1e-4)]
    pub learning_rate: f64,
    /// Peak learning rate of the translation model (`--target translation` or `pose`; default:
    /// --learning-rate). The quick pipeline trains its translation models at 2e-3 beside
    /// rotation models at 4e-3.
    #[arg(long)]
    pub translation_learning_rate: Option<f64>,
    /// The paper's occlusion augmentation (rectangles over 10–50% of 80% of the crops).
    #[arg(long)]
    pub occlusion: bool,
    /// Blur half the training crops (drawn per batch) by a Gaussian of σ uniform up to this many
    /// crop pixels, as real cameras' focus and motion blur soften images (0: none).
    #[arg(long, default_value_t = 0.0)]
    pub blur: f64,
    /// What the crops are cut around: the visible mask (background black), or the visible box
    /// (`bbox_visib`, else the mask's box) with everything inside it, each training box moved
    /// at random by up to 10% as a detector's are — for models that will be given a
    /// detector's box (`ipdf predict --bbox`, `ipdf eval --crop box`).
    #[arg(long, default_value = "mask", value_parser = choice::<CropSource>())]
    pub crop: CropSource,
    /// Query rotations per image and step: the rotated grid of this level (2: 4,608, as the
    /// reference; 1: 576 for quick CPU runs).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub query_level: u8,
    /// Query translations per image and step (translation models): the label's, the rest
    /// drawn around it and over the working volume.
    #[arg(long, default_value_t = 4_096, value_parser = clap::value_parser!(u64).range(2..=1_048_576))]
    pub translation_queries: u64,
    /// Steps per turn of a continuous symmetry in analytical label sets.
    #[arg(long, default_value_t = 36)]
    pub continuous_steps: usize,
    /// The frame the rotation model learns and answers in: the camera's, or the line of sight's
    /// through the crop's centre, where one look of the object is one rotation wherever in the
    /// image it was cut (answers are turned back into the camera's frame with the crop's box and
    /// the image's intrinsics). `ipdf pipeline --mesh` trains in the line of sight's.
    #[arg(long, value_parser = choice::<RotationFrame>(), default_value = "camera")]
    pub rotation_frame: RotationFrame,
    /// Rotation models trained as one ensemble, whose density is the members' geometric mean
    /// (renormalised) wherever the checkpoint is read: the first in --out, the k-th in
    /// --out/member-k from seed + k − 1, listed in --out/ensemble.json. Each costs a training.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=MAX_MEMBERS as u64))]
    pub members: u64,
    /// Pretrained encoder weights (.safetensors with torchvision names; efficientnet-lite0's
    /// ImageNet weights: .pretrained/efficientnet-lite0.safetensors, from `make setup`).
    #[arg(long)]
    pub pretrained: Option<PathBuf>,
    /// Keep the encoder's stem and first N blocks as --pretrained gives them (no gradients,
    /// batch norm in inference mode): efficientnet-lite0 only, N up to 16.
    #[arg(long, default_value_t = 0, requires = "pretrained")]
    pub freeze_encoder: usize,
}

/// Runs `ipdf train`; returns the last epoch's figures ([`TrainResult`]; for `--target pose`
/// `{"rotation": …, "translation": …}`).
pub fn run(args: &TrainArgs, seed: u64) -> Result<serde_json::Value> {
    check_args(args)?;
    let request = TrainRequest {
        dataset: args.dataset.clone(),
        models_dir: args.models_dir.clone(),
        split: args.split.clone(),
        val_split: args.val_split.clone(),
        obj_id: args.obj_id,
        object_name: args.object.clone(),
        labels: args.labels,
        target: args.target,
        model: ModelConfig {
            encoder: args.encoder,
            input_size: args.input_size as i64,
            head_sizes: args.head.clone(),
            seed,
            rotation_frame: args.rotation_frame,
            frozen_blocks: args.freeze_encoder,
            ..ModelConfig::default()
        },
        epochs: args.epochs,
        steps_per_epoch: args.steps_per_epoch,
        batch_size: args.batch_size,
        learning_rate: args.learning_rate,
        occlusion: args.occlusion,
        blur: args.blur,
        crop: args.crop,
        query_level: args.query_level,
        translation_queries: args.translation_queries as usize,
        continuous_steps: args.continuous_steps,
        pretrained: args.pretrained.clone(),
        validation_images: None,
        out: args.out.clone(),
        seed,
    };
    let train = |target: Target, out: PathBuf| -> Result<serde_json::Value> {
        let progress = bar(args.epochs * args.steps_per_epoch, "steps");
        let learning_rate = match target {
            Target::Translation => args.translation_learning_rate.unwrap_or(args.learning_rate),
            _ => args.learning_rate,
        };
        let members = match target {
            Target::Translation => 1,
            _ => args.members as usize,
        };
        let request = TrainRequest {
            target,
            out,
            learning_rate,
            ..request.clone()
        };
        let mut results = train_ensemble(&request, members, &progress)?.into_iter();
        progress.finish_and_clear();
        let mut first = serde_json::to_value(results.next())?;
        let others: Vec<_> = results.collect();
        if !others.is_empty() {
            first["members"] = serde_json::to_value(others)?;
        }
        Ok(first)
    };
    match args.target {
        Target::Pose => Ok(serde_json::json!({
            "rotation": train(Target::Rotation, args.out.clone())?,
            "translation": train(Target::Translation, args.out.join(TRANSLATION_DIR))?,
        })),
        target => train(target, args.out.clone()),
    }
}

/// Refuses the flag values `clap` cannot check alone.
fn check_args(args: &TrainArgs) -> Result<()> {
    if args.continuous_steps == 0 {
        bail!("--continuous-steps must be at least 1");
    }
    if args.batch_size == 0 {
        bail!("--batch-size must be at least 1");
    }
    if !(0.0..=10.0).contains(&args.blur) {
        bail!("--blur must be in 0..=10 crop pixels, got {}", args.blur);
    }
    if args.members > 1 && args.target == Target::Translation {
        bail!(
            "--members {}: only rotation models form ensembles",
            args.members
        );
    }
    if args.out.exists() && !args.out.is_dir() {
        bail!("--out {}: exists and is not a folder", args.out.display());
    }
    Ok(())
}
