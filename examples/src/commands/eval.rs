//! `ipdf eval`: LLH, MAAD and Recall MAAD of a trained model on a split with ground truth,
//! against the full ground-truth symmetry set of each instance.
use std::path::PathBuf;

use anyhow::Result;
use examples::atomic::write_json;
use examples::evaluation::evaluate;
use examples::progress::bar;
use examples::run_info::RunInfo;
use examples::training_data::{ExampleOptions, load_examples};
use ipdf_model::{ImplicitPdf, RefineOptions, default_device};
use serde_json::json;

/// Arguments of `ipdf eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// Run folder of `ipdf train`.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// BOP dataset folder (default: the one the model was trained on).
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// The dataset's models folder (default: the one the model was trained with).
    #[arg(long)]
    pub models_dir: Option<String>,
    /// Split to evaluate on.
    #[arg(long, default_value = "val")]
    pub split: String,
    /// Level of the evaluation grid (4: 294,912 cells), reached by refining level 2
    /// hierarchically (level 4 in at most 14,336 network queries per image).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(0..=6))]
    pub level: u8,
    /// Evaluate every cell of the level's grid (the reference the hierarchical evaluation
    /// approximates; 21× the queries at level 4, up to level 5).
    #[arg(long)]
    pub dense: bool,
    /// Write the scores here (JSON).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `ipdf eval`; returns `{"object", "obj_id", "labels", "split", "level", "evaluation",
/// "queries_per_image", "images", "llh", "maad_deg", "recall_maad_deg"}`.
pub fn run(args: &EvalArgs) -> Result<serde_json::Value> {
    let grid = if args.dense {
        if args.level > 5 {
            anyhow::bail!(
                "--dense goes up to level 5 (2,359,296 cells); got --level {}",
                args.level
            );
        }
        RefineOptions::dense(args.level)
    } else {
        RefineOptions::to_level(args.level)
    };
    let mut info = RunInfo::read(&args.checkpoint)?;
    if let Some(models_dir) = &args.models_dir {
        info.models_dir.clone_from(models_dir);
    }
    let dataset = info.dataset(args.dataset.as_deref())?;
    let model = ImplicitPdf::load(&args.checkpoint, default_device())?;
    let size = model.config().input_size as usize;
    let options = ExampleOptions::evaluation(&args.split, info.obj_id, size);
    let examples = load_examples(&dataset, &options)?;
    let progress = bar(examples.instances.len() as u64, "images");
    let scores = evaluate(&model, &examples, &grid, &progress)?;
    progress.finish_and_clear();
    let result = json!({
        "object": info.object,
        "obj_id": info.obj_id,
        "labels": info.labels,
        "split": args.split,
        "level": args.level,
        "evaluation": if args.dense { "dense" } else { "hierarchical" },
        "queries_per_image": scores.queries_per_image,
        "images": scores.images,
        "llh": scores.llh,
        "maad_deg": scores.maad_deg,
        "recall_maad_deg": scores.recall_maad_deg,
    });
    if let Some(path) = &args.out {
        write_json(path, &result)?;
    }
    Ok(result)
}
