//! `ipdf viz`: figures as PNG: a trained model's distribution for one object in one image (the
//! Implicit-PDF visualisation, with the ground truth where the dataset has it), or a run's
//! training curves.
use std::path::PathBuf;

use anyhow::{Result, bail};
use bop_dataset::{read_models_info, read_scene_gt};
use ipdf::evaluation::distribution_figure;
use ipdf::plots::{plot_training_curves, write_png};
use ipdf::run_info::RunInfo;
use ipdf::training_data::crop_files;
use ipdf_model::{ImplicitPdf, default_device};
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
    /// The PNG to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `ipdf viz`; returns `{"out", "width", "height"}`.
pub fn run(args: &VizArgs) -> Result<serde_json::Value> {
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
        let model = ImplicitPdf::load(run, default_device())?;
        let size = model.config().input_size as usize;
        let title = format!("{}, trained on {} labels", info.object, info.labels);
        match (&args.rgb, &args.mask, args.scene, args.image) {
            (Some(rgb), Some(mask), _, _) => {
                let crop = crop_files(rgb, mask, size)?;
                distribution_figure(&model, &crop, &[], args.level, &title)?
            }
            (_, _, Some(scene_id), Some(im_id)) => {
                let dataset = info.dataset(args.dataset.as_deref())?;
                let scene = dataset.scene(&args.split, scene_id);
                let truth = if scene.gt_path().exists() {
                    let gt = read_scene_gt(&scene.gt_path())?;
                    let Some(t) = gt.get(&im_id).and_then(|list| list.get(args.instance)) else {
                        bail!(
                            "{}: image {im_id} has no instance {}",
                            scene.gt_path().display(),
                            args.instance
                        );
                    };
                    if t.obj_id != info.obj_id {
                        bail!(
                            "{}: instance {} of image {im_id} is object {}, the model is for \
                             object {} ({}); choose its instance with --instance",
                            scene.gt_path().display(),
                            args.instance,
                            t.obj_id,
                            info.obj_id,
                            info.object
                        );
                    }
                    let models = read_models_info(&dataset.models_info_path())?;
                    models
                        .get(&t.obj_id)
                        .map(|m| m.symmetry.expand(&t.pose.rotation))
                        .unwrap_or_else(|| vec![t.pose.rotation])
                } else {
                    Vec::new()
                };
                let crop = crop_files(
                    &scene.rgb_path(im_id),
                    &scene.visible_mask_path(im_id, args.instance),
                    size,
                )?;
                distribution_figure(&model, &crop, &truth, args.level, &title)?
            }
            _ => bail!("--checkpoint needs --rgb and --mask, or --scene and --image"),
        }
    } else {
        bail!("give --train-log, or --checkpoint with an image");
    };
    write_png(&args.out, &image)?;
    Ok(json!({"out": args.out, "width": image.width(), "height": image.height()}))
}
