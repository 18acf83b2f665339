//! `ipdf pipeline`: the whole method on synthetic data (see `ipdf::pipeline`); this module maps
//! the flags onto a [`Plan`].
use std::path::PathBuf;

use anyhow::Result;
use depth_render::SensorPreset;
use ipdf::pipeline::{Plan, Preset, run_pipeline};

use super::choice::choice;

/// Arguments of `ipdf pipeline`.
#[derive(Debug, clap::Args)]
pub struct PipelineArgs {
    /// How big a run: `quick` (minutes on a laptop CPU: 800 training frames per object, a small
    /// CNN on 48-pixel crops) or `paper` (the paper's scale, GPU advised: 20,000 frames per
    /// variant, ResNet-18 on 224-pixel crops, 50 epochs of 200 steps of 64; with and without
    /// occlusion, and two more backbones).
    #[arg(long, value_parser = choice::<Preset>(), default_value = "quick")]
    pub preset: Preset,
    /// Run folder (a rerun with the same settings skips finished stages; one with other
    /// settings is refused: see `pipeline_config.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// Override the preset's training frames per object (uniform dataset).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Override the preset's validation frames per object.
    #[arg(long)]
    pub val_frames: Option<usize>,
    /// Override the preset's frames per object of the textured dataset.
    #[arg(long)]
    pub texture_frames: Option<usize>,
    /// The depth camera whose readings the datasets' depth imitates and the labelling expects,
    /// instead of the preset's (both: a Kinect v1).
    #[arg(long, value_parser = choice::<SensorPreset>(), conflicts_with = "clean_depth")]
    pub sensor: Option<SensorPreset>,
    /// Clean rendered depth instead of a sensor's readings.
    #[arg(long)]
    pub clean_depth: bool,
    /// Override the preset's epochs (of the translation models too, unless
    /// --translation-epochs is given).
    #[arg(long)]
    pub epochs: Option<u64>,
    /// Override the preset's epochs of the translation models.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub translation_epochs: Option<u64>,
    /// Override the preset's steps per epoch.
    #[arg(long)]
    pub steps_per_epoch: Option<u64>,
}

/// Runs `ipdf pipeline`; returns where the report is and the time per stage.
pub fn run(args: &PipelineArgs, seed: u64) -> Result<serde_json::Value> {
    let preset = args.preset.plan();
    let plan = Plan {
        frames: args.frames.unwrap_or(preset.frames),
        val_frames: args.val_frames.unwrap_or(preset.val_frames),
        texture_frames: args.texture_frames.unwrap_or(preset.texture_frames),
        sensor: if args.clean_depth {
            None
        } else {
            args.sensor.or(preset.sensor)
        },
        epochs: args.epochs.unwrap_or(preset.epochs),
        translation_epochs: args
            .translation_epochs
            .or(args.epochs)
            .unwrap_or(preset.translation_epochs),
        steps_per_epoch: args.steps_per_epoch.unwrap_or(preset.steps_per_epoch),
        ..preset
    };
    Ok(serde_json::to_value(run_pipeline(&args.out, &plan, seed)?)?)
}
