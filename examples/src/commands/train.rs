//! `ipdf train`: an Implicit-PDF model of one object from a BOP dataset, on single, analytical
//! or pseudo label sets; resumes a run folder that holds a checkpoint.
use std::path::PathBuf;

use anyhow::{Result, bail};
use examples::dataset::BopDataset;
use examples::progress::bar;
use examples::run_info::RunInfo;
use examples::training_data::{ExampleOptions, LabelSource, choose_object, load_examples};
use ipdf_model::{
    Augmentation, CHECKPOINT_FILE, EncoderKind, FitOptions, ImplicitPdf, LabelledImages,
    LearningRateSchedule, ModelConfig, QuerySampling, TrainOptions, Trainer, default_device, fit,
    load_backbone,
};
use serde_json::json;

/// The encoder named on the command line.
pub fn parse_encoder(name: &str) -> Result<EncoderKind, String> {
    EncoderKind::ALL
        .into_iter()
        .find(|kind| kind.name() == name)
        .ok_or_else(|| {
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
    /// Label sets: the GT pose alone, the GT pose with the symmetries of models_info.json, or
    /// the pseudo labels of `ipdf label`.
    #[arg(long, value_enum)]
    pub labels: LabelSource,
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
    /// Image encoder: resnet18, resnet18-2, convnext-tiny, small-cnn.
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
    /// The paper's occlusion augmentation (rectangles over 10–50% of 80% of the crops).
    #[arg(long)]
    pub occlusion: bool,
    /// Query rotations per image and step: the rotated grid of this level (2: 4,608, as the
    /// reference; 1: 576 for quick CPU runs).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub query_level: u8,
    /// Steps per turn of a continuous symmetry in analytical label sets.
    #[arg(long, default_value_t = 36)]
    pub continuous_steps: usize,
    /// Pretrained encoder weights (.safetensors with torchvision names).
    #[arg(long)]
    pub pretrained: Option<PathBuf>,
}

/// Runs `ipdf train`; returns the last epoch's figures.
pub fn run(args: &TrainArgs, seed: u64) -> Result<serde_json::Value> {
    if args.continuous_steps == 0 {
        bail!("--continuous-steps must be at least 1");
    }
    if args.batch_size == 0 {
        bail!("--batch-size must be at least 1");
    }
    if args.out.exists() && !args.out.is_dir() {
        bail!("--out {}: exists and is not a folder", args.out.display());
    }
    let config = ModelConfig {
        encoder: args.encoder,
        input_size: args.input_size as i64,
        head_sizes: args.head.clone(),
        seed,
        ..ModelConfig::default()
    };
    config.validate()?;
    let dataset = BopDataset::open(&args.dataset, &args.models_dir)?;
    let (obj_id, object) = choose_object(&dataset, args.obj_id, args.object.as_deref())?;
    let examples = |split: &str, labels: LabelSource| ExampleOptions {
        split: split.to_string(),
        obj_id,
        labels,
        input_size: args.input_size,
        min_visible_fraction: 0.1,
        continuous_steps: args.continuous_steps,
    };
    let train = load_examples(&dataset, &examples(&args.split, args.labels))?;
    // Validation measures what every model should learn, the ground-truth symmetry set, where
    // the split has ground truth; otherwise the same kind of labels as training.
    let val_dir = dataset.root.join(&args.val_split);
    let validation = if val_dir.is_dir() {
        let has_truth = dataset
            .scene_ids(&args.val_split)?
            .iter()
            .all(|&id| dataset.scene(&args.val_split, id).gt_path().exists());
        let labels = if has_truth {
            LabelSource::Analytical
        } else {
            args.labels
        };
        Some(load_examples(&dataset, &examples(&args.val_split, labels))?)
    } else {
        None
    };
    let info = RunInfo {
        dataset: std::path::absolute(&args.dataset)?,
        models_dir: args.models_dir.clone(),
        split: args.split.clone(),
        labels: args.labels.name().to_string(),
        obj_id,
        object: object.clone(),
        occlusion: args.occlusion,
    };
    let device = default_device();
    let mut trainer = if args.out.join(CHECKPOINT_FILE).exists() {
        let previous = RunInfo::read(&args.out)?;
        if previous != info {
            bail!(
                "{} holds a run of other data or options ({:?}); choose another --out",
                args.out.display(),
                previous
            );
        }
        let trainer = Trainer::resume(&args.out, device)?;
        trainer
            .model()
            .config()
            .check_same(&config, &args.out.join(CHECKPOINT_FILE))?;
        trainer
    } else {
        let mut model = ImplicitPdf::new(config, device)?;
        if let Some(path) = &args.pretrained {
            load_backbone(&mut model, path)?;
        }
        let total = (args.epochs * args.steps_per_epoch).max(1);
        let options = TrainOptions {
            schedule: LearningRateSchedule {
                peak: args.learning_rate,
                warmup_steps: total / 20,
                total_steps: total,
            },
            queries: QuerySampling::Grid {
                level: args.query_level,
            },
            augmentation: if args.occlusion {
                Augmentation::OCCLUSION
            } else {
                Augmentation::COLOUR
            },
            seed,
            ..TrainOptions::default()
        };
        std::fs::create_dir_all(&args.out)?;
        info.write(&args.out)?;
        Trainer::new(model, options)?
    };
    let train_images = LabelledImages::new(train.crops.shallow_clone(), train.label_sets.clone())?;
    let validation_images = match &validation {
        Some(v) => Some(LabelledImages::new(
            v.crops.shallow_clone(),
            v.label_sets.clone(),
        )?),
        None => None,
    };
    let options = FitOptions {
        epochs: args.epochs,
        steps_per_epoch: args.steps_per_epoch,
        batch_size: args.batch_size,
        validation_level: 2,
    };
    let total_steps = args.epochs * args.steps_per_epoch;
    let progress = bar(total_steps, "steps");
    progress.set_position(trainer.step().min(total_steps));
    let reports = fit(
        &mut trainer,
        &train_images,
        validation_images.as_ref(),
        &options,
        &args.out,
        |_| progress.inc(1),
    )?;
    progress.finish_and_clear();
    let last = reports.last();
    Ok(json!({
        "run": args.out,
        "object": object,
        "obj_id": obj_id,
        "labels": args.labels.name(),
        "train_images": train.instances.len(),
        "validation_images": validation.as_ref().map(|v| v.instances.len()),
        "step": trainer.step(),
        "epochs_run": reports.len(),
        "loss": last.map(|r| r.loss),
        "validation_llh": last.and_then(|r| r.validation_llh),
        "images_per_s": last.map(|r| r.images_per_second),
        "seconds": reports.iter().map(|r| r.seconds).sum::<f64>(),
    }))
}
