//! Training and evaluation data from a BOP split: for every visible instance of one object, a
//! square RGB crop around its visible mask (`ipdf_model::crop_object`, background black) or in
//! its visible box (`bbox_visib`, as a detector gives it: `ipdf_model::crop_in_box`), where
//! the crop came from (its box, the image's intrinsics from `scene_camera.json`), and its
//! rotation and translation label sets: the ground-truth pose alone (`single`), the pose
//! expanded by the object's symmetries from `models_info.json` (`analytical`), or the pseudo
//! labels of `ipdf label` (`pseudo`). The ground-truth symmetry set and pose are kept beside,
//! when the split has `scene_gt.json`, for evaluation.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ipdf_model::rotation::RotationFrame;
use ipdf_model::translation::{CameraIntrinsics, CropGeometry};
use ipdf_model::{CropBox, CropOptions, ImageBox, crop_box, crop_in_box, crop_object};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

use bop_dataset::{
    BopDataset, FileError, GtInfo, GtInstance, Intrinsics, PseudoInstance, RotationRepairs,
    SceneDir, read_models_info, read_pseudo_gt, read_scene_camera, read_scene_gt_info,
    read_scene_gt_repaired,
};
use ipdf_metrics::{CONTINUOUS_STEPS, SymmetryGroup};

use crate::Error;

/// Which rotations an instance is labelled with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LabelSource {
    /// The ground-truth pose of the image alone (what a pose-annotated dataset gives).
    Single,
    /// The ground-truth pose with every symmetry of `models_info.json`.
    Analytical,
    /// The pseudo labels of `scene_pseudo_gt.json` (no ground truth used).
    Pseudo,
    /// The reference sets A of `scene_reference_gt.json` (`ipdf label --reference`): every pose
    /// the labeller's acceptance rule accepts, found by brute force. The yardstick of a model
    /// trained on pseudo labels.
    Reference,
}

impl LabelSource {
    /// `single`, `analytical`, `pseudo` or `reference`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Single => "single",
            Self::Analytical => "analytical",
            Self::Pseudo => "pseudo",
            Self::Reference => "reference",
        }
    }

    /// Every source.
    pub const ALL: [Self; 4] = [
        Self::Single,
        Self::Analytical,
        Self::Pseudo,
        Self::Reference,
    ];
}

/// What a crop is cut around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CropSource {
    /// The visible mask (`mask_visib/`), everything off it black.
    #[default]
    Mask,
    /// The visible box, as a detector gives it: `bbox_visib` of `scene_gt_info.json`, else the
    /// visible mask's bounding box; everything inside it kept, the margin around it black.
    Box,
    /// Masks where the split has them, else boxes.
    Auto,
}

impl CropSource {
    /// `mask`, `box` or `auto`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Mask => "mask",
            Self::Box => "box",
            Self::Auto => "auto",
        }
    }

    /// Every source.
    pub const ALL: [Self; 3] = [Self::Mask, Self::Box, Self::Auto];
}

/// How far a jittered box ([`ExampleOptions::box_jitter`]) moves: its centre by up to this
/// fraction of its width and height, each side scaled by up to this fraction — the error of a
/// good detector's box (IoU with the true box about 0.7 or better).
pub const BOX_JITTER: f64 = 0.1;

/// Which instances become examples, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ExampleOptions {
    /// The split folder.
    pub split: String,
    /// The object whose instances are taken.
    pub obj_id: u32,
    /// Where the label sets come from.
    pub labels: LabelSource,
    /// Side of the square crops (pixels).
    pub input_size: usize,
    /// Instances with a smaller visible fraction (`scene_gt_info.json`) are left out.
    pub min_visible_fraction: f64,
    /// Steps per turn of a continuous symmetry in `analytical` label sets (the ground-truth
    /// sets of evaluation always use 200, as the paper).
    pub continuous_steps: usize,
    /// What each crop is cut around.
    pub crop: CropSource,
    /// With a seed, box crops are cut from boxes moved at random by up to [`BOX_JITTER`]
    /// (the same boxes for the same seed), so that a model trained on them takes a detector's
    /// imprecise boxes.
    pub box_jitter: Option<u64>,
}

impl ExampleOptions {
    /// The instances scored against their ground truth (`ipdf eval`): every instance of
    /// `obj_id` in `split` at least 10% visible, single labels (the ground-truth sets are
    /// [`Examples::truth_sets`]).
    pub fn evaluation(split: &str, obj_id: u32, input_size: usize) -> Self {
        Self {
            split: split.to_string(),
            obj_id,
            labels: LabelSource::Single,
            input_size,
            min_visible_fraction: 0.1,
            continuous_steps: 1,
            crop: CropSource::Auto,
            box_jitter: None,
        }
    }
}

/// One instance's place in the dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InstanceRef {
    /// Scene id.
    pub scene_id: u32,
    /// Image id.
    pub im_id: u32,
    /// Instance index in the image (mask order).
    pub instance: usize,
}

/// Crops, label sets and (where known) ground-truth symmetry sets of one object's instances.
pub struct Examples {
    /// `[N, 3, S, S]` crops, 8-bit.
    pub crops: Tensor,
    /// One label set per crop.
    pub label_sets: Vec<Vec<UnitQuaternion<f64>>>,
    /// One set of translation labels per crop (mm, camera frame): the ground-truth translation
    /// (`single`, `analytical`: a symmetry about the model's origin keeps it) or the pseudo
    /// labels' translations.
    pub translation_sets: Vec<Vec<Vector3<f64>>>,
    /// Where each crop was cut from.
    pub geometry: Vec<CropGeometry>,
    /// The ground-truth symmetry set per crop (continuous axes in 200 steps), when the split
    /// has ground truth.
    pub truth_sets: Option<Vec<Vec<UnitQuaternion<f64>>>>,
    /// The ground-truth pose per crop, translation in mm, when the split has ground truth.
    pub truth_poses: Option<Vec<Isometry3<f64>>>,
    /// Where each crop comes from.
    pub instances: Vec<InstanceRef>,
    /// Each instance's visible fraction (`visib_fract` of `scene_gt_info.json`), where known.
    pub visible_fractions: Vec<Option<f64>>,
    /// Ground-truth rotations read as their nearest rotations.
    pub repairs: RotationRepairs,
    /// How many crops were cut around the instance's box (everything inside it) rather than
    /// its visible mask: all under [`CropSource::Box`], those without a mask under
    /// [`CropSource::Auto`].
    pub box_crops: usize,
}

impl Examples {
    /// Each crop's turn from a rotation model's `frame` into the camera's
    /// ([`RotationFrame::to_camera`]; the identity for the camera's frame).
    pub fn frame_turns(&self, frame: RotationFrame) -> Result<Vec<UnitQuaternion<f64>>, Error> {
        if frame.is_camera() {
            return Ok(vec![UnitQuaternion::identity(); self.instances.len()]);
        }
        if self.geometry.len() != self.instances.len() {
            let reason = format!(
                "a model in the {} frame needs each crop's box and intrinsics: {} of {} known",
                frame.name(),
                self.geometry.len(),
                self.instances.len()
            );
            return Err(Error::option("rotation_frame", reason));
        }
        Ok(self.geometry.iter().map(|g| frame.to_camera(g)).collect())
    }

    /// `sets` (one rotation set per crop, camera frame) in a rotation model's `frame`.
    pub fn sets_in_frame(
        &self,
        sets: &[Vec<UnitQuaternion<f64>>],
        frame: RotationFrame,
    ) -> Result<Vec<Vec<UnitQuaternion<f64>>>, Error> {
        let turns = self.frame_turns(frame)?;
        Ok(sets
            .iter()
            .zip(&turns)
            .map(|(set, turn)| from_camera(set, turn))
            .collect())
    }

    /// [`Examples::truth_sets`], or the error that scoring needs them.
    pub fn required_truth_sets(&self) -> Result<&[Vec<UnitQuaternion<f64>>], Error> {
        self.truth_sets.as_deref().ok_or_else(no_truth)
    }

    /// [`Examples::truth_poses`], or the error that scoring needs them.
    pub fn required_truth_poses(&self) -> Result<&[Isometry3<f64>], Error> {
        self.truth_poses.as_deref().ok_or_else(no_truth)
    }
}

/// `set` (camera frame) in the frame whose turn into the camera's is `turn`.
pub fn from_camera(
    set: &[UnitQuaternion<f64>],
    turn: &UnitQuaternion<f64>,
) -> Vec<UnitQuaternion<f64>> {
    let back = turn.inverse();
    set.iter().map(|rotation| back * rotation).collect()
}

fn no_truth() -> Error {
    Error::option("dataset", "evaluation needs the split's scene_gt.json")
}

/// One instance to crop, before its images are read.
struct Pending {
    at: InstanceRef,
    labels: Vec<UnitQuaternion<f64>>,
    translations: Vec<Vector3<f64>>,
    intrinsics: Intrinsics,
    truth: Option<Vec<UnitQuaternion<f64>>>,
    truth_pose: Option<Isometry3<f64>>,
    /// Its `scene_gt_info.json` entry, and where it is (the file, the key prefix `3[0].`).
    info: Option<(GtInfo, PathBuf, String)>,
}

/// The examples of `options.obj_id` in `options.split` of `dataset`. Pseudo labels missing
/// from a scene are an error that says how to make them; instances whose labelling failed are
/// left out, as are instances below the visible fraction.
pub fn load_examples(dataset: &BopDataset, options: &ExampleOptions) -> Result<Examples, Error> {
    let models = read_models_info(&dataset.models_info_path())?;
    let group = models
        .get(&options.obj_id)
        .map(|m| m.symmetry.clone())
        .ok_or_else(|| {
            FileError::new(
                &dataset.models_info_path(),
                options.obj_id.to_string(),
                "no such object",
            )
        })?;
    let (mut pending, mut repairs) = (Vec::new(), RotationRepairs::default());
    for scene_id in dataset.scene_ids(&options.split)? {
        pending.extend(scene_instances(
            dataset,
            scene_id,
            options,
            &group,
            &mut repairs,
        )?);
    }
    let place = format!(
        "object {} in split {:?} of {}",
        options.obj_id,
        options.split,
        dataset.root.display()
    );
    if pending.is_empty() {
        let reason = format!("no labelled instance of {place}");
        return Err(Error::option("dataset", reason));
    }
    let (pending, crops): (Vec<Pending>, Vec<CutCrop>) = crop_instances(dataset, options, pending)?;
    let box_crops = crops.iter().filter(|(_, boxed)| *boxed).count();
    let crops: Vec<FileCrop> = crops.into_iter().map(|(crop, _)| crop).collect();
    if pending.is_empty() {
        let reason = format!("every instance of {place} has an empty visible mask or box");
        return Err(Error::option("dataset", reason));
    }
    let size = options.input_size as i64;
    let geometry = pending
        .iter()
        .zip(&crops)
        .map(|(p, crop)| crop.geometry(&p.intrinsics))
        .collect();
    let pixels: Vec<u8> = crops.into_iter().flat_map(|crop| crop.pixels).collect();
    let crops = Tensor::from_slice(&pixels)
        .reshape([pending.len() as i64, 3, size, size])
        .to_kind(Kind::Uint8);
    let has_truth = pending.iter().all(|p| p.truth.is_some());
    Ok(Examples {
        crops,
        truth_sets: has_truth.then(|| pending.iter().filter_map(|p| p.truth.clone()).collect()),
        truth_poses: has_truth.then(|| pending.iter().filter_map(|p| p.truth_pose).collect()),
        label_sets: pending.iter().map(|p| p.labels.clone()).collect(),
        translation_sets: pending.iter().map(|p| p.translations.clone()).collect(),
        geometry,
        instances: pending.iter().map(|p| p.at).collect(),
        visible_fractions: pending
            .iter()
            .map(|p| p.info.as_ref().map(|(info, ..)| info.visib_fract))
            .collect(),
        repairs,
        box_crops,
    })
}

/// The instances of `options.obj_id` in scene `scene_id` with a label set, visible enough;
/// the ground truth's repaired rotations are added to `repairs`.
fn scene_instances(
    dataset: &BopDataset,
    scene_id: u32,
    options: &ExampleOptions,
    group: &SymmetryGroup,
    repairs: &mut RotationRepairs,
) -> Result<Vec<Pending>, Error> {
    let scene = dataset.scene(&options.split, scene_id);
    let optional = |path: PathBuf| path.exists().then_some(path);
    let gt = match optional(scene.gt_path()) {
        Some(path) => {
            let (gt, repaired) = read_scene_gt_repaired(&path)?;
            repairs.merge(&repaired);
            Some(gt)
        }
        None => None,
    };
    let visible = optional(scene.gt_info_path())
        .map(|p| read_scene_gt_info(&p))
        .transpose()?;
    // The pose sets of `ipdf label` (with `--reference`, the reference sets A), where they are
    // the labels.
    let sets = match options.labels {
        LabelSource::Pseudo => Some((scene.pseudo_gt_path(), "")),
        LabelSource::Reference => Some((scene.reference_gt_path(), " --reference")),
        LabelSource::Single | LabelSource::Analytical => None,
    };
    let pseudo = sets
        .map(|(path, flag)| {
            let command = format!(
                "ipdf label --dataset {} --split {}{flag}",
                dataset.root.display(),
                options.split
            );
            read_scene_label_sets(&path, &command)
        })
        .transpose()?;
    let cameras = read_scene_camera(&scene.camera_path())?;
    let object_ids = mask_objects(&scene, gt.as_ref(), pseudo.as_ref(), options.labels)?;
    // The symmetry rotations, once per scene: a can's 400 take 80,000 comparisons to build.
    let analytical = group.rotations(options.continuous_steps);
    let truth_symmetries = group.rotations(CONTINUOUS_STEPS);
    let mut out = Vec::new();
    for (im_id, ids) in object_ids {
        for (instance, &obj_id) in ids.iter().enumerate() {
            let info = visible
                .as_ref()
                .and_then(|v| v.get(&im_id)?.get(instance))
                .map(|info| (*info, scene.gt_info_path(), format!("{im_id}[{instance}].")));
            let fraction = info.as_ref().map_or(1.0, |(info, ..)| info.visib_fract);
            if obj_id != options.obj_id || fraction < options.min_visible_fraction {
                continue;
            }
            let truth = gt.as_ref().and_then(|gt| gt.get(&im_id)?.get(instance));
            let pseudo_labels = pseudo.as_ref().and_then(|p| p.get(&im_id)?.get(instance));
            let labels = instance_labels(options.labels, truth, pseudo_labels, &analytical);
            let Some((labels, translations)) = labels.filter(|l| !l.0.is_empty()) else {
                continue;
            };
            let intrinsics = intrinsics_of(&cameras, &scene, im_id)?;
            out.push(Pending {
                at: InstanceRef {
                    scene_id,
                    im_id,
                    instance,
                },
                labels,
                translations,
                intrinsics,
                truth: truth.map(|t| turned(&t.pose.rotation, &truth_symmetries)),
                truth_pose: truth
                    .map(|t| Isometry3::from_parts(millimetres(&t.pose).into(), t.pose.rotation)),
                info,
            });
        }
    }
    Ok(out)
}

/// Image `im_id`'s intrinsics in `cameras` (`scene`'s `scene_camera.json`), or the error that
/// names the file and the image.
pub fn intrinsics_of(
    cameras: &BTreeMap<u32, Intrinsics>,
    scene: &SceneDir,
    im_id: u32,
) -> Result<Intrinsics, FileError> {
    cameras.get(&im_id).copied().ok_or_else(|| {
        FileError::new(
            &scene.camera_path(),
            format!("{im_id}"),
            "missing: the image's intrinsics",
        )
    })
}

/// Which object each mask of each image of `scene` shows: from the ground truth, or, without
/// it, from the pseudo labels (`source` needs the ground truth otherwise).
fn mask_objects(
    scene: &SceneDir,
    gt: Option<&BTreeMap<u32, Vec<GtInstance>>>,
    pseudo: Option<&BTreeMap<u32, Vec<PseudoInstance>>>,
    source: LabelSource,
) -> Result<BTreeMap<u32, Vec<u32>>, Error> {
    match (gt, pseudo) {
        (Some(gt), _) => Ok(gt
            .iter()
            .map(|(&im, list)| (im, list.iter().map(|i| i.obj_id).collect()))
            .collect()),
        (None, Some(pseudo)) => Ok(pseudo
            .iter()
            .map(|(&im, list)| (im, list.iter().map(|i| i.obj_id).collect()))
            .collect()),
        (None, None) => {
            let reason = format!("missing: {} labels need the ground truth", source.name());
            Err(FileError::new(&scene.gt_path(), "file", reason).into())
        }
    }
}

/// An instance's rotation labels and translation labels (mm).
type LabelSets = (Vec<UnitQuaternion<f64>>, Vec<Vector3<f64>>);

/// An instance's rotation labels and translation labels (mm) from `source`: its ground truth
/// (`truth`), turned by the object's symmetries (`analytical`), or its pseudo labels or
/// reference set (`sets`); `None` when the source has none for it.
fn instance_labels(
    source: LabelSource,
    truth: Option<&GtInstance>,
    sets: Option<&PseudoInstance>,
    analytical: &[UnitQuaternion<f64>],
) -> Option<LabelSets> {
    match source {
        LabelSource::Single => truth.map(|t| (vec![t.pose.rotation], vec![millimetres(&t.pose)])),
        LabelSource::Analytical => truth.map(|t| {
            (
                turned(&t.pose.rotation, analytical),
                vec![millimetres(&t.pose)],
            )
        }),
        LabelSource::Pseudo | LabelSource::Reference => sets.map(|p| {
            let rotations = p.labels.iter().map(|l| l.pose.rotation).collect();
            let translations = p.labels.iter().map(|l| millimetres(&l.pose)).collect();
            (rotations, translations)
        }),
    }
}

/// A pose's translation in millimetres.
fn millimetres(pose: &Isometry3<f64>) -> Vector3<f64> {
    pose.translation.vector * 1000.0
}

/// `rotation` composed with each of `symmetries`.
fn turned(
    rotation: &UnitQuaternion<f64>,
    symmetries: &[UnitQuaternion<f64>],
) -> Vec<UnitQuaternion<f64>> {
    symmetries.iter().map(|s| rotation * s).collect()
}

/// The scene's pose sets at `path` (`scene_pseudo_gt.json`, `scene_reference_gt.json`); a
/// missing file is an error saying to run `command` first.
fn read_scene_label_sets(
    path: &Path,
    command: &str,
) -> Result<BTreeMap<u32, Vec<PseudoInstance>>, FileError> {
    if !path.exists() {
        let reason = format!("missing: make it first with `{command}`");
        return Err(FileError::new(path, "file", reason));
    }
    read_pseudo_gt(path)
}

/// A crop, and whether it was cut around a box rather than a mask.
type CutCrop = (FileCrop, bool);

/// The crops of `pending`, in parallel, each with whether it was cut around a box; an instance
/// whose visible mask or box is empty (fully occluded: BOP keeps them, with `visib_fract` 0) is
/// left out, like one below the visible fraction.
fn crop_instances(
    dataset: &BopDataset,
    options: &ExampleOptions,
    pending: Vec<Pending>,
) -> Result<(Vec<Pending>, Vec<CutCrop>), Error> {
    let crops: Vec<Option<CutCrop>> = pending
        .par_iter()
        .map(|p| crop_instance(dataset, options, p))
        .collect::<Result<_, Error>>()?;
    Ok(pending
        .into_iter()
        .zip(crops)
        .filter_map(|(p, crop)| Some((p, crop?)))
        .unzip())
}

/// The crop of one instance as `options.crop` asks, and whether it was cut around a box;
/// `None` when its mask or box is empty.
fn crop_instance(
    dataset: &BopDataset,
    options: &ExampleOptions,
    p: &Pending,
) -> Result<Option<CutCrop>, Error> {
    let scene = dataset.scene(&options.split, p.at.scene_id);
    let rgb = scene.rgb_path(p.at.im_id);
    let mask = scene.visible_mask_path(p.at.im_id, p.at.instance);
    let use_mask = match options.crop {
        CropSource::Mask => true,
        CropSource::Box => false,
        CropSource::Auto => mask.exists(),
    };
    if use_mask {
        return match crop_files(&rgb, &mask, options.input_size) {
            Ok(crop) => Ok(Some((crop, false))),
            Err(CropError::EmptyMask(_)) => Ok(None),
            Err(error) => Err(error.into()),
        };
    }
    let Some((image_box, (file, field))) = instance_box(p, &mask)? else {
        return Ok(None);
    };
    let image_box = match options.box_jitter {
        Some(seed) => jittered(&image_box, seed, &p.at),
        None => image_box,
    };
    let clip = options.box_jitter.is_some();
    match crop_file_box(&rgb, &image_box, options.input_size, clip) {
        Ok(crop) => Ok(Some((crop, true))),
        Err(CropError::BadBox(reason)) => Err(FileError::new(&file, field, reason).into()),
        Err(error) => Err(error.into()),
    }
}

/// A box and the file and field it comes from.
type PlacedBox = (ImageBox, (PathBuf, String));

/// An instance's visible box and the file and field it comes from: `bbox_visib` of
/// `scene_gt_info.json`, else the bounding box of its visible mask; `None` when empty.
fn instance_box(p: &Pending, mask: &Path) -> Result<Option<PlacedBox>, Error> {
    if let Some((info, file, prefix)) = &p.info {
        let at = (file.clone(), format!("{prefix}bbox_visib"));
        return Ok(ImageBox::from_bop(info.bbox_visib).map(|b| (b, at)));
    }
    if !mask.exists() {
        let reason = "missing: a box crop needs the instance's bbox_visib (scene_gt_info.json) \
                      or its visible mask";
        return Err(FileError::new(mask, "file", reason).into());
    }
    let visible = bop_dataset::read_mask(mask)?;
    let pixels: Vec<u8> = visible.pixels.iter().map(|&m| u8::from(m)).collect();
    let at = (mask.to_path_buf(), "mask".to_string());
    Ok(ImageBox::around(&pixels, visible.width as usize).map(|b| (b, at)))
}

/// `image_box` moved at random by up to [`BOX_JITTER`] (centre and size), the same for the same
/// seed and instance (a box pushed past the image's edge is clipped by [`crop_file_box`]).
fn jittered(image_box: &ImageBox, seed: u64, at: &InstanceRef) -> ImageBox {
    let key = (u64::from(at.scene_id) << 40) ^ (u64::from(at.im_id) << 16) ^ at.instance as u64;
    let mut rng =
        rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ key.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut unit = || rng.random_range(-BOX_JITTER..=BOX_JITTER);
    let (dx, dy, sw, sh) = (unit(), unit(), unit(), unit());
    let (width, height) = (image_box.width * (1.0 + sw), image_box.height * (1.0 + sh));
    ImageBox {
        x: image_box.x + image_box.width * (0.5 + dx) - width / 2.0,
        y: image_box.y + image_box.height * (0.5 + dy) - height / 2.0,
        width,
        height,
    }
}

/// The object a run is for: `obj_id` or the object named `name` (`dataset_info.json`), or the
/// dataset's only object; with its name (`obj_NNNNNN` when the dataset names none).
pub fn choose_object(
    dataset: &BopDataset,
    obj_id: Option<u32>,
    name: Option<&str>,
) -> Result<(u32, String), Error> {
    let models = read_models_info(&dataset.models_info_path())?;
    let names = dataset
        .read_info()?
        .map(|info| info.names)
        .unwrap_or_default();
    let name_of = |id: u32| {
        names
            .get(&id)
            .cloned()
            .unwrap_or_else(|| format!("obj_{id:06}"))
    };
    let ids: Vec<u32> = models.keys().copied().collect();
    let chosen = match (obj_id, name) {
        (Some(id), _) => Some(id).filter(|id| models.contains_key(id)),
        (None, Some(name)) => ids.iter().copied().find(|&id| name_of(id) == name),
        (None, None) => (ids.len() == 1).then(|| ids[0]),
    };
    let listing = ids
        .iter()
        .map(|&id| format!("{id} ({})", name_of(id)))
        .collect::<Vec<_>>()
        .join(", ");
    chosen.map(|id| (id, name_of(id))).ok_or_else(|| {
        Error::option(
            "obj_id",
            format!("choose one of the dataset's objects: {listing}"),
        )
    })
}

/// Why [`crop_files`] gave no crop.
#[derive(Debug, thiserror::Error)]
pub enum CropError {
    /// The mask file selects no pixel (e.g. a fully occluded instance).
    #[error("{}: mask: the object mask is empty", .0.display())]
    EmptyMask(PathBuf),
    /// A box that cannot be cropped from the image: empty, negative or outside it.
    #[error("{0}")]
    BadBox(String),
    /// Unreadable images, mismatched sizes or a bad crop size.
    #[error(transparent)]
    Failed(#[from] Error),
}

impl From<CropError> for Error {
    fn from(error: CropError) -> Self {
        match error {
            CropError::Failed(error) => error,
            CropError::EmptyMask(path) => {
                FileError::new(&path, "mask", "the object mask is empty").into()
            }
            CropError::BadBox(reason) => Self::option("box", reason),
        }
    }
}

/// A crop of an image file and where it was cut from.
#[derive(Debug, Clone, PartialEq)]
pub struct FileCrop {
    /// 8-bit `[3, size, size]` values, channel-major.
    pub pixels: Vec<u8>,
    /// The square it was cut from (`ipdf_model::crop_box`).
    pub crop_box: CropBox,
    /// The image's width, pixels.
    pub width: usize,
    /// The image's height, pixels.
    pub height: usize,
}

impl FileCrop {
    /// The crop's geometry with the image's intrinsics.
    pub fn geometry(&self, intrinsics: &Intrinsics) -> CropGeometry {
        CropGeometry {
            crop: self.crop_box,
            intrinsics: CameraIntrinsics {
                fx: intrinsics.fx,
                fy: intrinsics.fy,
                cx: intrinsics.cx,
                cy: intrinsics.cy,
            },
            width: self.width,
            height: self.height,
        }
    }
}

/// The 8-bit `[3, size, size]` crop (channel-major) of the colour image at `rgb` around the
/// mask at `mask` (`ipdf_model::crop_object`), with its box.
pub fn crop_files(rgb: &Path, mask: &Path, size: usize) -> Result<FileCrop, CropError> {
    let colour = bop_dataset::read_rgb(rgb).map_err(Error::from)?;
    let visible = bop_dataset::read_mask(mask).map_err(Error::from)?;
    if (visible.width, visible.height) != (colour.width, colour.height) {
        let reason = format!(
            "{}×{} but the colour image is {}×{}",
            visible.width, visible.height, colour.width, colour.height
        );
        return Err(Error::from(FileError::new(mask, "size", reason)).into());
    }
    crop_bytes(
        colour.pixels.as_flattened(),
        &visible.pixels,
        colour.width as usize,
        colour.height as usize,
        size,
    )
    .map_err(|error| match error {
        ipdf_model::ModelError::EmptyMask => CropError::EmptyMask(mask.to_path_buf()),
        error => Error::from(error).into(),
    })
}

/// The 8-bit `[3, size, size]` crop (channel-major) of the colour image at `rgb` in
/// `image_box` (`ipdf_model::crop_in_box`: the crop of the mask that fills the box), with its
/// square. With `clip`, a box reaching past the image is clipped to it first. A box that is
/// empty, negative or outside the image is [`CropError::BadBox`].
pub fn crop_file_box(
    rgb: &Path,
    image_box: &ImageBox,
    size: usize,
    clip: bool,
) -> Result<FileCrop, CropError> {
    let colour = bop_dataset::read_rgb(rgb).map_err(Error::from)?;
    let (width, height) = (colour.width as usize, colour.height as usize);
    let image_box = &if clip {
        image_box.clipped(width, height)
    } else {
        *image_box
    };
    let options = CropOptions::new(size);
    let pixels = colour.pixels.as_flattened();
    let (values, crop_box) = match crop_in_box(pixels, image_box, width, height, &options) {
        Ok(crop) => crop,
        Err(ipdf_model::ModelError::InvalidOption {
            name: "box",
            reason,
        }) => {
            return Err(CropError::BadBox(reason));
        }
        Err(error) => return Err(Error::from(error).into()),
    };
    Ok(FileCrop {
        pixels: to_bytes(&values),
        crop_box,
        width,
        height,
    })
}

fn to_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().map(|v| (v * 255.0).round() as u8).collect()
}

/// The 8-bit `[3, size, size]` crop (`ipdf_model::crop_object`) of a row-major RGB image
/// around the true pixels of `mask`, with its box.
fn crop_bytes(
    rgb: &[u8],
    mask: &[bool],
    width: usize,
    height: usize,
    size: usize,
) -> Result<FileCrop, ipdf_model::ModelError> {
    let mask: Vec<u8> = mask.iter().map(|&m| u8::from(m)).collect();
    let options = CropOptions::new(size);
    let values = crop_object(rgb, &mask, width, height, &options)?;
    Ok(FileCrop {
        pixels: to_bytes(&values),
        crop_box: crop_box(&mask, width, height, &options)?,
        width,
        height,
    })
}

/// An 8-bit crop from [`crop_files`] as the `[3, S, S]` float tensor in `[0, 1]` the model takes.
pub fn crop_tensor(crop: &[u8], size: usize) -> Tensor {
    let s = size as i64;
    to_unit_floats(&Tensor::from_slice(crop).reshape([3, s, s]))
}

/// 8-bit crops (one, or a batch as in [`Examples::crops`]) as the floats in `[0, 1]` the model
/// takes.
pub fn to_unit_floats(crops: &Tensor) -> Tensor {
    crops.to_kind(Kind::Float) / 255.0
}

/// `count` examples of `object` rendered in memory (no dataset on disk): frames as
/// [`synth_data::FrameRenderer`] draws them, uniform colour, crops of `size` pixels, each labelled and
/// scored with its full symmetry set. For tests and examples.
pub fn rendered_examples(
    object: &synth_data::SynthObject,
    count: usize,
    size: usize,
    seed: u64,
) -> Result<Examples, Error> {
    let renderer = synth_data::FrameRenderer::new(&object.mesh)?;
    let camera = synth_data::SynthOptions::t_less_camera().camera;
    let style = synth_data::FrameStyle::plain(depth_render::Material::Uniform(object.colour));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (width, height) = (camera.width as usize, camera.height as usize);
    let intrinsics = Intrinsics {
        fx: camera.fx,
        fy: camera.fy,
        cx: camera.cx,
        cy: camera.cy,
        depth_scale: 1.0,
    };
    let (mut crops, mut sets, mut instances) = (Vec::new(), Vec::new(), Vec::new());
    let (mut geometry, mut poses) = (Vec::new(), Vec::new());
    for im_id in 0..count as u32 {
        let frame =
            renderer.render(&camera, &synth_data::ViewRange::default(), &style, &mut rng)?;
        let crop = crop_bytes(
            frame.rgb.as_flattened(),
            &frame.mask_visib,
            width,
            height,
            size,
        )?;
        geometry.push(crop.geometry(&intrinsics));
        crops.extend(crop.pixels);
        poses.push(Isometry3::from_parts(
            (frame.pose.translation.vector * 1000.0).into(),
            frame.pose.rotation,
        ));
        sets.push(object.symmetry.expand(&frame.pose.rotation));
        instances.push(InstanceRef {
            scene_id: 0,
            im_id,
            instance: 0,
        });
    }
    let s = size as i64;
    Ok(Examples {
        crops: Tensor::from_slice(&crops).reshape([count as i64, 3, s, s]),
        label_sets: sets.clone(),
        translation_sets: poses.iter().map(|p| vec![p.translation.vector]).collect(),
        geometry,
        truth_sets: Some(sets),
        truth_poses: Some(poses),
        instances,
        visible_fractions: vec![None; count],
        repairs: RotationRepairs::default(),
        box_crops: 0,
    })
}
