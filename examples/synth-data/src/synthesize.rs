//! Rendering a split of a synthetic dataset into BOP files, resumably.
use std::collections::BTreeMap;
use std::path::{Component, Path};
use std::time::Instant;

use depth_render::{DepthSensor, ImageTexture, MaskErrors, Material};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde_json::{Value, json};

use crate::frame::{Frame, FrameRenderer, FrameStyle, Placement, ViewRange};
use crate::{Randomization, SynthError, SynthObject};
use bop_dataset::{
    BopCamera, BopDataset, DatasetInfo, FileError, GtInfo, GtInstance, Intrinsics, ModelInfo,
    Progress, SceneDir, as_recorded, check_recorded, image_file_complete, read_scene_camera,
    read_scene_gt, read_scene_gt_info, write_coloured_mesh_ply, write_json, write_models_info,
    write_scene_camera, write_scene_gt, write_scene_gt_info,
};

/// The paper's two kinds of synthetic dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// One flat colour per object: the image shows the geometric symmetries.
    Uniform,
    /// Colour patches fixed to the model: every orientation looks different.
    Texture,
}

impl Variant {
    /// `uniform` or `texture`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Uniform => "uniform",
            Self::Texture => "texture",
        }
    }

    /// Every variant.
    pub const ALL: [Self; 2] = [Self::Uniform, Self::Texture];
}

/// Options of [`synthesize`].
#[derive(Debug, Clone, PartialEq)]
pub struct SynthOptions {
    /// Frames per object.
    pub frames: usize,
    /// Frames per scene folder (BOP's real datasets hold up to 1000 per scene).
    pub frames_per_scene: usize,
    /// Uniform or textured objects.
    pub variant: Variant,
    /// The camera (T-LESS-like by default) and the unit of the depth PNGs.
    pub camera: BopCamera,
    /// Where the camera may be, and how the object rests on the table.
    pub view: ViewRange,
    /// Distractor objects per frame.
    pub distractors: usize,
    /// Distractor objects per frame between the object and the camera.
    pub occluders: usize,
    /// What the depth camera reads of the scene, or clean depth.
    pub sensor: Option<DepthSensor>,
    /// A detector's errors on the visible masks (`mask_visib`), or exact masks.
    pub mask_errors: Option<MaskErrors>,
    /// The parts of each frame's look drawn at random (domain randomisation).
    pub randomization: Randomization,
    /// Seed of everything random.
    pub seed: u64,
}

impl SynthOptions {
    /// The default camera: 640 × 480 with T-LESS Primesense's focal lengths (1075.65,
    /// 1073.90 px), principal point at the centre, depth in units of 0.1 mm.
    pub fn t_less_camera() -> BopCamera {
        let intrinsics = Intrinsics {
            fx: 1075.65,
            fy: 1073.90,
            cx: 320.0,
            cy: 240.0,
            depth_scale: 0.1,
        };
        intrinsics
            .camera(640, 480)
            .expect("the default camera is valid")
    }
}

impl Default for SynthOptions {
    /// 1,000 frames per object in one scene, uniform colours, [`SynthOptions::t_less_camera`],
    /// [`ViewRange::default`], no distractors, clean depth, exact masks, the plain look, seed 0.
    fn default() -> Self {
        Self {
            frames: 1000,
            frames_per_scene: 1000,
            variant: Variant::Uniform,
            camera: Self::t_less_camera(),
            view: ViewRange::default(),
            distractors: 0,
            occluders: 0,
            sensor: None,
            mask_errors: None,
            randomization: Randomization::NONE,
            seed: 0,
        }
    }
}

/// What [`synthesize`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthSummary {
    /// Frames in the split.
    pub frames: usize,
    /// Frames rendered by this run (the others were already complete).
    pub rendered: usize,
    /// Scenes found finished but with files missing or truncated, rendered again.
    pub repaired: usize,
    /// Scenes in the split.
    pub scenes: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// `dataset_info.json`: what the dataset holds, so that a rerun into the same folder with other
/// objects or another variant is refused rather than mixed in.
fn dataset_info(objects: &[SynthObject], options: &SynthOptions) -> DatasetInfo {
    DatasetInfo {
        generator: "ipdf synth".into(),
        variant: options.variant.name().into(),
        names: (1..).zip(objects.iter().map(|o| o.name.clone())).collect(),
    }
}

/// The file in a split's folder that records the options its frames were generated with.
pub const SYNTH_OPTIONS_FILE: &str = "synth_options.json";

/// `synth_options.json`: everything that decides a split's scenes and frames (object ids and
/// sizes, frames, scene layout, seed, camera, views, distractors, sensor, mask errors), so that a rerun with
/// other options is refused rather than completed into a mixture. Numbers pass through JSON text
/// once, so that they compare equal to what a file read back holds.
fn split_options(objects: &[SynthObject], options: &SynthOptions) -> Value {
    let objects: Vec<Value> = objects
        .iter()
        .map(|object| {
            let (low, high) = object.mesh.bounds();
            // Micrometres are plenty to tell a mesh at another scale.
            let size = (high - low).map(|v| (f64::from(v) * 1e6).round() / 1e6);
            json!({"name": object.name, "size_m": [size.x, size.y, size.z]})
        })
        .collect();
    let camera = &options.camera;
    let mut value = json!({
        "generator": "ipdf synth",
        "objects": objects,
        "variant": options.variant.name(),
        "frames": options.frames,
        "frames_per_scene": options.frames_per_scene,
        "seed": options.seed,
        "camera": {
            "fx": camera.camera.fx, "fy": camera.camera.fy, "cx": camera.camera.cx,
            "cy": camera.camera.cy, "width": camera.camera.width, "height": camera.camera.height,
            "depth_scale": camera.depth_scale,
        },
        "elevation_deg": [options.view.elevation_deg.0, options.view.elevation_deg.1],
        "distance": [options.view.distance.0, options.view.distance.1],
        "table_offset": options.view.table_offset,
        "distractors": options.distractors,
        "sensor": options.sensor,
        "mask_errors": options.mask_errors,
    });
    // Recorded only where used, so that splits made before the option compare equal.
    if options.occluders > 0 {
        value["occluders"] = json!(options.occluders);
    }
    if options.view.off_centre > 0.0 {
        value["off_centre"] = json!(options.view.off_centre);
    }
    if options.view.roll_deg > 0.0 {
        value["roll_deg"] = json!(options.view.roll_deg);
    }
    if options.view.placement != Placement::Tossed {
        value["placement"] = json!(options.view.placement.name());
    }
    if !options.randomization.is_none() {
        value["randomize"] = json!(options.randomization.names());
    }
    as_recorded(value)
}

/// Refuses a split name that is not one plain folder name (`train`, `val`): no separators,
/// `.`, `..` or absolute paths, which would write outside the dataset.
fn check_split_name(split: &str) -> Result<(), SynthError> {
    let mut components = Path::new(split).components();
    let plain = matches!(
        (components.next(), components.next()),
        (Some(Component::Normal(name)), None) if name == split
    );
    if plain {
        Ok(())
    } else {
        Err(SynthError::option(
            "split",
            format!("{split:?} is not a plain folder name (like \"train\" or \"val\")"),
        ))
    }
}

/// Writes the models, `models_info.json`, `camera.json` and `dataset_info.json` of `objects`
/// (object ids from 1, in order) and the split's `synth_options.json`, refusing a folder that
/// holds another dataset or a split generated with other options.
fn write_models(
    dataset: &BopDataset,
    split: &str,
    objects: &[SynthObject],
    options: &SynthOptions,
) -> Result<(), SynthError> {
    let info = dataset_info(objects, options);
    if dataset.read_info()?.is_some_and(|found| found != info) {
        return Err(FileError::new(
            &dataset.info_path(),
            "objects",
            "the folder holds a dataset of other objects or another variant; choose a new folder",
        )
        .into());
    }
    let options_path = dataset.root.join(split).join(SYNTH_OPTIONS_FILE);
    let recorded_options = split_options(objects, options);
    check_recorded(
        &options_path,
        &recorded_options,
        "rerun with the same options to complete the split, or write to another folder",
    )?;
    let mut models = BTreeMap::new();
    for (i, object) in objects.iter().enumerate() {
        let obj_id = i as u32 + 1;
        write_coloured_mesh_ply(
            &dataset.model_path(obj_id),
            &object.mesh,
            object.appearance.as_ref(),
        )?;
        models.insert(obj_id, ModelInfo::of_mesh(&object.mesh, &object.symmetry));
    }
    write_models_info(&dataset.models_info_path(), &models)?;
    options.camera.write(&dataset.camera_path())?;
    dataset.write_info(&info)?;
    write_json(&options_path, &recorded_options)?;
    Ok(())
}

/// Renders `options.frames` frames of each of `objects` into `split` of `dataset` (object ids
/// from 1 in the order given; object `k`'s frames fill consecutive scenes), skipping complete
/// scenes. `progress` is told the split's frame count, then advances by one per frame (a
/// complete scene's frames at once).
///
/// Errors: no objects, no frames, a `split` that is not a plain folder name, a folder holding
/// another dataset or a split generated with other options (see [`SYNTH_OPTIONS_FILE`]),
/// rendering and I/O.
pub fn synthesize(
    dataset: &BopDataset,
    split: &str,
    objects: &[SynthObject],
    options: &SynthOptions,
    progress: &dyn Progress,
) -> Result<SynthSummary, SynthError> {
    if objects.is_empty() {
        return Err(SynthError::option("objects", "at least one object"));
    }
    if options.frames == 0 || options.frames_per_scene == 0 {
        return Err(SynthError::option(
            "frames",
            "frames and frames per scene must be at least 1",
        ));
    }
    check_split_name(split)?;
    let started = Instant::now();
    write_models(dataset, split, objects, options)?;
    let scenes_per_object = options.frames.div_ceil(options.frames_per_scene);
    progress.set_total((options.frames * objects.len()) as u64, 0);
    let (mut rendered, mut repaired) = (0, 0);
    let borrowed: Vec<ImageTexture> = objects
        .iter()
        .filter_map(|object| match &object.appearance {
            Some(Material::Image(texture)) => Some(texture.clone()),
            _ => None,
        })
        .collect();
    for (k, object) in objects.iter().enumerate() {
        let renderer = FrameRenderer::new(&object.mesh)?;
        let style = frame_style(options, k, object, &borrowed);
        for chunk in 0..scenes_per_object {
            let scene_id = (k * scenes_per_object + chunk) as u32;
            let first = chunk * options.frames_per_scene;
            let count = options.frames_per_scene.min(options.frames - first);
            let scene = dataset.scene(split, scene_id);
            if scene.gt_info_path().exists() {
                if scene_complete(&scene, count) {
                    progress.advance(count as u64);
                    continue;
                }
                repaired += 1;
            }
            let object = (k as u32 + 1, &renderer, &style);
            render_scene(&scene, count, object, options, progress)?;
            rendered += count;
        }
    }
    Ok(SynthSummary {
        frames: options.frames * objects.len(),
        rendered,
        repaired,
        scenes: scenes_per_object * objects.len(),
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// How object `k` (from 0) looks in its frames: its flat colour, or its own surface (a mesh
/// file's texture or vertex colours) and else colour patches of its own; and the options'
/// distractors, occluders, sensor, mask errors and randomisation, whose distractors may wear
/// the `borrowed` textures.
fn frame_style(
    options: &SynthOptions,
    k: usize,
    object: &SynthObject,
    borrowed: &[ImageTexture],
) -> FrameStyle {
    let material = match options.variant {
        Variant::Uniform => Material::Uniform(object.colour),
        Variant::Texture => object.appearance.clone().unwrap_or(Material::Patches {
            cell: 0.02,
            seed: k as u64 + 1,
        }),
    };
    FrameStyle {
        material,
        random_surface: options.variant == Variant::Texture
            && object.appearance.is_none()
            && options.randomization.textures,
        distractors: options.distractors,
        occluders: options.occluders,
        sensor: options.sensor,
        mask_errors: options.mask_errors,
        randomization: options.randomization,
        borrowed_textures: borrowed.to_vec(),
    }
}

/// Renders frames `0..count` of `scene` (in parallel) of the object `(obj_id, renderer,
/// style)` and writes their images, then the scene's `scene_camera.json`, `scene_gt.json` and,
/// last, `scene_gt_info.json`; `progress` advances by one per frame.
fn render_scene(
    scene: &SceneDir,
    count: usize,
    (obj_id, renderer, style): (u32, &FrameRenderer, &FrameStyle),
    options: &SynthOptions,
    progress: &dyn Progress,
) -> Result<(), SynthError> {
    let frames: Vec<(u32, GtInstance, GtInfo)> = (0..count as u32)
        .into_par_iter()
        .map(|im_id| {
            let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
            rng.set_stream((u64::from(scene.id) << 32) | u64::from(im_id));
            let frame = renderer.render(&options.camera.camera, &options.view, style, &mut rng)?;
            write_frame(scene, im_id, &frame, &options.camera)?;
            progress.advance(1);
            Ok((
                im_id,
                GtInstance {
                    obj_id,
                    pose: frame.pose,
                },
                frame.info,
            ))
        })
        .collect::<Result<_, SynthError>>()?;
    let intrinsics = Intrinsics {
        fx: options.camera.camera.fx,
        fy: options.camera.camera.fy,
        cx: options.camera.camera.cx,
        cy: options.camera.camera.cy,
        depth_scale: options.camera.depth_scale,
    };
    let cameras = frames.iter().map(|f| (f.0, intrinsics)).collect();
    let gt = frames.iter().map(|f| (f.0, vec![f.1.clone()])).collect();
    let info = frames.iter().map(|f| (f.0, vec![f.2])).collect();
    write_scene_camera(&scene.camera_path(), &cameras)?;
    write_scene_gt(&scene.gt_path(), &gt)?;
    write_scene_gt_info(&scene.gt_info_path(), &info)?;
    Ok(())
}

/// Whether a finished `scene` (its `scene_gt_info.json` is written last) still holds every file
/// of its `count` frames, whole: the three JSON files read and name every frame, and each
/// frame's RGB, depth and masks end as whole PNGs ([`image_file_complete`]).
fn scene_complete(scene: &SceneDir, count: usize) -> bool {
    let (Ok(cameras), Ok(gt), Ok(info)) = (
        read_scene_camera(&scene.camera_path()),
        read_scene_gt(&scene.gt_path()),
        read_scene_gt_info(&scene.gt_info_path()),
    ) else {
        return false;
    };
    (0..count as u32).all(|im_id| {
        cameras.contains_key(&im_id)
            && gt.contains_key(&im_id)
            && info.contains_key(&im_id)
            && [
                scene.rgb_path(im_id),
                scene.depth_path(im_id),
                scene.mask_path(im_id, 0),
                scene.mask_visib_path(im_id, 0),
            ]
            .iter()
            .all(|path| image_file_complete(path))
    })
}

/// Writes a frame's RGB, depth and masks (instance 0) into `scene`.
fn write_frame(
    scene: &SceneDir,
    im_id: u32,
    frame: &Frame,
    camera: &BopCamera,
) -> Result<(), FileError> {
    let (width, height) = (camera.camera.width, camera.camera.height);
    bop_dataset::write_rgb(&scene.rgb_path(im_id), &frame.rgb, width, height)?;
    bop_dataset::write_depth(
        &scene.depth_path(im_id),
        &frame.depth,
        width,
        height,
        camera.depth_scale,
    )?;
    bop_dataset::write_mask(&scene.mask_path(im_id, 0), &frame.mask, width, height)?;
    bop_dataset::write_mask(
        &scene.mask_visib_path(im_id, 0),
        &frame.mask_visib,
        width,
        height,
    )
}
