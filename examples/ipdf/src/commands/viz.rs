//! `ipdf viz`: figures as PNG: a trained model's distribution for one object in one image (the
//! Implicit-PDF visualisation, with the ground truth where the dataset has it), or a run's
//! training curves.
use std::path::PathBuf;

use super::check_extension;
use anyhow::{Result, bail};
use bop_dataset::{BopDataset, SceneDir, read_models_info, read_scene_camera, read_scene_gt};
use ipdf::eval::rotation::{crop_turn, distribution_figure};
use ipdf::plots::{plot_training_curves, write_png};
use ipdf::run_info::RunInfo;
use ipdf::training_data::{crop_files, intrinsics_of};
use ipdf_model::default_device;
use ipdf_model::rotation::ImplicitPdf;
use nalgebra::UnitQuaternion;
use serde_json::json;

/// Arguments of `ipdf viz`.
#[derive(Debug, clap::Args)]
pub struct VizArgs {
    /// Draw the training curves of this `train_log.csv` (or of the run folder holding it).
    #[arg(long, conflicts_with = "checkpoint")]
    pub train_log: Option<PathBuf>,
    /// Draw this run's distribution (with --rgb and --mask, or --scene and --image).
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// Colour image.
    #[arg(long, conflicts_with = "scene")]
    pub rgb: Option<PathBuf>,
    /// The object's mask in it.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Dataset folder of --scene/--image (default: the run's); draws the ground truth too.
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// Split of --scene.
    #[arg(long, default_value = "val")]
    pub split: String,
    /// Scene id in the dataset.
    #[arg(long)]
    pub scene: Option<u32>,
    /// Image id in the scene.
    #[arg(long)]
    pub image: Option<u32>,
    /// Instance index in the image (mask order).
    #[arg(long, default_value_t = 0)]
    pub instance: usize,
    /// Grid level of the distribution drawn (3: 36,864 rotations).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=4))]
    pub level: u8,
    /// Draw the distribution averaged over the crop and this many test-time views of it, as
    /// `ipdf predict --views` (at most 8; 0: the crop alone; 8 is what the mesh pipeline's
    /// figures draw).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=8))]
    pub views: u8,
    /// The PNG to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `ipdf viz`; returns `{"out", "width", "height"}`.
pub fn run(args: &VizArgs) -> Result<serde_json::Value> {
    check_extension("--out", &args.out, "png", "the figure (PNG)")?;
    let image = if let Some(log) = &args.train_log {
        let path = if log.is_dir() {
            log.join(ipdf_model::TRAIN_LOG)
        } else {
            log.clone()
        };
        let text = std::fs::read_to_string(&path)
            .map_err(|e| bop_dataset::FileError::new(&path, "file", e.to_string()))?;
        plot_training_curves(&text, &path)?
    } else if let Some(run) = &args.checkpoint {
        let info = RunInfo::read(run)?;
        let members = ImplicitPdf::load_ensemble(run, default_device())?;
        let model = &members[0];
        let size = model.config().input_size as usize;
        let title = format!("{}, trained on {} labels", info.object, info.labels);
        match (&args.rgb, &args.mask, args.scene, args.image) {
            (Some(rgb), Some(mask), _, _) => {
                let frame = model.config().rotation_frame;
                if !frame.is_camera() {
                    bail!(
                        "--rgb: {} answers in the {} frame, which needs the camera's intrinsics: \
                         draw it with --scene and --image of a dataset",
                        run.display(),
                        frame.name()
                    );
                }
                let crop = crop_files(rgb, mask, size)?;
                let identity = UnitQuaternion::identity();
                distribution_figure(
                    &members,
                    &crop.pixels,
                    &identity,
                    &[],
                    args.level,
                    args.views.into(),
                    &title,
                )?
            }
            (_, _, Some(scene_id), Some(im_id)) => {
                let dataset = info.dataset(args.dataset.as_deref())?;
                let scene = dataset.scene(&args.split, scene_id);
                let truth = truth_rotations(&dataset, &scene, im_id, &info, args)?;
                let crop = crop_files(
                    &scene.rgb_path(im_id),
                    &scene.visible_mask_path(im_id, args.instance),
                    size,
                )?;
                let cameras = read_scene_camera(&scene.camera_path())?;
                let turn = crop_turn(model, &crop, &intrinsics_of(&cameras, &scene, im_id)?);
                distribution_figure(
                    &members,
                    &crop.pixels,
                    &turn,
                    &truth,
                    args.level,
                    args.views.into(),
                    &title,
                )?
            }
            _ => bail!("--checkpoint needs --rgb and --mask, or --scene and --image"),
        }
    } else {
        bail!("give --train-log, or --checkpoint with an image");
    };
    write_png(&args.out, &image)?;
    Ok(json!({"out": args.out, "width": image.width(), "height": image.height()}))
}

/// The ground-truth rotations of instance `args.instance` of image `im_id` of `scene`, expanded
/// by the object's symmetries (`models_info.json`); none where the scene has no ground truth.
/// An instance of another object is refused, naming where the run's object is.
fn truth_rotations(
    dataset: &BopDataset,
    scene: &SceneDir,
    im_id: u32,
    info: &RunInfo,
    args: &VizArgs,
) -> Result<Vec<UnitQuaternion<f64>>> {
    if !scene.gt_path().exists() {
        return Ok(Vec::new());
    }
    let gt = read_scene_gt(&scene.gt_path())?;
    let instances = gt.get(&im_id).map(Vec::as_slice).unwrap_or_default();
    let found = instances.get(args.instance);
    let Some(t) = found.filter(|t| t.obj_id == info.obj_id) else {
        let what = match found {
            Some(t) => format!("instance {} is object {}", args.instance, t.obj_id),
            None => format!("has no instance {}", args.instance),
        };
        bail!(
            "{}: image {im_id} {what}, the model is for object {} ({}); {}",
            scene.gt_path().display(),
            info.obj_id,
            info.object,
            where_object(dataset, &args.split, info.obj_id)?
        );
    };
    let models = read_models_info(&dataset.models_info_path())?;
    Ok(models
        .get(&t.obj_id)
        .map(|m| m.symmetry.expand(&t.pose.rotation))
        .unwrap_or_else(|| vec![t.pose.rotation]))
}

/// Where object `obj_id` appears in `split`: its scenes and the flags of its first instance.
fn where_object(dataset: &BopDataset, split: &str, obj_id: u32) -> Result<String> {
    let mut scenes = Vec::new();
    let mut first = None;
    for scene_id in dataset.scene_ids(split)? {
        let path = dataset.scene(split, scene_id).gt_path();
        if !path.exists() {
            continue;
        }
        let gt = read_scene_gt(&path)?;
        let held = gt.iter().find_map(|(im_id, list)| {
            let k = list.iter().position(|t| t.obj_id == obj_id)?;
            Some((*im_id, k))
        });
        if let Some((im_id, k)) = held {
            scenes.push(scene_id.to_string());
            first.get_or_insert((scene_id, im_id, k));
        }
    }
    Ok(match first {
        Some((scene_id, im_id, k)) => format!(
            "split {split} holds it in scene{} {} (e.g. --scene {scene_id} --image {im_id} \
             --instance {k})",
            if scenes.len() > 1 { "s" } else { "" },
            scenes.join(", ")
        ),
        None => format!("no scene of split {split} holds it (choose the split with --split)"),
    })
}
