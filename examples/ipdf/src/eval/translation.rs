//! Scores of translation models, and of a rotation model with a translation model as a 6D pose,
//! on examples with ground truth: the translation LLH (`ln p(t | I)` at the ground-truth
//! translation, density per mm³), the error of the most likely translation (mm), and, for
//! poses, the joint LLH and the ADD-S AUC (thresholds up to 10% of the object's diameter).
use std::path::{Path, PathBuf};

use bop_dataset::Progress;
use ipdf_metrics::{ModelPoints, SymmetryGroup, add_s, auc, translation_error};
use ipdf_model::rotation::ImplicitPdf;
use ipdf_model::translation::{
    CropGeometry, CropTerms, TranslationArgmax, TranslationArgmaxOptions, TranslationPdf,
    TranslationPredictor,
};
use ipdf_model::{CellMasses, default_device};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use tch::Tensor;

use bop_dataset::BopDataset;

use crate::Error;
use crate::median::median;
use crate::training::TRANSLATION_DIR;
use crate::training_data::{Examples, to_unit_floats};

/// The finest cells (mm) of the translation distributions scored.
pub const TRANSLATION_CELL_MM: f64 = 2.0;
/// Surface points of the object's mesh that ADD-S averages over.
const ADD_S_POINTS: usize = 2_000;
/// ADD-S AUC integrates thresholds from 0 to this fraction of the diameter (BOP, YCB-Video).
pub const ADD_S_AUC_FRACTION: f64 = 0.1;

/// A translation model's scores: the `"translation"` of `ipdf eval`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TranslationEval {
    /// Crops scored.
    pub images: usize,
    /// Mean `ln p(t | I)` at the ground-truth translation (nats, density per mm³; a uniform
    /// density over the working volume scores `−ln |V|`).
    pub llh: f64,
    /// Median distance of the most likely translation from the ground truth, mm.
    pub median_error_mm: f64,
    /// Mean distance, mm.
    pub mean_error_mm: f64,
    /// Median error along the ground truth's line of sight (depth), mm.
    pub median_depth_error_mm: f64,
    /// Median error across the line of sight, mm.
    pub median_lateral_error_mm: f64,
    /// Side of the finest octree cells, at most this (mm).
    pub cell_mm: f64,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
}

/// A rotation and a translation model scored together: the `"pose"` of `ipdf eval`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseEval {
    /// Mean of the rotation LLH plus the translation LLH over crops (the two models are
    /// independent given the image).
    pub joint_llh: f64,
    /// Area under the ADD-S accuracy curve for thresholds up to 10% of the diameter, in [0, 1].
    pub add_s_auc: f64,
    /// Median ADD-S of the most likely pose, mm.
    pub median_add_s_mm: f64,
    /// The object's diameter (mm, `models_info.json`).
    pub diameter_mm: f64,
}

/// One crop's translation distribution as scored (cells down to [`TRANSLATION_CELL_MM`]) and
/// its most likely translation.
pub struct TranslationPrediction {
    /// The hierarchical distribution.
    pub distribution: CellMasses,
    /// Its cells' centres (mm).
    pub centres: Vec<Vector3<f64>>,
    /// The most likely translation (gradient ascent from the densest cells).
    pub argmax: TranslationArgmax,
}

/// The distribution and most likely translation of `model` for one crop (`[3, S, S]` in
/// `[0, 1]`) cut out with `geometry`.
pub fn predict_translation(
    model: &TranslationPdf,
    crop: &Tensor,
    geometry: &CropGeometry,
) -> Result<TranslationPrediction, Error> {
    let predictor = TranslationPredictor::new(model);
    let terms = predictor.crop_terms(crop, geometry)?;
    predict_from(&predictor, &terms, geometry)
}

/// [`predict_translation`] from the crop's terms ([`TranslationPredictor::crop_terms`]).
fn predict_from(
    predictor: &TranslationPredictor,
    terms: &CropTerms,
    geometry: &CropGeometry,
) -> Result<TranslationPrediction, Error> {
    let options = TranslationArgmaxOptions {
        cell_size: TRANSLATION_CELL_MM,
        ..TranslationArgmaxOptions::default()
    };
    let refine = predictor.refine_options(geometry, options.cell_size);
    let distribution = predictor.hierarchical_for(terms, geometry, &refine)?;
    let argmax = predictor.argmax_from(terms, geometry, &distribution, &options)?;
    Ok(TranslationPrediction {
        centres: predictor.cell_centres(&distribution, geometry)?,
        distribution,
        argmax,
    })
}

/// The translation scores of `model` on `examples`, and the most likely translation of each
/// crop (mm); `progress` advances by one per crop. Fails when the examples have no ground truth.
pub fn evaluate_translation(
    model: &TranslationPdf,
    examples: &Examples,
    progress: &dyn Progress,
) -> Result<(TranslationEval, Vec<Vector3<f64>>), Error> {
    let truths = examples.required_truth_poses()?;
    let predictor = TranslationPredictor::new(model);
    let (mut llh, mut errors, mut argmax, mut queries) = (0.0, Vec::new(), Vec::new(), 0);
    let (mut depth_errors, mut lateral_errors) = (Vec::new(), Vec::new());
    for (i, truth) in truths.iter().enumerate() {
        let crop = to_unit_floats(&examples.crops.get(i as i64));
        let geometry = &examples.geometry[i];
        let truth = truth.translation.vector;
        let terms = predictor.crop_terms(&crop, geometry)?;
        let prediction = predict_from(&predictor, &terms, geometry)?;
        let distribution = &prediction.distribution;
        llh += predictor.log_densities_for(&terms, &[truth], distribution)?[0];
        queries = queries.max(distribution.queries);
        let best = prediction.argmax;
        errors.push(translation_error(&best.translation, &truth));
        let offset = best.translation - truth;
        let along = offset.dot(&truth.normalize());
        depth_errors.push(along.abs());
        lateral_errors.push((offset.norm_squared() - along * along).max(0.0).sqrt());
        argmax.push(best.translation);
        progress.advance(1);
    }
    let n = truths.len().max(1) as f64;
    let scores = TranslationEval {
        images: truths.len(),
        llh: llh / n,
        median_error_mm: median(&mut errors),
        mean_error_mm: errors.iter().sum::<f64>() / n,
        median_depth_error_mm: median(&mut depth_errors),
        median_lateral_error_mm: median(&mut lateral_errors),
        cell_mm: TRANSLATION_CELL_MM,
        queries_per_image: queries,
    };
    Ok((scores, argmax))
}

/// ADD-S of the poses made of the most likely rotations and translations (mm) of the crops of
/// `examples` against the ground truth, on the surface points of `object`; with the joint LLH
/// from the two models' mean LLHs.
pub fn evaluate_pose(
    examples: &Examples,
    rotations: &[UnitQuaternion<f64>],
    translations: &[Vector3<f64>],
    object: &ObjectModel,
    llh: (f64, f64),
) -> Result<PoseEval, Error> {
    let truths = examples.required_truth_poses()?;
    let mut errors = Vec::with_capacity(truths.len());
    for ((truth, rotation), translation) in truths.iter().zip(rotations).zip(translations) {
        let estimate = Isometry3::from_parts((*translation).into(), *rotation);
        errors.push(add_s(&object.points, &estimate, truth));
    }
    Ok(PoseEval {
        joint_llh: llh.0 + llh.1,
        add_s_auc: auc(&errors, ADD_S_AUC_FRACTION * object.diameter_mm)?,
        median_add_s_mm: median(&mut errors),
        diameter_mm: object.diameter_mm,
    })
}

/// What pose errors need of an object: points on its surface, its diameter, its symmetry.
pub struct ObjectModel {
    /// 2,000 points on the surface of its mesh (mm, as BOP meshes are).
    pub points: ModelPoints,
    /// Its diameter from `models_info.json` (mm).
    pub diameter_mm: f64,
    /// Whether `models_info.json` gives it symmetries (ADD-S scores it, else ADD).
    pub symmetric: bool,
}

impl ObjectModel {
    /// Object `obj_id` of `dataset`: its mesh sampled and its `models_info.json` entry.
    pub fn load(dataset: &BopDataset, obj_id: u32) -> Result<Self, Error> {
        let mesh = crate::eval::object_mesh(dataset, obj_id, 1.0)?;
        let (points, _) = depth_render::sample_surface(&mesh, ADD_S_POINTS, u64::from(obj_id));
        let points: Vec<Point3<f64>> = points.iter().map(|p| p.cast()).collect();
        let models = bop_dataset::read_models_info(&dataset.models_info_path())?;
        let info = models.get(&obj_id).ok_or_else(|| {
            bop_dataset::FileError::new(
                &dataset.models_info_path(),
                obj_id.to_string(),
                "no such object",
            )
        })?;
        Ok(Self {
            points: ModelPoints::new(&points)?,
            diameter_mm: info.diameter,
            symmetric: info.symmetry != SymmetryGroup::none(),
        })
    }
}

/// The `translation/` folder of a pose run, when it holds a checkpoint.
pub fn pose_translation_dir(run: &Path) -> Option<PathBuf> {
    let dir = run.join(TRANSLATION_DIR);
    dir.join(ipdf_model::CHECKPOINT_FILE)
        .exists()
        .then_some(dir)
}

/// The translation model of a pose run whose rotation model is `rotation`, when it has one,
/// checked to take the same crops.
pub fn pose_translation_model(
    run: &Path,
    rotation: &ImplicitPdf,
) -> Result<Option<TranslationPdf>, Error> {
    let Some(dir) = pose_translation_dir(run) else {
        return Ok(None);
    };
    let model = TranslationPdf::load(&dir, default_device())?;
    let (size, expected) = (
        model.config().network.input_size,
        rotation.config().input_size,
    );
    if size != expected {
        return Err(Error::option(
            "checkpoint",
            format!(
                "{}: the translation model takes {size} px crops, the rotation model {expected}",
                dir.display()
            ),
        ));
    }
    Ok(Some(model))
}

/// Whether the run folder `dir` holds a translation model's checkpoint (a folder without a
/// checkpoint is left to the rotation model's loader, whose error names what is missing).
pub fn is_translation_run(dir: &Path) -> Result<bool, Error> {
    if !dir.join(ipdf_model::CHECKPOINT_FILE).exists() {
        return Ok(false);
    }
    Ok(ipdf_model::CheckpointInfo::read(dir)?.translation.is_some())
}
