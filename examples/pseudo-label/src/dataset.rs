//! Labelling a BOP split: options, sharding, the per-scene loop and its summary.
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;

use bop_dataset::{
    BopDataset, FileError, Intrinsics, Progress, PseudoInstance, PseudoLabel, SceneDir,
    as_recorded, check_recorded, mesh_appearance, read_depth, read_mask, read_object_ids, read_rgb,
    read_scene_camera, write_json, write_pseudo_gt,
};

use depth_render::SensorPreset;

use crate::early_stop;
use crate::instance::{InstanceLabels, LabelFailure, label_instance, noise_ratio};
use crate::{LabelError, ObjectModel, Observation, PixelLattice, ReferenceOptions, reference_set};

/// How the labels of an instance after the first are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    /// ICP re-seeded at the best pose composed with each self-symmetry of the model.
    Reseed,
    /// Independent trials from random initial poses, each label the best of `trials` (the
    /// paper's procedure).
    Trials,
}

impl Strategy {
    /// Every strategy.
    pub const ALL: [Self; 2] = [Self::Reseed, Self::Trials];

    /// `reseed` or `trials`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Reseed => "reseed",
            Self::Trials => "trials",
        }
    }
}

/// Options of the labelling; lengths are fractions of the object's diameter so that one set
/// fits objects of any size.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LabelOptions {
    /// K: at most this many labels per instance.
    pub labels: usize,
    /// M: global-alignment trials per label: fewer once one scores below `good_score`, up to
    /// 3M while none does (after the grid search, with [`Strategy::Reseed`]).
    pub trials: usize,
    /// How labels after the first are found.
    pub strategy: Strategy,
    /// Voxel size of the clouds, as a fraction of the diameter.
    pub voxel_fraction: f64,
    /// Surface samples of the model before downsampling.
    pub model_points: usize,
    /// The depth sensor whose expected error at each pixel is the unit of the render-and-compare
    /// score ([`crate::render_and_compare`]).
    pub sensor: SensorPreset,
    /// Per-pixel residuals are capped at this many expected errors (and a depth the pose does
    /// not explain costs as much).
    pub outlier_sigmas: f64,
    /// No pose scoring above this is a label: the true pose scores about 0.8 on the sensor's
    /// noise alone.
    pub max_score: f64,
    /// Poses scoring more than this above the best are dropped: what depth tells apart from
    /// the best pose is not a symmetry of it.
    pub score_margin: f64,
    /// A trial scoring below this stops the search for the first label early; over a
    /// dataset, raised per object and scene where its true poses score higher (see the
    /// `early_stop` module of this crate).
    pub good_score: f64,
    /// Labels closer than this (degrees) to a better one are merged into it.
    pub merge_angle_deg: f64,
    /// Where the view leaves a turn of a label free, poses this many degrees apart are walked
    /// along it and kept while accepted (0: off; see the `arc` module of this crate).
    pub arc_step_deg: f64,
    /// At most this many poses are added along free turns per instance, beyond `labels`.
    pub arc_labels: usize,
    /// At most this many self-symmetries are used for re-seeding, spread evenly.
    pub max_symmetries: usize,
    /// Where the mesh has colours and the image colour, labels whose colours match the image
    /// worse than the best label's by more than this are dropped ([`crate::appearance_match`],
    /// a correlation; 0: off, the default; [`APPEARANCE_MARGIN`] the measured choice): what
    /// depth cannot tell apart, the print on a box can. Off by default because the labels then
    /// hold only the printed pose where BOP's geometric symmetries (and the scores against
    /// them) hold its half turns too, and the quick preset's models trained on them read the
    /// print on their renders but not on real frames (docs/results.md, "Colour tells printed
    /// look-alikes apart"). Recorded in `label_options.json` only when on, so that splits
    /// labelled before it existed resume.
    #[serde(skip_serializing_if = "is_off")]
    pub appearance_margin: f64,
    /// Depth and mask are read at every n-th pixel of every n-th row ([`PixelLattice`]):
    /// the observed cloud is downsampled to voxels of millimetres anyway, and the
    /// render-and-compare score is a mean over the window, so 2 costs a quarter of the rays
    /// for the same labels.
    pub pixel_stride: u32,
    /// Seed of the initial poses and of FGR's sampling.
    pub seed: u64,
}

impl Default for LabelOptions {
    /// K = 8 labels, M = 3 trials, re-seeding, voxel 1/40 of the diameter, 20,000 model
    /// samples, a Kinect's expected error as the unit, residuals capped at 3, labels scoring
    /// under 1.3 and within 0.1 of the best, early stop under 0.9, merge within 2°, poses
    /// every 7.5° along free turns (at most 96 more), 32 symmetries, colours not compared,
    /// every other pixel, seed 0.
    fn default() -> Self {
        Self {
            labels: 8,
            trials: 3,
            strategy: Strategy::Reseed,
            voxel_fraction: 0.025,
            model_points: 20_000,
            sensor: SensorPreset::Kinect,
            outlier_sigmas: 3.0,
            max_score: 1.3,
            score_margin: 0.1,
            good_score: 0.9,
            merge_angle_deg: 2.0,
            arc_step_deg: 7.5,
            arc_labels: 96,
            max_symmetries: 32,
            appearance_margin: 0.0,
            pixel_stride: 2,
            seed: 0,
        }
    }
}

/// A margin of 0: the colour rule off.
fn is_off(margin: &f64) -> bool {
    *margin == 0.0
}

/// The [`LabelOptions::appearance_margin`]s that can be asked for: 0 (off) up to the widest a
/// correlation's difference can be.
pub const APPEARANCE_MARGINS: std::ops::RangeInclusive<f64> = 0.0..=2.0;

/// The [`LabelOptions::appearance_margin`] measured on textured scans' renders (off by
/// default: see the field).
pub const APPEARANCE_MARGIN: f64 = 0.2;

impl LabelOptions {
    /// These options for depth `ratio` times as noisy as the sensor's ([`crate::noise_ratio`]):
    /// `max_score` and `good_score` move with the true pose's expected score, 0.8 · ratio
    /// (E|N(0, ratio²)| in expected errors), so that a wrong pose is not accepted on depth
    /// cleaner than the sensor's (clean renders).
    pub fn for_noise(&self, ratio: f64) -> Self {
        let shift = Self::noise_shift(ratio);
        Self {
            max_score: self.max_score + shift,
            good_score: self.good_score + shift,
            ..self.clone()
        }
    }

    /// How far [`Self::for_noise`] moves the scores' thresholds for depth `ratio` times as
    /// noisy as the sensor's: 0.8 · (ratio − 1).
    pub fn noise_shift(ratio: f64) -> f64 {
        0.8 * (ratio - 1.0)
    }

    /// The highest score the acceptance rule accepts where the best pose scores `best`: under
    /// `max_score` and within `score_margin` of the best.
    pub fn accepted_score(&self, best: f64) -> f64 {
        self.max_score.min(best + self.score_margin)
    }

    fn validate(&self) -> Result<(), LabelError> {
        let positive = |name: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(LabelError::option(
                    name,
                    format!("{value}: must be positive"),
                ))
            }
        };
        positive("voxel_fraction", self.voxel_fraction)?;
        positive("outlier_sigmas", self.outlier_sigmas)?;
        positive("max_score", self.max_score)?;
        positive("good_score", self.good_score)?;
        if !(self.score_margin.is_finite() && self.score_margin >= 0.0) {
            return Err(LabelError::option("score_margin", "must be at least 0"));
        }
        if !APPEARANCE_MARGINS.contains(&self.appearance_margin) {
            let (off, most) = APPEARANCE_MARGINS.into_inner();
            return Err(LabelError::option(
                "appearance_margin",
                format!("must be {off} (off) to {most}"),
            ));
        }
        if !(self.merge_angle_deg.is_finite() && self.merge_angle_deg >= 0.0) {
            return Err(LabelError::option("merge_angle", "must be at least 0"));
        }
        if !(self.arc_step_deg.is_finite() && (0.0..=90.0).contains(&self.arc_step_deg)) {
            return Err(LabelError::option(
                "arc_step",
                "must be 0 (off) to 90 degrees",
            ));
        }
        for (name, value) in [
            ("labels", self.labels),
            ("trials", self.trials),
            ("model_points", self.model_points),
            ("max_symmetries", self.max_symmetries),
            ("pixel_stride", self.pixel_stride as usize),
        ] {
            if value == 0 {
                return Err(LabelError::option(name, "must be at least 1"));
            }
        }
        Ok(())
    }
}

/// Which part of a split one job labels: scene `k` (in sorted order) belongs to shard `k mod n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This job's shard, from 0.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// All scenes.
    pub const ALL: Self = Self { index: 0, count: 1 };

    /// Parses `i/n` (0 ≤ i < n).
    pub fn parse(text: &str) -> Result<Self, LabelError> {
        let bad = || LabelError::option("shard", format!("{text:?}: expected i/n with 0 ≤ i < n"));
        let (index, count) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            index.trim().parse::<usize>().map_err(|_| bad())?,
            count.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

/// What [`label_dataset`] did.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct LabelSummary {
    /// Scenes of this shard.
    pub scenes: usize,
    /// Of those, scenes already labelled by an earlier run.
    pub scenes_skipped: usize,
    /// Images labelled by this run.
    pub images: usize,
    /// Instances labelled by this run.
    pub instances: usize,
    /// Of those, instances with at least one label.
    pub labelled: usize,
    /// Labels written.
    pub labels: usize,
    /// Instances with a warning.
    pub warnings: usize,
    /// What loading repaired in each object's mesh, by object id (meshes loaded by this run
    /// that needed repairs only).
    pub mesh_repairs: BTreeMap<u32, depth_render::MeshRepairs>,
    /// Failed instances by kind ([`LabelFailure::kind`]).
    pub failures: BTreeMap<&'static str, usize>,
    /// The early stop of each object in each scene labelled by this run, by object id:
    /// `good_score`, or higher where a sample of the scene's instances scored higher (see
    /// the `early_stop` module of this crate).
    pub good_scores: BTreeMap<u32, Vec<f64>>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Where to find each instance's object and mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetOptions {
    /// The split's folder name (`train`, `test_primesense`, …).
    pub split: String,
    /// Metres per mesh unit (BOP: 0.001).
    pub mesh_scale: f64,
    /// The object id of every mask, for datasets without `scene_gt.json`.
    pub obj_id: Option<u32>,
    /// The scenes of this job.
    pub shard: Shard,
    /// Label this shard's scenes again, with these options, discarding their labels (else a
    /// split labelled with other options is refused, see [`LABEL_OPTIONS_FILE`]).
    pub relabel: bool,
}

/// The file in a split's folder that records the options its labels were made with: a rerun
/// with other options is refused (finished scenes would keep the old labels), unless it
/// relabels.
pub const LABEL_OPTIONS_FILE: &str = "label_options.json";

/// The file in a split's folder that records the options its reference sets
/// (`scene_reference_gt.json`, [`reference_dataset`]) were made with, as
/// [`LABEL_OPTIONS_FILE`] does for the labels.
pub const REFERENCE_OPTIONS_FILE: &str = "reference_options.json";

/// What a labelling of a split writes, and how it labels one instance: the labeller
/// ([`label_dataset`]) or the reference labeller ([`reference_dataset`]).
struct Job<'a> {
    /// The split's options file.
    options_file: &'static str,
    /// What it records beyond the label options.
    recorded: serde_json::Value,
    /// A scene's output file.
    output: fn(&SceneDir) -> std::path::PathBuf,
    /// The labels of one instance (its options and seed given).
    label: &'a (dyn Fn(&ObjectModel, &Observation, &LabelOptions, u64) -> InstanceLabels + Sync),
}

/// What `label_options.json` records: everything that decides the labels.
fn recorded_options(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    job: &Job,
) -> serde_json::Value {
    let models = dataset
        .models
        .file_name()
        .unwrap_or_default()
        .to_string_lossy();
    let mut recorded = serde_json::json!({
        "generator": "ipdf label",
        "models_dir": models,
        "mesh_scale": dataset_options.mesh_scale,
        "obj_id": dataset_options.obj_id,
    });
    // The options' fields beside those, so that a difference is named by its own key.
    if let (Some(all), Ok(serde_json::Value::Object(fields))) =
        (recorded.as_object_mut(), serde_json::to_value(options))
    {
        all.extend(fields);
    }
    if let (Some(all), serde_json::Value::Object(fields)) =
        (recorded.as_object_mut(), job.recorded.clone())
    {
        all.extend(fields);
    }
    as_recorded(recorded)
}

/// Labels every unlabelled scene of `options.split` in this shard (see the module docs);
/// `progress` advances by one per image (a skipped scene's images at once); its total is the
/// caller's to set ([`BopDataset::image_count`] counts a split's images).
pub fn label_dataset(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    progress: &dyn Progress,
) -> Result<LabelSummary, LabelError> {
    let job = Job {
        options_file: LABEL_OPTIONS_FILE,
        recorded: serde_json::json!({}),
        output: SceneDir::pseudo_gt_path,
        label: &label_instance,
    };
    run_split(dataset, dataset_options, options, &job, progress)
}

/// The reference sets A ([`reference_set`]) of every instance of `options.split` in this
/// shard, under the acceptance rule of `options`, written as `scene_reference_gt.json` beside
/// each scene's `scene_pseudo_gt.json` (the same format: A's poses are its labels), resumable
/// as [`label_dataset`] is, its options recorded in [`REFERENCE_OPTIONS_FILE`]. Slow: seconds
/// to a minute per instance (docs/results.md measures it).
pub fn reference_dataset(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    reference: &ReferenceOptions,
    progress: &dyn Progress,
) -> Result<LabelSummary, LabelError> {
    reference.validate()?;
    let job = Job {
        options_file: REFERENCE_OPTIONS_FILE,
        recorded: serde_json::json!({ "reference": reference }),
        output: SceneDir::reference_gt_path,
        label: &|model, observation, options, _| InstanceLabels {
            labels: reference_set(model, observation, options, reference).map(|set| set.poses),
            warning: None,
        },
    };
    run_split(dataset, dataset_options, options, &job, progress)
}

/// The scene loop of [`label_dataset`] and [`reference_dataset`].
fn run_split(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    job: &Job,
    progress: &dyn Progress,
) -> Result<LabelSummary, LabelError> {
    options.validate()?;
    dataset.check_models()?;
    let started = Instant::now();
    let scene_ids = shard_scenes(dataset, dataset_options)?;
    record_options(dataset, dataset_options, options, job, &scene_ids)?;
    let mut summary = LabelSummary {
        scenes: scene_ids.len(),
        ..LabelSummary::default()
    };
    let mut models: BTreeMap<u32, Option<Arc<ObjectModel>>> = BTreeMap::new();
    for scene_id in scene_ids {
        let scene = dataset.scene(&dataset_options.split, scene_id);
        let instances = scene_instances(&scene, dataset_options.obj_id)?;
        if (job.output)(&scene).exists() {
            summary.scenes_skipped += 1;
            progress.advance(instances.len() as u64);
            continue;
        }
        for obj_id in instances.values().flatten() {
            if !models.contains_key(obj_id) {
                models.insert(
                    *obj_id,
                    load_model(dataset, *obj_id, dataset_options, options, &mut summary)?,
                );
            }
        }
        let (labelled, good_scores) =
            label_scene(&scene, &instances, &models, options, job, progress)?;
        summary.count(&labelled);
        for (obj_id, good) in good_scores {
            summary.good_scores.entry(obj_id).or_default().push(good);
        }
        let labelled = labelled
            .into_iter()
            .map(|(im_id, list)| (im_id, list.into_iter().map(|o| o.instance).collect()))
            .collect();
        write_pseudo_gt(&(job.output)(&scene), &labelled)?;
    }
    summary.seconds = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// The scenes of `dataset_options.split` in this job's shard; an error when the split has
/// none.
fn shard_scenes(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
) -> Result<Vec<u32>, LabelError> {
    let shard = dataset_options.shard;
    let all_scenes = dataset.scene_ids(&dataset_options.split)?;
    if all_scenes.is_empty() {
        return Err(FileError::new(
            &dataset.root.join(&dataset_options.split),
            "folder",
            "no scene folders (six-digit names such as 000001)",
        )
        .into());
    }
    Ok(all_scenes
        .into_iter()
        .enumerate()
        .filter(|(k, _)| k % shard.count == shard.index)
        .map(|(_, id)| id)
        .collect())
}

/// Records the options in the split's options file of `job`: after discarding the labels of
/// `scene_ids` when relabelling, else after refusing options other than those recorded.
fn record_options(
    dataset: &BopDataset,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    job: &Job,
    scene_ids: &[u32],
) -> Result<(), LabelError> {
    let options_path = dataset
        .root
        .join(&dataset_options.split)
        .join(job.options_file);
    let recorded = recorded_options(dataset, dataset_options, options, job);
    if dataset_options.relabel {
        for &scene_id in scene_ids {
            let path = (job.output)(&dataset.scene(&dataset_options.split, scene_id));
            if path.exists() {
                std::fs::remove_file(&path)
                    .map_err(|e| FileError::new(&path, "file", format!("cannot remove: {e}")))?;
            }
        }
    } else {
        check_recorded(
            &options_path,
            &recorded,
            "rerun with the same options to complete the split, or add --relabel to label it \
             again with these",
        )?;
    }
    write_json(&options_path, &recorded)?;
    Ok(())
}

/// The labels of every image of `scene` (in parallel, by image id), `instances` giving the
/// object id of each of its instances by image id, and the early stop of each object
/// ([`early_stop`]): a sample of the images is labelled first to set it; `progress` advances
/// by one per image.
fn label_scene(
    scene: &SceneDir,
    instances: &BTreeMap<u32, Vec<u32>>,
    models: &BTreeMap<u32, Option<Arc<ObjectModel>>>,
    options: &LabelOptions,
    job: &Job,
    progress: &dyn Progress,
) -> Result<(ImageOutcomes, BTreeMap<u32, f64>), LabelError> {
    let cameras = read_scene_camera(&scene.camera_path())?;
    let ids: Vec<u32> = instances.keys().copied().collect();
    let (sample, rest) = early_stop::split_sample(&ids);
    let label = |ids: &[u32], per_object: &BTreeMap<u32, LabelOptions>| {
        ids.par_iter()
            .map(|&im_id| {
                let obj_ids = &instances[&im_id];
                let result = match cameras.get(&im_id) {
                    Some(intrinsics) => {
                        let image = Image {
                            scene,
                            im_id,
                            intrinsics,
                        };
                        label_image(&image, obj_ids, models, options, per_object, job)
                    }
                    None => failed_image(
                        obj_ids,
                        &LabelFailure::Input(format!(
                            "{}: image {im_id} is missing",
                            scene.camera_path().display()
                        )),
                    ),
                };
                progress.advance(1);
                (im_id, result)
            })
            .collect::<Vec<_>>()
    };
    let mut labelled = label(&sample, &BTreeMap::new());
    let scores: Vec<(u32, f64)> = labelled
        .iter()
        .flat_map(|(_, list)| list)
        .filter_map(|o| Some((o.instance.obj_id, o.sensor_score?)))
        .collect();
    let good_scores = early_stop::good_scores(options, &scores);
    let per_object = good_scores
        .iter()
        .map(|(&obj_id, &good_score)| {
            let options = LabelOptions {
                good_score,
                ..options.clone()
            };
            (obj_id, options)
        })
        .collect();
    labelled.extend(label(&rest, &per_object));
    labelled.sort_by_key(|(im_id, _)| *im_id);
    Ok((labelled, good_scores))
}

impl LabelSummary {
    /// Counts the images, instances, labels, warnings and failures of a scene's `labelled`
    /// images.
    fn count(&mut self, labelled: &ImageOutcomes) {
        for Outcome {
            instance, failure, ..
        } in labelled.iter().flat_map(|(_, list)| list)
        {
            self.instances += 1;
            self.labels += instance.labels.len();
            self.warnings += usize::from(instance.warning.is_some());
            match failure {
                None => self.labelled += 1,
                Some(kind) => *self.failures.entry(kind).or_default() += 1,
            }
        }
        self.images += labelled.len();
    }
}

/// Each image's id and the outcome of each of its instances.
type ImageOutcomes = Vec<(u32, Vec<Outcome>)>;

/// An instance's pseudo labels and what the labelling learnt of it.
struct Outcome {
    instance: PseudoInstance,
    /// The kind of failure, when labelling failed.
    failure: Option<&'static str>,
    /// The best label's score as on the sensor's own noise ([`LabelOptions::noise_shift`]
    /// taken off), when labelled.
    sensor_score: Option<f64>,
}

/// The outcome of an instance whose labelling failed with `failure`.
fn failed_instance(obj_id: u32, failure: &LabelFailure) -> Outcome {
    let instance = PseudoInstance {
        obj_id,
        error: Some(failure.to_string()),
        ..PseudoInstance::default()
    };
    Outcome {
        instance,
        failure: Some(failure.kind()),
        sensor_score: None,
    }
}

/// Image id → the object id of each instance, in mask order: from `scene_gt.json` (only
/// `obj_id`), or, without it, one instance of `obj_id` per `mask_visib` file.
fn scene_instances(
    scene: &SceneDir,
    obj_id: Option<u32>,
) -> Result<BTreeMap<u32, Vec<u32>>, LabelError> {
    let gt = scene.gt_path();
    if gt.exists() {
        return Ok(read_object_ids(&gt)?);
    }
    let Some(obj_id) = obj_id else {
        return Err(FileError::new(
            &gt,
            "file",
            "missing: the object id of each mask is unknown (give --obj-id for a one-object dataset)",
        )
        .into());
    };
    let cameras = read_scene_camera(&scene.camera_path())?;
    Ok(cameras
        .keys()
        .map(|&im_id| {
            let count = (0..)
                .take_while(|&k| scene.visible_mask_path(im_id, k).exists())
                .count();
            (im_id, vec![obj_id; count])
        })
        .collect())
}

/// The prepared model of `obj_id`, or `None` when it has no mesh file; what loading repaired
/// in the mesh goes into `summary`.
fn load_model(
    dataset: &BopDataset,
    obj_id: u32,
    dataset_options: &DatasetOptions,
    options: &LabelOptions,
    summary: &mut LabelSummary,
) -> Result<Option<Arc<ObjectModel>>, LabelError> {
    let path = dataset.model_path(obj_id);
    if !path.exists() {
        return Ok(None);
    }
    let loaded = depth_render::load_mesh(&path, dataset_options.mesh_scale)?;
    depth_render::check_mesh_size(
        &loaded.mesh,
        &path,
        dataset_options.mesh_scale,
        "--mesh-scale",
    )?;
    let appearance = mesh_appearance(&path, &loaded)?;
    if !loaded.repairs.is_empty() {
        summary.mesh_repairs.insert(obj_id, loaded.repairs);
    }
    let model = ObjectModel::new(obj_id, &loaded.mesh, options)?.with_appearance(appearance);
    Ok(Some(Arc::new(model)))
}

/// Every instance of an image failed for the same reason.
fn failed_image(obj_ids: &[u32], failure: &LabelFailure) -> Vec<Outcome> {
    obj_ids
        .iter()
        .map(|&obj_id| failed_instance(obj_id, failure))
        .collect()
}

/// A seed per instance, so that results do not depend on the order of work.
fn instance_seed(seed: u64, scene_id: u32, im_id: u32, instance: usize) -> u64 {
    let mut x = seed ^ (u64::from(scene_id) << 40) ^ (u64::from(im_id) << 16) ^ instance as u64;
    // splitmix64's finaliser
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// The colours of the image at `path` on the lattice, or why the colour rule cannot use it
/// (the warning its coloured instances carry): it cannot be read, or it is not of the depth's
/// `size`.
fn image_colour(
    path: &Path,
    size: (u32, u32),
    lattice: &PixelLattice,
) -> Result<Vec<[u8; 3]>, String> {
    let off = "labelled by depth alone (the colour rule is on)";
    let rgb = read_rgb(path).map_err(|error| format!("{off}: {error}"))?;
    if (rgb.width, rgb.height) != size {
        return Err(format!(
            "{off}: {} is {}×{} pixels, the depth {}×{}",
            path.display(),
            rgb.width,
            rgb.height,
            size.0,
            size.1
        ));
    }
    Ok(lattice.sample(&rgb.pixels, [0; 3]))
}

/// Both warnings, where an instance has two.
fn join_warnings(first: Option<String>, second: Option<String>) -> Option<String> {
    match (first, second) {
        (Some(first), Some(second)) => Some(format!("{first}; {second}")),
        (first, second) => first.or(second),
    }
}

/// One image of a scene.
struct Image<'a> {
    scene: &'a SceneDir,
    im_id: u32,
    intrinsics: &'a Intrinsics,
}

/// The labels of every instance of one image, by `job`, with the options of its object in
/// `per_object`, else `options`.
fn label_image(
    image: &Image,
    obj_ids: &[u32],
    models: &BTreeMap<u32, Option<Arc<ObjectModel>>>,
    options: &LabelOptions,
    per_object: &BTreeMap<u32, LabelOptions>,
    job: &Job,
) -> Vec<Outcome> {
    let Image {
        scene,
        im_id,
        intrinsics,
    } = *image;
    let depth_path = scene.depth_path(im_id);
    let depth = match read_depth(&depth_path, intrinsics.depth_scale) {
        Ok(depth) => depth,
        Err(error) => return failed_image(obj_ids, &LabelFailure::Input(error.to_string())),
    };
    let camera = match intrinsics.camera(depth.width, depth.height) {
        Ok(camera) => camera.camera,
        Err(error) => return failed_image(obj_ids, &LabelFailure::Input(error.to_string())),
    };
    // Sampled once per image; each instance samples only its mask.
    let lattice = PixelLattice::new(&camera, options.pixel_stride);
    let sampled_depth = lattice.sample(&depth.pixels, 0.0);
    // Read only where the colour rule is on and some object is coloured; where the image
    // cannot serve, its coloured instances are labelled by depth alone, with a warning.
    let coloured = |obj_id: &u32| {
        models
            .get(obj_id)
            .and_then(Option::as_ref)
            .is_some_and(|m| m.appearance.is_some())
    };
    let sampled_colour =
        (options.appearance_margin > 0.0 && obj_ids.iter().any(coloured)).then(|| {
            image_colour(
                &scene.rgb_path(im_id),
                (depth.width, depth.height),
                &lattice,
            )
        });
    let sampled = SampledImage {
        size: (depth.width, depth.height),
        lattice: &lattice,
        depth: &sampled_depth,
        colour: sampled_colour.as_ref(),
    };
    obj_ids
        .iter()
        .enumerate()
        .map(|(k, &obj_id)| {
            let Some(model) = models.get(&obj_id).and_then(Option::as_ref) else {
                return failed_instance(obj_id, &LabelFailure::UnknownObject { obj_id });
            };
            let object_options = per_object.get(&obj_id).unwrap_or(options);
            let instance = InstanceInput {
                obj_id,
                k,
                model,
                coloured: coloured(&obj_id),
            };
            label_one(image, &sampled, &instance, (options, object_options), job)
        })
        .collect()
}

/// An image's depth (and colour, where read) sampled on the labelling's pixel lattice.
struct SampledImage<'a> {
    /// The depth image's width and height (pixels): every mask must have them.
    size: (u32, u32),
    lattice: &'a PixelLattice,
    depth: &'a [f32],
    /// The colour where the rule reads it, or why it could not be read.
    colour: Option<&'a Result<Vec<[u8; 3]>, String>>,
}

/// One instance of an image: its object, its index among the image's masks, the object's
/// model and whether the colour rule applies to it.
struct InstanceInput<'a> {
    obj_id: u32,
    k: usize,
    model: &'a ObjectModel,
    coloured: bool,
}

/// The labels of instance `instance` of `image`, by `job`: its mask read and checked, then the
/// labeller run with `options.1` (the object's options; `options.0` the run's, whose sensor
/// and seed apply).
fn label_one(
    image: &Image,
    sampled: &SampledImage,
    instance: &InstanceInput,
    (options, object_options): (&LabelOptions, &LabelOptions),
    job: &Job,
) -> Outcome {
    let InstanceInput {
        obj_id,
        k,
        model,
        coloured,
    } = *instance;
    let mask_path = image.scene.visible_mask_path(image.im_id, k);
    let mask = match read_mask(&mask_path) {
        Ok(mask) => mask,
        Err(error) => return failed_instance(obj_id, &LabelFailure::Input(error.to_string())),
    };
    let (width, height) = sampled.size;
    if (mask.width, mask.height) != (width, height) {
        let failure = LabelFailure::MaskSize {
            mask: mask_path,
            mask_width: mask.width,
            mask_height: mask.height,
            width,
            height,
        };
        return failed_instance(obj_id, &failure);
    }
    let sampled_mask = sampled.lattice.sample(&mask.pixels, false);
    let Some(mut observation) =
        Observation::new(sampled.lattice.camera, sampled.depth, &sampled_mask)
    else {
        return failed_instance(obj_id, &LabelFailure::EmptyMask);
    };
    let mut colour_warning = None;
    match sampled.colour {
        Some(Ok(colour)) => observation = observation.with_colour(colour),
        Some(Err(warning)) if coloured => colour_warning = Some(warning.clone()),
        _ => {}
    }
    let seed = instance_seed(options.seed, image.scene.id, image.im_id, k);
    let found = (job.label)(model, &observation, object_options, seed);
    let sensor_score = found.labels.as_ref().ok().and_then(|labels| {
        let best = labels.iter().map(|l| l.score).min_by(f64::total_cmp)?;
        let ratio = noise_ratio(&observation, &options.sensor.sensor());
        Some(best - LabelOptions::noise_shift(ratio))
    });
    let (labels, error, kind) = match &found.labels {
        Ok(labels) => (labels.clone(), None, None),
        Err(failure) => (Vec::new(), Some(failure.to_string()), Some(failure.kind())),
    };
    let best = match found.labels {
        Err(LabelFailure::NoPoseAccepted {
            best, best_pose, ..
        }) if best.is_finite() => Some(PseudoLabel {
            pose: best_pose,
            score: best,
        }),
        _ => None,
    };
    let instance = PseudoInstance {
        obj_id,
        labels,
        error,
        warning: join_warnings(found.warning, colour_warning),
        best,
    };
    Outcome {
        instance,
        failure: kind,
        sensor_score,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The early stop's wiring. A scene of 100 images of one object, each a flat, clean depth
    /// patch (noise ratio 0, so each score is 0.8 under what the sensor's noise would give)
    /// 600 + i mm away, labelled by a stand-in that scores image i at 0.06 + 0.0005 i: the 64
    /// images ⌊100 j / 64⌋ are labelled with the good score as given, the other 36 with the
    /// upper fence of the sample's scores on the sensor's noise, 0.86 + 0.0005 i.
    #[test]
    fn the_rest_of_a_scene_gets_the_early_stop_of_its_sample() {
        let dir = tempfile::tempdir().unwrap();
        let scene = SceneDir {
            dir: dir.path().join("000000"),
            id: 0,
        };
        let (width, height) = (32, 24);
        let intrinsics = Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 16.0,
            cy: 12.0,
            depth_scale: 1.0,
        };
        for sub in ["depth", "mask_visib"] {
            std::fs::create_dir_all(scene.dir.join(sub)).unwrap();
        }
        let mut cameras = BTreeMap::new();
        for im_id in 0..100u32 {
            let depth = vec![0.6 + 0.001 * im_id as f32; width * height];
            let (w, h) = (width as u32, height as u32);
            bop_dataset::write_depth(&scene.depth_path(im_id), &depth, w, h, 1.0).unwrap();
            let mask = vec![true; width * height];
            bop_dataset::write_mask(&scene.mask_visib_path(im_id, 0), &mask, w, h).unwrap();
            cameras.insert(im_id, intrinsics);
        }
        bop_dataset::write_scene_camera(&scene.camera_path(), &cameras).unwrap();
        let instances: BTreeMap<u32, Vec<u32>> = (0..100).map(|im_id| (im_id, vec![1])).collect();
        let options = LabelOptions::default();
        let object = synth_data::SynthObject::built_in(synth_data::ObjectKind::Box).unwrap();
        let model = ObjectModel::new(1, &object.mesh, &options).unwrap();
        let models = BTreeMap::from([(1, Some(Arc::new(model)))]);

        let seen = std::sync::Mutex::new(BTreeMap::new());
        let stand_in = |_: &ObjectModel, observation: &Observation, options: &LabelOptions, _| {
            let centre = observation.depth[observation.depth.len() / 2];
            let im_id = ((f64::from(centre) - 0.6) * 1e3).round() as u32;
            seen.lock().unwrap().insert(im_id, options.good_score);
            InstanceLabels {
                labels: Ok(vec![PseudoLabel {
                    pose: nalgebra::Isometry3::identity(),
                    score: 0.06 + 0.0005 * f64::from(im_id),
                }]),
                warning: None,
            }
        };
        let job = Job {
            options_file: LABEL_OPTIONS_FILE,
            recorded: serde_json::json!({}),
            output: SceneDir::pseudo_gt_path,
            label: &stand_in,
        };
        let (labelled, good_scores) =
            label_scene(&scene, &instances, &models, &options, &job, &()).unwrap();

        let ids: Vec<u32> = labelled.iter().map(|(im_id, _)| *im_id).collect();
        assert_eq!(ids, (0..100).collect::<Vec<_>>());
        let sample: Vec<u32> = (0..64).map(|j| j * 100 / 64).collect();
        let sample_scores: Vec<f64> = sample
            .iter()
            .map(|&i| 0.86 + 0.0005 * f64::from(i))
            .collect();
        let fence = early_stop::upper_fence(&sample_scores).unwrap();
        assert!(
            fence > 0.9 && fence < 0.9 + early_stop::MAX_RAISE,
            "{fence}"
        );
        assert!((good_scores[&1] - fence).abs() < 1e-9, "{good_scores:?}");
        let seen = seen.into_inner().unwrap();
        assert_eq!(seen.len(), 100);
        for (im_id, good) in seen {
            let expected = if sample.contains(&im_id) { 0.9 } else { fence };
            assert!((good - expected).abs() < 1e-9, "image {im_id}: {good}");
        }
    }

    #[test]
    fn a_pixel_stride_of_zero_is_refused_by_name() {
        let options = LabelOptions {
            pixel_stride: 0,
            ..LabelOptions::default()
        };
        let error = options.validate().unwrap_err().to_string();
        assert!(error.contains("pixel_stride"), "{error}");
        assert!(LabelOptions::default().validate().is_ok());
    }

    #[test]
    fn an_arc_step_out_of_range_is_refused_by_name() {
        for step in [-1.0, 90.5, f64::NAN] {
            let options = LabelOptions {
                arc_step_deg: step,
                ..LabelOptions::default()
            };
            let error = options.validate().unwrap_err().to_string();
            assert!(error.contains("arc_step"), "{step}: {error}");
        }
        for step in [0.0, 90.0] {
            let options = LabelOptions {
                arc_step_deg: step,
                ..LabelOptions::default()
            };
            assert!(options.validate().is_ok(), "{step}");
        }
    }

    #[test]
    fn the_colour_rule_is_recorded_only_when_on() {
        // Splits labelled before the rule existed record no margin: off resumes them.
        let off = serde_json::to_value(LabelOptions::default()).unwrap();
        assert!(off.get("appearance_margin").is_none(), "{off}");
        let on = LabelOptions {
            appearance_margin: APPEARANCE_MARGIN,
            ..LabelOptions::default()
        };
        let on = serde_json::to_value(on).unwrap();
        assert_eq!(on["appearance_margin"], APPEARANCE_MARGIN);
    }

    #[test]
    fn score_options_out_of_range_are_refused_by_name() {
        for (name, options) in [
            (
                "max_score",
                LabelOptions {
                    max_score: 0.0,
                    ..LabelOptions::default()
                },
            ),
            (
                "score_margin",
                LabelOptions {
                    score_margin: -0.1,
                    ..LabelOptions::default()
                },
            ),
            (
                "good_score",
                LabelOptions {
                    good_score: f64::NAN,
                    ..LabelOptions::default()
                },
            ),
            (
                "outlier_sigmas",
                LabelOptions {
                    outlier_sigmas: -3.0,
                    ..LabelOptions::default()
                },
            ),
            (
                "appearance_margin",
                LabelOptions {
                    appearance_margin: -0.2,
                    ..LabelOptions::default()
                },
            ),
            (
                "appearance_margin",
                LabelOptions {
                    appearance_margin: f64::INFINITY,
                    ..LabelOptions::default()
                },
            ),
        ] {
            let error = options.validate().unwrap_err().to_string();
            assert!(error.contains(name), "{error}");
        }
    }

    /// The colour rule's image: one of another size than the depth, or one that cannot be
    /// read, is refused with a warning naming the file; one of the depth's size is sampled.
    #[test]
    fn an_image_whose_colours_cannot_serve_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let camera = depth_render::PinholeCamera::new(40.0, 40.0, 16.0, 12.0, 32, 24).unwrap();
        let lattice = PixelLattice::new(&camera, 2);
        let path = dir.path().join("000001.png");
        bop_dataset::write_rgb(&path, &vec![[10, 20, 30]; 16 * 12], 16, 12).unwrap();
        let error = image_colour(&path, (32, 24), &lattice).unwrap_err();
        assert!(
            error.contains("000001.png") && error.contains("16×12") && error.contains("32×24"),
            "{error}"
        );
        bop_dataset::write_rgb(&path, &vec![[10, 20, 30]; 32 * 24], 32, 24).unwrap();
        let colours = image_colour(&path, (32, 24), &lattice).unwrap();
        assert_eq!(colours, vec![[10, 20, 30]; 16 * 12]);
        std::fs::write(&path, b"not a PNG").unwrap();
        let error = image_colour(&path, (32, 24), &lattice).unwrap_err();
        assert!(
            error.contains("000001.png") && error.contains("depth alone"),
            "{error}"
        );
    }
}
