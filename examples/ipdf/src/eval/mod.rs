//! Scores of trained runs on a BOP split with ground truth (`ipdf eval`, the pipeline's
//! `eval_levelN.json`): a rotation model's ([`rotation`]), a translation model's and a pose's
//! ([`translation`]), side by side, and per instance as real frames are scored
//! ([`instances`]).
pub mod instances;
pub mod rotation;
pub mod surface;
pub mod translation;

use std::path::{Path, PathBuf};

use bop_dataset::{BopDataset, Progress, RotationRepairs};
use depth_render::SensorPreset;
use ipdf_model::rotation::{ImplicitPdf, UNDER_RESOLUTION_LIMIT};
use ipdf_model::translation::TranslationPdf;
use ipdf_model::{RefineOptions, default_device};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::pipeline::config::{is_one, one};
use crate::run_info::RunInfo;
use crate::training_data::{CropSource, ExampleOptions, Examples, LabelSource, load_examples};
use instances::{Accuracy, InstanceScore, PoseParts, RefinedParts, score_instances};
use rotation::{Picks, RotationEvaluation, evaluate_rotations};
use translation::{
    ObjectModel, PoseEval, TranslationEval, evaluate_pose, evaluate_translation,
    pose_translation_model,
};

/// What each instance's rotations are scored against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Truth {
    /// The ground truth (`scene_gt.json`) with the symmetries of `models_info.json`.
    #[default]
    GroundTruth,
    /// The instance's reference set A (`scene_reference_gt.json` of `ipdf label --reference`):
    /// every pose the view cannot tell apart, a mug's arc where its handle is hidden. Instances
    /// without one are left out.
    Reference,
}

impl Truth {
    /// `gt` or `reference`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::GroundTruth => "gt",
            Self::Reference => "reference",
        }
    }

    /// Every choice.
    pub const ALL: [Self; 2] = [Self::GroundTruth, Self::Reference];
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
    /// What the crops are cut around (default: boxes for a run trained on boxes, else masks
    /// where the split has them and boxes where not).
    pub crop: Option<CropSource>,
    /// Instances less visible than this (`visib_fract`) are left out.
    pub min_visible_fraction: f64,
    /// Each instance's scores too (the most likely rotation of every crop: a little slower).
    pub per_instance: bool,
    /// What the rotations are scored against.
    pub truth: Truth,
    /// With per-instance scores, a pose found from this many of the rotation model's
    /// hypotheses and the frame's depth is scored beside the models' own
    /// ([`surface::depth_refined_poses`]; 0: none; a split without depth under any visible
    /// mask is scored as with 0).
    pub depth_hypotheses: usize,
    /// The depth camera of the split's frames: its expected errors are the unit in which that
    /// pose is compared with the depth (default: the labeller's).
    pub sensor: SensorPreset,
    /// Test-time views of each crop whose image terms the rotation model averages
    /// ([`ipdf_model::rotation::Predictor::with_views`]; 0: the crop alone, as the paper).
    pub views: usize,
    /// Each crop's rotation estimate is the centre of the ball of this radius (degrees) that
    /// holds the most probability ([`ipdf_model::CellMasses::heaviest_ball`]) instead of the
    /// most likely rotation (`None`, as the paper).
    pub ball_deg: Option<f64>,
}

impl EvalRequest {
    /// Scores of the run in `checkpoint` on `split`: the hierarchical evaluation to `level`,
    /// the run's dataset, object and crops, instances at least 10% visible (BOP's threshold),
    /// no per-instance scores.
    pub fn new(checkpoint: PathBuf, split: &str, level: u8) -> Self {
        Self {
            checkpoint,
            dataset: None,
            models_dir: None,
            obj_id: None,
            split: split.to_string(),
            level,
            dense: false,
            crop: None,
            min_visible_fraction: MIN_VISIBLE_FRACTION,
            per_instance: false,
            truth: Truth::GroundTruth,
            depth_hypotheses: 0,
            sensor: pseudo_label::LabelOptions::default().sensor,
            views: 0,
            ball_deg: None,
        }
    }

    /// The cells scored: every cell of the level (`dense`, up to level 5), else level 2 refined
    /// hierarchically to it.
    fn grid(&self) -> Result<RefineOptions, Error> {
        if !self.dense {
            return Ok(RefineOptions::to_level(self.level));
        }
        if self.level > 5 {
            let reason = format!(
                "--dense goes up to level 5 (2,359,296 cells); got --level {}",
                self.level
            );
            return Err(Error::option("level", reason));
        }
        Ok(RefineOptions::dense(self.level))
    }

    /// The examples the request scores, with crops of `size` pixels, for the run of `info`;
    /// with [`Truth::Reference`], their truth sets are the reference sets.
    fn examples(
        &self,
        dataset: &BopDataset,
        info: &RunInfo,
        size: usize,
    ) -> Result<Examples, Error> {
        let crop = self.crop.unwrap_or(match info.crop {
            CropSource::Box => CropSource::Box,
            _ => CropSource::Auto,
        });
        let labels = match self.truth {
            Truth::GroundTruth => LabelSource::Single,
            Truth::Reference => LabelSource::Reference,
        };
        let options = ExampleOptions {
            min_visible_fraction: self.min_visible_fraction,
            crop,
            labels,
            ..ExampleOptions::evaluation(&self.split, info.obj_id, size)
        };
        let mut examples = load_examples(dataset, &options)?;
        if self.truth == Truth::Reference {
            examples.truth_sets = Some(examples.label_sets.clone());
        }
        Ok(examples)
    }
}

/// [`Truth::GroundTruth`]'s name: what results written before [`EvalResult::truth`] were
/// scored against.
fn ground_truth_name() -> String {
    Truth::GroundTruth.name().into()
}

/// The rotation model's hypotheses a pose is refined from with depth where asked for
/// (`ipdf eval --depth-hypotheses`, the mesh pipeline's real split)…
pub const DEPTH_HYPOTHESES: usize = 8;
/// …at least this far apart (degrees): ICP from a start this far off a box's true pose still
/// lands on it (`pseudo_label::pose_from_hypotheses`' tests start 25° off).
pub const HYPOTHESIS_SPACING_DEG: f64 = 30.0;

/// BOP's least visible fraction of an instance scored.
pub const MIN_VISIBLE_FRACTION: f64 = 0.1;

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
    /// What the rotations were scored against: `gt` or `reference` ([`Truth`]).
    #[serde(default = "ground_truth_name")]
    pub truth: String,
    /// The level of the evaluation grid.
    pub level: u8,
    /// `hierarchical` or `dense`.
    pub evaluation: String,
    /// Test-time views averaged per crop beside the crop itself ([`EvalRequest::views`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub views: usize,
    /// The radius (degrees) of the heaviest ball whose centre is each crop's rotation estimate
    /// ([`EvalRequest::ball_deg`]; not written where the estimate is the most likely rotation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ball_deg: Option<f64>,
    /// Rotation models whose scores were averaged: the checkpoint's ensemble
    /// ([`ImplicitPdf::load_ensemble`]; 1: one model, and then not written).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub members: usize,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
    /// Crops scored.
    pub images: usize,
    /// Mean log-likelihood of the ground-truth sets (the reference sets with `truth`
    /// `reference`).
    pub llh: f64,
    /// Mean absolute angular deviation (degrees).
    pub maad_deg: f64,
    /// Recall mean absolute angular deviation (degrees).
    pub recall_maad_deg: f64,
    /// How far the grid is from resolving the model's peaks
    /// ([`ipdf_model::rotation::Predictor::under_resolution`], mean over the crops).
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
    /// Acc@15°, Acc@30° and ADD(-S) over the instances, when scored per instance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<Accuracy>,
    /// Each instance's scores, when asked for.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub instances: Vec<InstanceScore>,
    /// Ground-truth rotations orthonormal only to published precision, read as their nearest
    /// rotations.
    #[serde(default, skip_serializing_if = "RotationRepairs::is_empty")]
    pub repaired_rotations: RotationRepairs,
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
    progress: &dyn Progress,
) -> Result<TranslationRunEval, Error> {
    let (info, dataset) = run_dataset(request)?;
    let model = TranslationPdf::load(&request.checkpoint, default_device())?;
    let size = model.config().network.input_size as usize;
    let examples = request.examples(&dataset, &info, size)?;
    progress.set_total(examples.instances.len() as u64, 0);
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
fn run_dataset(request: &EvalRequest) -> Result<(RunInfo, BopDataset), Error> {
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
pub fn evaluate_run(request: &EvalRequest, progress: &dyn Progress) -> Result<EvalResult, Error> {
    let grid = request.grid()?;
    let (info, dataset) = run_dataset(request)?;
    let models = ImplicitPdf::load_ensemble(&request.checkpoint, default_device())?;
    let model = &models[0];
    let examples = request.examples(&dataset, &info, model.config().input_size as usize)?;
    let translation_model = pose_translation_model(&request.checkpoint, model)?;
    let passes = if translation_model.is_some() { 2 } else { 1 };
    progress.set_total(passes * examples.instances.len() as u64, 0);
    let refine = request.per_instance && request.depth_hypotheses > 0;
    let picks = Picks {
        estimates: translation_model.is_some() || request.per_instance,
        ball: request.ball_deg.map(f64::to_radians),
        hypotheses: if refine { request.depth_hypotheses } else { 0 },
        hypothesis_spacing: HYPOTHESIS_SPACING_DEG.to_radians(),
    };
    let evaluation = evaluate_rotations(&models, &examples, &grid, request.views, picks, progress)?;
    let scores = evaluation.scores;
    let (translation, pose, poses) = match &translation_model {
        Some(translation_model) => {
            let (translation, translations) =
                evaluate_translation(translation_model, &examples, progress)?;
            let object = ObjectModel::load(&dataset, info.obj_id)?;
            let pose = evaluate_pose(
                &examples,
                &evaluation.estimates,
                &translations,
                &object,
                (scores.llh, translation.llh),
            )?;
            (Some(translation), Some(pose), Some((translations, object)))
        }
        None => (None, None, None),
    };
    let (instances, accuracy) = if request.per_instance {
        let run = ScoredRun {
            request,
            dataset: &dataset,
            obj_id: info.obj_id,
            examples: &examples,
            evaluation: &evaluation,
        };
        let (rows, accuracy) = run.score_each_instance(poses.as_ref(), refine)?;
        (rows, Some(accuracy))
    } else {
        (Vec::new(), None)
    };
    let warning = warning(request, &info, &examples, scores.under_resolution);
    Ok(EvalResult {
        object: info.object,
        obj_id: info.obj_id,
        labels: info.labels,
        split: request.split.clone(),
        truth: request.truth.name().into(),
        level: request.level,
        evaluation: if request.dense {
            "dense"
        } else {
            "hierarchical"
        }
        .into(),
        views: request.views,
        ball_deg: request.ball_deg,
        members: models.len(),
        queries_per_image: scores.queries_per_image,
        images: scores.images,
        llh: scores.llh,
        maad_deg: scores.maad_deg,
        recall_maad_deg: scores.recall_maad_deg,
        under_resolution: scores.under_resolution,
        warning,
        translation,
        pose,
        accuracy,
        instances,
        repaired_rotations: examples.repairs,
    })
}

/// Each crop's pose found with its frame's depth (where one was), and that pose's rotation's
/// VSD to the truth.
type RefinedWithDepth = (Vec<Option<Isometry3<f64>>>, Vec<Option<f64>>);

/// What the per-instance scores of a run read: the request, the dataset, the object, its
/// crops and the rotation model's answers on them.
struct ScoredRun<'a> {
    request: &'a EvalRequest,
    dataset: &'a BopDataset,
    obj_id: u32,
    examples: &'a Examples,
    evaluation: &'a RotationEvaluation,
}

impl ScoredRun<'_> {
    /// Each instance's scores and their summary: the rotation's VSD, and where the run has a
    /// translation model (`poses`: its translations and the object) the pose's and the
    /// translation fitted to the frame's depth; with `refine`, the pose found from the
    /// hypotheses with the frame's depth too.
    fn score_each_instance(
        &self,
        poses: Option<&(Vec<Vector3<f64>>, ObjectModel)>,
        refine: bool,
    ) -> Result<(Vec<InstanceScore>, Accuracy), Error> {
        let fitted = match poses {
            Some((translations, _)) => self.depth_fitted(translations)?,
            None => Vec::new(),
        };
        let pose = poses.map(|(translations, object)| PoseParts {
            translations,
            object,
            fitted: &fitted,
        });
        let most_likely: Vec<_> = self
            .evaluation
            .estimates
            .iter()
            .copied()
            .map(Some)
            .collect();
        let vsd = self.vsd(&most_likely)?;
        let refined = if refine {
            self.refined_with_depth()?
        } else {
            None
        };
        let loaded;
        let object = match (&refined, poses) {
            (None, _) => None,
            (Some(_), Some((_, object))) => Some(object),
            (Some(_), None) => {
                loaded = ObjectModel::load(self.dataset, self.obj_id)?;
                Some(&loaded)
            }
        };
        let refined_parts = refined
            .as_ref()
            .zip(object)
            .map(|((poses, vsd), object)| RefinedParts { poses, vsd, object });
        score_instances(
            self.examples,
            self.evaluation,
            pose.as_ref(),
            refined_parts.as_ref(),
            &vsd,
            self.request.min_visible_fraction,
        )
    }

    /// Each crop's most likely pose (the rotation model's estimate, the translation model's
    /// `translations`) with its translation fitted to the frame's depth, where it could be.
    fn depth_fitted(
        &self,
        translations: &[Vector3<f64>],
    ) -> Result<Vec<Option<Vector3<f64>>>, Error> {
        let estimates: Vec<Isometry3<f64>> = translations
            .iter()
            .zip(&self.evaluation.estimates)
            .map(|(t, r)| Isometry3::from_parts((*t).into(), *r))
            .collect();
        surface::depth_fitted_translations(
            self.dataset,
            &self.request.split,
            self.obj_id,
            self.examples,
            &estimates,
        )
    }

    /// The VSD of each crop's `rotations` to the truth (`None` where there is none).
    fn vsd(&self, rotations: &[Option<UnitQuaternion<f64>>]) -> Result<Vec<Option<f64>>, Error> {
        surface::rotation_vsd(
            self.dataset,
            &self.request.split,
            self.obj_id,
            self.examples,
            rotations,
        )
    }

    /// The poses found from the rotation model's hypotheses with each frame's depth, and their
    /// rotations' VSD; `None` where the split has no depth.
    fn refined_with_depth(&self) -> Result<Option<RefinedWithDepth>, Error> {
        let request = self.request;
        let Some(poses) = surface::depth_refined_poses(
            self.dataset,
            &request.split,
            self.obj_id,
            self.examples,
            &self.evaluation.hypotheses,
            request.sensor,
        )?
        else {
            return Ok(None);
        };
        let rotations: Vec<_> = poses.iter().map(|p| p.map(|p| p.rotation)).collect();
        let vsd = self.vsd(&rotations)?;
        Ok(Some((poses, vsd)))
    }
}

/// Why the scores of `request` may mislead, if they may: a grid level too coarse for the
/// model's sharpness (its mean `under_resolution`), or crops cut around boxes, clutter and all,
/// for a model trained on masked crops, black off the object.
fn warning(
    request: &EvalRequest,
    info: &RunInfo,
    examples: &Examples,
    under_resolution: f64,
) -> Option<String> {
    let mut warnings = Vec::new();
    if under_resolution > UNDER_RESOLUTION_LIMIT {
        warnings.push(format!(
            "level {} is too coarse for this model: its heaviest cells' mass changes by a \
             factor of {:.1} when they are split (under-resolution {under_resolution:.2} > \
             {UNDER_RESOLUTION_LIMIT}), so LLH, MAAD and Recall MAAD are unreliable; score at \
             --level {} or finer",
            request.level,
            under_resolution.exp(),
            request.level + 1
        ));
    }
    if info.crop != CropSource::Box && examples.box_crops > 0 {
        warnings.push(format!(
            "{} of the {} crops of split {:?} are cut around the instance's box (bbox_visib), \
             everything inside it, for want of a visible mask (mask_visib/), while the model \
             was trained on masked crops, black off the object: it reads such crops poorly \
             (docs/results.md, \"Another real dataset\"); give the split visible masks, a \
             segmenter's or a detector's, to score it on what it was trained to see",
            examples.box_crops,
            examples.instances.len(),
            request.split
        ));
    }
    (!warnings.is_empty()).then(|| warnings.join("; and "))
}

/// Object `obj_id`'s mesh in `dataset`, at `scale` metres per mesh unit (BOP meshes are in
/// millimetres: 1.0 keeps them so, 0.001 gives metres); a mesh that cannot be read is an error
/// naming its file.
pub(crate) fn object_mesh(
    dataset: &BopDataset,
    obj_id: u32,
    scale: f64,
) -> Result<depth_render::TriangleMesh, Error> {
    let path = dataset.model_path(obj_id);
    Ok(depth_render::load_mesh(&path, scale)
        .map_err(|e| bop_dataset::FileError::new(&path, "mesh", e.to_string()))?
        .mesh)
}

/// The file the pipeline keeps a run's scores at `level` in.
pub fn eval_file(run_dir: &Path, level: u8) -> PathBuf {
    run_dir.join(format!("eval_level{level}.json"))
}

impl EvalResult {
    /// `what` scored, as the heading of the per-instance table: naming the ensemble when the
    /// scores average several rotation models, and the rotation estimate when it is not the
    /// argmax.
    pub fn heading(&self, what: &str) -> String {
        let mut heading = what.to_string();
        if self.members > 1 {
            heading += &format!(", an ensemble of {} rotation models", self.members);
        }
        if let Some(degrees) = self.ball_deg {
            heading += &format!(", each rotation the centre of its heaviest {degrees}° ball");
        }
        heading
    }
}

fn is_zero(count: &usize) -> bool {
    *count == 0
}
