//! `ipdf eval`: LLH, MAAD and Recall MAAD of a trained model on a split with ground truth,
//! against the full ground-truth symmetry set of each instance; translation LLH and errors of a
//! translation model; and for a pose run (a rotation model with one in `translation/`) both,
//! with the joint LLH and the ADD-S AUC.
use std::path::PathBuf;

use anyhow::Result;
use bop_dataset::write_json;
use ipdf::eval::translation::is_translation_run;
use ipdf::eval::{EvalRequest, evaluate_run, evaluate_translation_run};
use ipdf::progress::bar;

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
    /// The object's id in that dataset (default: the one the model was trained on), e.g. a
    /// real BOP dataset's id for a model trained on `ipdf synth --mesh` renders.
    #[arg(long)]
    pub obj_id: Option<u32>,
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

/// Runs `ipdf eval`; returns its [`EvalResult`].
pub fn run(args: &EvalArgs) -> Result<serde_json::Value> {
    let request = EvalRequest {
        checkpoint: args.checkpoint.clone(),
        dataset: args.dataset.clone(),
        models_dir: args.models_dir.clone(),
        obj_id: args.obj_id,
        split: args.split.clone(),
        level: args.level,
        dense: args.dense,
    };
    let progress = bar(0, "images");
    let result = if is_translation_run(&args.checkpoint)? {
        serde_json::to_value(evaluate_translation_run(&request, &progress)?)?
    } else {
        let result = evaluate_run(&request, &progress)?;
        if let Some(warning) = &result.warning {
            eprintln!("warning: {warning}");
        }
        serde_json::to_value(result)?
    };
    progress.finish_and_clear();
    if let Some(path) = &args.out {
        write_json(path, &result)?;
    }
    Ok(result)
}
