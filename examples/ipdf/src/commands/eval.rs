//! `ipdf eval`: LLH, MAAD and Recall MAAD of a trained model on a split with ground truth,
//! against the full ground-truth symmetry set of each instance; translation LLH and errors of a
//! translation model; and for a pose run (a rotation model with one in `translation/`) both,
//! with the joint LLH and the ADD-S AUC. Rotation and pose runs are scored per instance too, as
//! real frames are (Acc@15°, Acc@30°, ADD(-S)), in the JSON and a Markdown table beside it.
use std::path::PathBuf;

use anyhow::{Result, bail};
use bop_dataset::{write_atomically, write_json};
use ipdf::eval::instances::markdown;
use ipdf::eval::translation::is_translation_run;
use ipdf::eval::{
    EvalRequest, MIN_VISIBLE_FRACTION, Truth, evaluate_run, evaluate_translation_run,
};
use ipdf::progress::bar;
use ipdf::training_data::CropSource;

use super::choice::choice;

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
    /// What the crops are cut around: the visible masks (`mask_visib/`), the visible boxes
    /// (`bbox_visib` of `scene_gt_info.json`: a detector's box, everything inside it), or masks
    /// where the split has them and boxes where not (default for runs trained on masks; runs
    /// trained with `--crop box` are scored on boxes).
    #[arg(long, value_parser = choice::<CropSource>())]
    pub crop: Option<CropSource>,
    /// Leave out instances less visible than this (`visib_fract` of `scene_gt_info.json`;
    /// BOP scores from 0.1).
    #[arg(long, default_value_t = MIN_VISIBLE_FRACTION)]
    pub min_visib: f64,
    /// What each instance's rotations are scored against: its ground truth with the
    /// symmetries of models_info.json, or its reference set A of `ipdf label --reference`
    /// (every pose the view cannot tell apart; instances without one are left out).
    #[arg(long, default_value = "gt", value_parser = choice::<Truth>())]
    pub truth: Truth,
    /// Beside the models' own, score a pose found from this many of the rotation model's
    /// hypotheses (its rotation estimate, then its densest cells 30° apart) and each frame's
    /// depth inside the instance's visible mask: each placed on the masked points, refined by
    /// ICP and scored by render-and-compare, the depth choosing among them where it can tell
    /// them apart and the image where it cannot (0: off; 8 is the mesh pipeline's). A split
    /// without depth under any visible mask is scored as without it.
    #[arg(long, default_value_t = 0)]
    pub depth_hypotheses: usize,
    #[command(flatten)]
    pub frames: super::FrameArgs,
    /// Each crop's rotation estimate (its error, Acc@15°, the pose scored, the first depth
    /// hypothesis) is the centre of the ball of this many degrees holding the most probability
    /// instead of the most likely rotation: the estimate most often within that angle of the
    /// truth (15 is the mesh pipeline's; off: the argmax, as the paper scores).
    #[arg(long)]
    pub ball: Option<f64>,
    /// Write the scores here (JSON), each instance's as a Markdown table beside it (`.md`).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `ipdf eval`; returns its [`EvalResult`].
pub fn run(args: &EvalArgs) -> Result<serde_json::Value> {
    if !(0.0..=1.0).contains(&args.min_visib) {
        bail!("--min-visib {}: a visible fraction, 0 to 1", args.min_visib);
    }
    super::check_ball(args.ball)?;
    let request = EvalRequest {
        dataset: args.dataset.clone(),
        models_dir: args.models_dir.clone(),
        obj_id: args.obj_id,
        dense: args.dense,
        crop: args.crop,
        min_visible_fraction: args.min_visib,
        per_instance: true,
        truth: args.truth,
        depth_hypotheses: args.depth_hypotheses,
        sensor: args.frames.sensor,
        views: args.frames.views.into(),
        ball_deg: args.ball,
        ..EvalRequest::new(args.checkpoint.clone(), &args.split, args.level)
    };
    let progress = bar(0, "images");
    let result = if is_translation_run(&args.checkpoint)? {
        serde_json::to_value(evaluate_translation_run(&request, &progress)?)?
    } else {
        let result = evaluate_run(&request, &progress)?;
        if let Some(warning) = &result.warning {
            eprintln!("warning: {warning}");
        }
        if let Some(note) = result.repaired_rotations.note() {
            eprintln!("ipdf eval: {note}");
        }
        if let (Some(path), Some(accuracy)) = (&args.out, &result.accuracy) {
            let what = format!(
                "{} ({}), split {}, level {}",
                result.object, result.obj_id, result.split, result.level
            );
            let table = markdown(&result.heading(&what), &result.instances, accuracy);
            write_atomically(&path.with_extension("md"), |out| {
                std::io::Write::write_all(out, table.as_bytes())
            })?;
        }
        serde_json::to_value(result)?
    };
    progress.finish_and_clear();
    if let Some(path) = &args.out {
        write_json(path, &result)?;
    }
    Ok(result)
}
