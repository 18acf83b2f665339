//! The paper's scores of a trained model on examples with ground truth: for each crop, the
//! normalised distribution on the grid (refined hierarchically, or dense), then LLH (mean
//! log-density over the ground-truth symmetry set), MAAD (expected distance of a sample to the
//! nearest ground-truth rotation) and Recall MAAD (mean distance of each ground-truth rotation
//! to the nearest predicted one), averaged over crops.
use std::path::{Path, PathBuf};

use bop_dataset::BopDataset;
use indicatif::ProgressBar;
use ipdf_model::{
    ArgmaxOptions, CellMasses, ImplicitPdf, Predictor, RefineOptions, TranslationPdf,
    UNDER_RESOLUTION_LIMIT, default_device,
};
use metrics::{Distribution, GridCell, RECALL_THRESHOLD, maad, recall_maad};
use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};
use so3_grid::Grid;

use crate::PipelineError;
use crate::plots::plot_distribution;
use crate::run_info::RunInfo;
use crate::training_data::{ExampleOptions, Examples, crop_tensor, load_examples, to_unit_floats};
use crate::translation_eval::{
    PoseEval, TranslationEval, evaluate_pose, evaluate_translation, pose_translation_model,
};

/// Mean scores over the crops evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Crops evaluated.
    pub images: usize,
    /// Mean log-likelihood of the ground-truth set (−2.29 for a uniform density).
    pub llh: f64,
    /// Mean absolute angular deviation, degrees.
    pub maad_deg: f64,
    /// Recall mean absolute angular deviation, degrees.
    pub recall_maad_deg: f64,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
    /// How far the grid is from resolving the model's peaks
    /// ([`Predictor::under_resolution`]), the mean over crops.
    pub under_resolution: f64,
}

/// Scores `model` on every crop of `examples`, its distribution evaluated on the cells
/// `grid` describes ([`RefineOptions::to_level`] for the hierarchical evaluation,
/// [`RefineOptions::dense`] for every cell of a level); `progress` advances by one per crop.
/// LLH is the reference implementation's: the density `exp(F(R) − ln Z)` at each ground-truth
/// rotation itself, `Z` from the grid; MAAD and Recall MAAD come from the `metrics` crate on
/// the cells' masses. Fails when the examples have no ground truth.
pub fn evaluate(
    model: &ImplicitPdf,
    examples: &Examples,
    grid: &RefineOptions,
    progress: &ProgressBar,
) -> Result<Scores, PipelineError> {
    Ok(evaluate_rotations(model, examples, grid, false, progress)?.0)
}

/// [`evaluate`], and with `argmax` each crop's most likely rotation too
/// ([`Predictor::argmax_from`] on the same distribution; empty without). Each crop's image term
/// is computed once.
pub fn evaluate_rotations(
    model: &ImplicitPdf,
    examples: &Examples,
    grid: &RefineOptions,
    argmax: bool,
    progress: &ProgressBar,
) -> Result<(Scores, Vec<UnitQuaternion<f64>>), PipelineError> {
    let Some(truths) = &examples.truth_sets else {
        return Err(PipelineError::option(
            "dataset",
            "evaluation needs the split's scene_gt.json",
        ));
    };
    let mut predictor = Predictor::new(model);
    let argmax_options = ArgmaxOptions {
        refine: *grid,
        ..ArgmaxOptions::default()
    };
    let (mut sum_llh, mut sum_maad, mut sum_recall, mut queries) = (0.0, 0.0, 0.0, 0);
    let mut sum_under = 0.0;
    let mut rotations = Vec::new();
    for (i, truth) in truths.iter().enumerate() {
        let crop = to_unit_floats(&examples.crops.get(i as i64));
        let image_term = predictor.image_term(&crop)?;
        let masses = predictor.hierarchical_for(&image_term, grid)?;
        let densities = predictor.log_densities_for(&image_term, truth, &masses)?;
        sum_llh += densities.iter().sum::<f64>() / densities.len().max(1) as f64;
        let distribution = cell_distribution(&masses)?;
        sum_maad += maad(&distribution, truth)?;
        sum_recall += recall_maad(&distribution, truth, RECALL_THRESHOLD)?;
        sum_under += predictor.under_resolution_for(&image_term, &masses)?;
        queries = queries.max(masses.queries);
        if argmax {
            let best = predictor.argmax_from(&image_term, &masses, &argmax_options)?;
            rotations.push(best.rotation);
        }
        progress.inc(1);
    }
    let n = truths.len().max(1) as f64;
    let scores = Scores {
        images: truths.len(),
        llh: sum_llh / n,
        maad_deg: sum_maad / n,
        recall_maad_deg: sum_recall / n,
        queries_per_image: queries,
        under_resolution: sum_under / n,
    };
    Ok((scores, rotations))
}

/// Which trained run to score, on what and on which grid.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalRequest {
    /// The run folder of `ipdf train`.
    pub checkpoint: PathBuf,
    /// Another copy of the dataset (default: the one the model was trained on).
    pub dataset: Option<PathBuf>,
    /// Another models folder of the dataset (default: the one the model was trained with).
    pub models_dir: Option<String>,
    /// Another object id in that dataset (default: the one the model was trained on): a model
    /// trained on synthetic renders of a mesh, scored on a real dataset that numbers the
    /// object otherwise.
    pub obj_id: Option<u32>,
    /// The split scored (it needs `scene_gt.json`).
    pub split: String,
    /// The level of the evaluation grid.
    pub level: u8,
    /// Every cell of the level (up to level 5), else level 2 refined hierarchically.
    pub dense: bool,
}

/// The scores of a run: the JSON of `ipdf eval` and the pipeline's `eval_levelN.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalResult {
    /// The object's name.
    pub object: String,
    /// The object's id.
    pub obj_id: u32,
    /// The labels the model was trained on.
    pub labels: String,
    /// The split scored.
    pub split: String,
    /// The level of the evaluation grid.
    pub level: u8,
    /// `hierarchical` or `dense`.
    pub evaluation: String,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
    /// Crops scored.
    pub images: usize,
    /// Mean log-likelihood of the ground-truth sets.
    pub llh: f64,
    /// Mean absolute angular deviation (degrees).
    pub maad_deg: f64,
    /// Recall mean absolute angular deviation (degrees).
    pub recall_maad_deg: f64,
    /// How far the grid is from resolving the model's peaks
    /// ([`Predictor::under_resolution`], mean over the crops).
    #[serde(default)]
    pub under_resolution: f64,
    /// Why the scores may mislead: a level too coarse for the model's sharpness.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
    /// The scores of the run's translation model (`translation/`), when it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<TranslationEval>,
    /// The two models' scores as a 6D pose, when the run has a translation model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseEval>,
}

/// The scores of a translation model's run: the JSON of `ipdf eval` on one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TranslationRunEval {
    /// The object's name.
    pub object: String,
    /// The object's id.
    pub obj_id: u32,
    /// The labels the model was trained on.
    pub labels: String,
    /// The split scored.
    pub split: String,
    /// The scores.
    pub translation: TranslationEval,
}

/// Scores the translation model run of `request` on its split (the grid options are for
/// rotations; translations are refined to 2 mm cells); `progress` advances by one per crop.
pub fn evaluate_translation_run(
    request: &EvalRequest,
    progress: &ProgressBar,
) -> Result<TranslationRunEval, PipelineError> {
    let (info, dataset) = run_dataset(request)?;
    let model = TranslationPdf::load(&request.checkpoint, default_device())?;
    let size = model.config().network.input_size as usize;
    let examples = load_examples(
        &dataset,
        &ExampleOptions::evaluation(&request.split, info.obj_id, size),
    )?;
    progress.set_length(examples.instances.len() as u64);
    let (translation, _) = evaluate_translation(&model, &examples, progress)?;
    Ok(TranslationRunEval {
        object: info.object,
        obj_id: info.obj_id,
        labels: info.labels,
        split: request.split.clone(),
        translation,
    })
}

/// The run's `run.json` (with the request's models folder and object id) and its dataset (the
/// request's copy, or where it was trained).
fn run_dataset(request: &EvalRequest) -> Result<(RunInfo, BopDataset), PipelineError> {
    let mut info = RunInfo::read(&request.checkpoint)?;
    if let Some(models_dir) = &request.models_dir {
        info.models_dir.clone_from(models_dir);
    }
    if let Some(obj_id) = request.obj_id {
        info.obj_id = obj_id;
    }
    let dataset = info.dataset(request.dataset.as_deref())?;
    Ok((info, dataset))
}

/// Scores the run of `request` on its split; `progress` has its length set to the crops and
/// advances by one per crop.
pub fn evaluate_run(
    request: &EvalRequest,
    progress: &ProgressBar,
) -> Result<EvalResult, PipelineError> {
    let grid = if request.dense {
        if request.level > 5 {
            return Err(PipelineError::option(
                "level",
                format!(
                    "--dense goes up to level 5 (2,359,296 cells); got --level {}",
                    request.level
                ),
            ));
        }
        RefineOptions::dense(request.level)
    } else {
        RefineOptions::to_level(request.level)
    };
    let (info, dataset) = run_dataset(request)?;
    let model = ImplicitPdf::load(&request.checkpoint, default_device())?;
    let size = model.config().input_size as usize;
    let options = ExampleOptions::evaluation(&request.split, info.obj_id, size);
    let examples = load_examples(&dataset, &options)?;
    let translation_model = pose_translation_model(&request.checkpoint, &model)?;
    let passes = if translation_model.is_some() { 2 } else { 1 };
    progress.set_length(passes * examples.instances.len() as u64);
    let (scores, rotations) = evaluate_rotations(
        &model,
        &examples,
        &grid,
        translation_model.is_some(),
        progress,
    )?;
    let (translation, pose) = match &translation_model {
        Some(translation_model) => {
            let (translation, translations) =
                evaluate_translation(translation_model, &examples, progress)?;
            let pose = evaluate_pose(
                &examples,
                &rotations,
                &translations,
                &dataset,
                info.obj_id,
                (scores.llh, translation.llh),
            )?;
            (Some(translation), Some(pose))
        }
        None => (None, None),
    };
    Ok(EvalResult {
        object: info.object,
        obj_id: info.obj_id,
        labels: info.labels,
        split: request.split.clone(),
        level: request.level,
        evaluation: if request.dense {
            "dense"
        } else {
            "hierarchical"
        }
        .into(),
        queries_per_image: scores.queries_per_image,
        images: scores.images,
        llh: scores.llh,
        maad_deg: scores.maad_deg,
        recall_maad_deg: scores.recall_maad_deg,
        under_resolution: scores.under_resolution,
        warning: (scores.under_resolution > UNDER_RESOLUTION_LIMIT).then(|| {
            format!(
                "level {} is too coarse for this model: its heaviest cells' mass changes by a \
                 factor of {:.1} when they are split (under-resolution {:.2} > {UNDER_RESOLUTION_LIMIT}), \
                 so LLH, MAAD and Recall MAAD are unreliable; score at --level {} or finer",
                request.level,
                scores.under_resolution.exp(),
                scores.under_resolution,
                request.level + 1
            )
        }),
        translation,
        pose,
    })
}

/// The file the pipeline keeps a run's scores at `level` in.
pub fn eval_file(run_dir: &Path, level: u8) -> PathBuf {
    run_dir.join(format!("eval_level{level}.json"))
}

/// The cells and masses of a (hierarchical or dense) evaluation as a `metrics` distribution.
pub fn cell_distribution(masses: &CellMasses) -> Result<Distribution, PipelineError> {
    let cells = masses
        .cells
        .iter()
        .map(|&(level, index)| GridCell { level, index })
        .collect();
    Ok(Distribution::from_cells(cells, masses.masses.clone())?)
}

/// The Implicit-PDF figure of `model`'s distribution for an 8-bit crop (`[3, S, S]`) on the
/// `level` grid, with `truth` drawn over it.
pub fn distribution_figure(
    model: &ImplicitPdf,
    crop: &[u8],
    truth: &[nalgebra::UnitQuaternion<f64>],
    level: u8,
    title: &str,
) -> Result<image::RgbImage, PipelineError> {
    let size = model.config().input_size as usize;
    let grid = Grid::new(level).map_err(|e| PipelineError::option("level", e.to_string()))?;
    let masses = Predictor::new(model).probabilities(&crop_tensor(crop, size), level)?;
    plot_distribution(crop, size, &grid.rotations(), &masses, truth, title)
}
