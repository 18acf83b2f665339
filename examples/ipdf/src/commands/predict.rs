//! `ipdf predict`: the distribution over SO(3) of a trained model for one object in one image
//! (`.npy`, in the cell order of `ipdf grid`), and its most likely rotation (JSON); for a
//! translation model, or a pose run (a rotation model with one in `translation/`), the
//! distribution over translations too and the most likely translation (`cam_t_m2c`, mm); with
//! the image's depth, that translation fitted to it (`fitted_cam_t_m2c`, mm), and a pose found
//! from the rotation model's hypotheses and the depth (`refined_with_depth`).
use std::path::{Path, PathBuf};

use super::check_extension;
use anyhow::{Context, Result, bail};
use bop_dataset::{
    BopCamera, Intrinsics, camera_from_json, read_depth, read_json, read_mask, write_json,
};
use depth_render::{PinholeCamera, Scene, SensorPreset, TriangleMesh, load_mesh};
use ipdf::depth_fit::{MIN_PIXELS, fit_translation, pose_from_depth};
use ipdf::eval::rotation::BALL_CANDIDATES;
use ipdf::eval::translation::{
    self, is_translation_run, pose_translation_dir, pose_translation_model,
};
use ipdf::eval::{DEPTH_HYPOTHESES, HYPOTHESIS_SPACING_DEG};
use ipdf::npy::write_f32;
use ipdf::run_info::RunInfo;
use ipdf::training_data::{CropError, FileCrop, crop_file_box, crop_files, crop_tensor};
use ipdf_model::rotation::{ArgmaxOptions, ImplicitPdf, Precision, Predictor};
use ipdf_model::translation::{CropGeometry, TranslationPdf};
use ipdf_model::{ImageBox, default_device};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde_json::{Value, json};
use so3_grid::{Grid, rotation_to_matrix, rotation_to_wxyz};

/// Arguments of `ipdf predict`.
#[derive(Debug, clap::Args)]
pub struct PredictArgs {
    /// Run folder of `ipdf train`.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Colour image (PNG or JPEG).
    #[arg(long)]
    pub rgb: PathBuf,
    /// The object's mask in it (non-zero on the object): the crop keeps its pixels only.
    #[arg(long, required_unless_present = "bbox", conflicts_with = "bbox")]
    pub mask: Option<PathBuf>,
    /// The object's box in it instead of a mask, `x,y,w,h` in pixels (a detector's box: the
    /// pixels whose centres lie in `[x, x + w) × [y, y + h)`); the crop keeps everything in
    /// it. Models trained with `ipdf train --crop box` expect such crops.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub bbox: Option<Vec<f64>>,
    /// The camera's intrinsics in pixels, `fx,fy,cx,cy` (BOP's cam_K): needed by translation
    /// models (without it or `--camera`, a pose run predicts the orientation only).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub intrinsics: Option<Vec<f64>>,
    /// The camera as a JSON file instead of `--intrinsics`: BOP's `camera.json` or the file of
    /// `ipdf synth --camera` (`fx fy cx cy` or `cam_K`; `width` and `height`, where given,
    /// must be the image's).
    #[arg(long, conflicts_with = "intrinsics")]
    pub camera: Option<PathBuf>,
    /// The image's depth (BOP's 16-bit PNG, in the units of `--camera`'s `depth_scale`;
    /// millimetres with `--intrinsics`): a pose run's most likely translation is also fitted to
    /// it inside `--mask`, along its line of sight, with the mesh of the run's dataset
    /// (`"fitted_cam_t_m2c"`, mm), and a rotation model's 8 rotation hypotheses (its most
    /// likely rotation, then its densest cells 30° apart) are each placed on the masked depth,
    /// refined by ICP and compared with it, the depth choosing where it can tell them apart and
    /// the model where it cannot (`"refined_with_depth"`; the library's `ipdf::depth_fit`).
    #[arg(long)]
    pub depth: Option<PathBuf>,
    #[command(flatten)]
    pub frames: super::FrameArgs,
    /// Also give the centre of the ball of this many degrees holding the most probability
    /// (`"heaviest_ball"`: the rotation most likely within that angle of the truth, the mesh
    /// pipeline's estimate at 15; the argmax is where one peak rises highest).
    #[arg(long)]
    pub ball: Option<f64>,
    /// Grid level of the rotation distribution (4: 294,912 rotations).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(0..=5))]
    pub level: u8,
    /// The rotation distribution: float32 probabilities, one per cell of `ipdf grid --level L`
    /// (cell `i` is the rotation `q · R_i`, `q` the JSON's `cell_turn_wxyz`: the identity for a
    /// model in the camera's frame, the crop's line of sight for one in the line of sight's).
    /// A translation distribution goes beside it as `<name>_translation.npy` (one row per
    /// octree cell: x, y, z of its centre in mm, its level, its probability), the most likely
    /// pose as JSON (same name, `.json`).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `ipdf predict`; returns `{"argmax": {"quaternion_wxyz", "cam_R_m2c", "cam_t_m2c",
/// "fitted_cam_t_m2c", "score"}, "level", "cells", "cell_turn_wxyz",
/// "densest": [{"quaternion_wxyz", "probability"}, …], "heaviest_ball": {"quaternion_wxyz",
/// "cam_R_m2c", "radius_deg", "mass"},
/// "translation": {"cells", "distribution", "score"}, "refined_with_depth": {"quaternion_wxyz",
/// "cam_R_m2c", "cam_t_m2c", "hypothesis", "score"}}` with the parts the run's models and the
/// inputs give.
pub fn run(args: &PredictArgs) -> Result<Value> {
    check_extension(
        "--out",
        &args.out,
        "npy",
        "the distribution (a NumPy array; the most likely pose goes beside it as .json)",
    )?;
    super::check_ball(args.ball)?;
    if args.depth.is_some() && args.mask.is_none() {
        bail!("--depth needs --mask: the object's own pixels (a box holds the background too)");
    }
    let (members, translation, skipped) = load_models(args)?;
    let rotation = members.first();
    let size = match (&rotation, &translation) {
        (Some(model), _) => model.config().input_size,
        (None, Some(model)) => model.config().network.input_size,
        (None, None) => bail!("{}: no model", args.checkpoint.display()),
    } as usize;
    let crop = match (&args.mask, args.bbox.as_deref()) {
        (Some(mask), _) => crop_files(&args.rgb, mask, size)?,
        (None, Some(values)) => box_crop(&args.rgb, values, size)?,
        (None, None) => bail!("--mask or --bbox: where the object is in --rgb"),
    };
    // Every input is checked before anything is written.
    let frame = rotation.as_ref().map(|m| m.config().rotation_frame);
    let needs_camera = translation.is_some() || frame.is_some_and(|f| !f.is_camera());
    let geometry = needs_camera
        .then(|| crop_geometry(&crop, args))
        .transpose()?;
    let depth_view = args
        .depth
        .as_ref()
        .map(|depth| depth_view(depth, &crop, args, rotation.is_none()))
        .transpose()?;
    let mut result = json!({});
    let mut most_likely = None;
    if let Some(model) = &rotation {
        let turn = geometry
            .as_ref()
            .map_or_else(UnitQuaternion::identity, |g| {
                model.config().rotation_frame.to_camera(g)
            });
        let (value, best, hypotheses) = predict_rotation(&members, &crop, &turn, args)?;
        result = value;
        most_likely = Some(best);
        if let Some(view) = &depth_view {
            match view.refine(&hypotheses)? {
                Some(found) => result["refined_with_depth"] = refined_json(&found),
                None => eprintln!(
                    "ipdf predict: the depth inside --mask could not be registered to the run's \
                     mesh (too few readings, or a mesh of another scale): no refined pose"
                ),
            }
        }
    }
    if let (Some(model), Some(geometry)) = (&translation, &geometry) {
        add_translation(
            &mut result,
            model,
            (&crop, geometry),
            args,
            depth_view.as_ref(),
            most_likely,
        )?;
    }
    write_json(&args.out.with_extension("json"), &result)?;
    if let Some(dir) = skipped {
        eprintln!(
            "ipdf predict: no --intrinsics or --camera, so the orientation only (the translation \
             model of {} needs the camera's fx,fy,cx,cy)",
            dir.display()
        );
    }
    Ok(result)
}

/// The models of `--checkpoint`: the rotation model's members (one model, or an ensemble's
/// from `ensemble.json`, the first's settings shared; none in a translation run), the
/// translation model where one is used, and the translation model's folder where a pose run
/// without intrinsics leaves it out (it then predicts the orientation, and says so).
fn load_models(
    args: &PredictArgs,
) -> Result<(Vec<ImplicitPdf>, Option<TranslationPdf>, Option<PathBuf>)> {
    let translation_only = is_translation_run(&args.checkpoint)?;
    let members = (!translation_only)
        .then(|| ImplicitPdf::load_ensemble(&args.checkpoint, default_device()))
        .transpose()?
        .unwrap_or_default();
    let (translation, skipped) = match members.first() {
        None => (
            Some(TranslationPdf::load(&args.checkpoint, default_device())?),
            None,
        ),
        Some(model) if args.intrinsics.is_some() || args.camera.is_some() => {
            (pose_translation_model(&args.checkpoint, model)?, None)
        }
        Some(_) => (None, pose_translation_dir(&args.checkpoint)),
    };
    Ok((members, translation, skipped))
}

/// The translation model's answer on `crop` added to `result` (`argmax.cam_t_m2c`,
/// `translation`), and with the depth view and the most likely rotation the translation
/// fitted to the depth (`argmax.fitted_cam_t_m2c`).
fn add_translation(
    result: &mut Value,
    model: &TranslationPdf,
    (crop, geometry): (&FileCrop, &CropGeometry),
    args: &PredictArgs,
    depth_view: Option<&DepthView>,
    most_likely: Option<UnitQuaternion<f64>>,
) -> Result<()> {
    let (t, summary) = predict_translation(model, crop, geometry, args)?;
    result["argmax"]["cam_t_m2c"] = json!([t.x, t.y, t.z]);
    result["translation"] = summary;
    if let (Some(view), Some(rotation)) = (depth_view, most_likely) {
        let pose = Isometry3::from_parts((t / 1000.0).into(), rotation);
        match view.fit(&pose) {
            Some(fitted) => {
                let f = fitted.translation.vector * 1000.0;
                result["argmax"]["fitted_cam_t_m2c"] = json!([f.x, f.y, f.z]);
            }
            None => eprintln!(
                "ipdf predict: fewer than {MIN_PIXELS} pixels of --mask read a depth where \
                 the mesh at the most likely pose shows its surface: no fitted translation"
            ),
        }
    }
    Ok(())
}

/// The rotation distribution written to `--out`, the JSON of the most likely rotation and the
/// densest cells, the most likely rotation, and the rotation hypotheses a pose is refined from
/// with depth; `turn` takes the model's frame into the camera's, in which every rotation is
/// given (the distribution's cells are the grid's rotations turned by it). `models`: one model,
/// or an ensemble's members.
fn predict_rotation(
    models: &[ImplicitPdf],
    crop: &FileCrop,
    turn: &UnitQuaternion<f64>,
    args: &PredictArgs,
) -> Result<(Value, UnitQuaternion<f64>, Vec<UnitQuaternion<f64>>)> {
    let mut predictor =
        Predictor::ensemble(models, Precision::Model)?.with_views(args.frames.views.into())?;
    let crop = crop_tensor(&crop.pixels, models[0].config().input_size as usize);
    // The encoder runs once: the grid's masses and the argmax share the crop's image term.
    let image_term = predictor.image_term(&crop)?;
    let masses = predictor.probabilities_for(&image_term, args.level)?;
    write_f32(&args.out, &[masses.len() as u64], &masses)?;
    let options = ArgmaxOptions::default();
    let refined = predictor.hierarchical_for(&image_term, &options.refine)?;
    let best = predictor.argmax_from(&image_term, &refined, &options)?;
    let hypotheses = refined
        .rotation_hypotheses(
            best.rotation,
            DEPTH_HYPOTHESES,
            HYPOTHESIS_SPACING_DEG.to_radians(),
        )?
        .iter()
        .map(|h| turn * h)
        .collect();
    let most_likely = turn * best.rotation;
    let grid = Grid::new(args.level)?;
    let mut order: Vec<usize> = (0..masses.len()).collect();
    order.sort_by(|&a, &b| masses[b].total_cmp(&masses[a]));
    let densest = order
        .iter()
        .take(5)
        .map(|&i| {
            let rotation = turn * grid.rotation(i as u64)?;
            Ok(json!({"quaternion_wxyz": rotation_to_wxyz(&rotation), "probability": masses[i]}))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut value = json!({
        "argmax": {
            "quaternion_wxyz": rotation_to_wxyz(&most_likely),
            "cam_R_m2c": rotation_to_matrix(&most_likely),
            "score": best.score,
        },
        "level": args.level,
        "cells": masses.len(),
        "cell_turn_wxyz": rotation_to_wxyz(turn),
        "densest": densest,
    });
    if let Some(degrees) = args.ball {
        let ball = refined.heaviest_ball(degrees.to_radians(), BALL_CANDIDATES)?;
        let rotation = turn * ball.rotation;
        value["heaviest_ball"] = json!({
            "quaternion_wxyz": rotation_to_wxyz(&rotation),
            "cam_R_m2c": rotation_to_matrix(&rotation),
            "radius_deg": degrees,
            "mass": ball.mass,
        });
    }
    Ok((value, most_likely, hypotheses))
}

/// The JSON of a pose found from the hypotheses and the depth: its rotation, its translation
/// (mm), which hypothesis it came from (0: the most likely rotation) and its render-and-compare
/// score (in the sensor's expected errors).
fn refined_json(found: &pseudo_label::SeededPose) -> Value {
    let t = found.pose.translation.vector * 1000.0;
    json!({
        "quaternion_wxyz": rotation_to_wxyz(&found.pose.rotation),
        "cam_R_m2c": rotation_to_matrix(&found.pose.rotation),
        "cam_t_m2c": [t.x, t.y, t.z],
        "hypothesis": found.hypothesis,
        "score": found.score,
    })
}

/// The depth image of `--depth`, the mask of `--mask`, the camera and the mesh of the run's
/// dataset, read and checked: what fitting the most likely pose to depth needs.
struct DepthView {
    depth: Vec<f32>,
    mask: Vec<bool>,
    camera: PinholeCamera,
    mesh: TriangleMesh,
    scene: Scene,
    obj_id: u32,
    sensor: SensorPreset,
}

impl DepthView {
    /// `pose` (metres) fitted to the depth ([`fit_translation`]).
    fn fit(&self, pose: &Isometry3<f64>) -> Option<Isometry3<f64>> {
        fit_translation(&self.scene, &self.camera, &self.depth, &self.mask, pose)
    }

    /// The pose found from `hypotheses` and the depth ([`pose_from_depth`], the labeller's
    /// default options but the sensor).
    fn refine(
        &self,
        hypotheses: &[UnitQuaternion<f64>],
    ) -> Result<Option<pseudo_label::SeededPose>> {
        let options = pseudo_label::LabelOptions {
            sensor: self.sensor,
            ..pseudo_label::LabelOptions::default()
        };
        let model = pseudo_label::ObjectModel::new(self.obj_id, &self.mesh, &options)?;
        Ok(pose_from_depth(
            &model,
            &options,
            &self.camera,
            &self.depth,
            &self.mask,
            hypotheses,
        ))
    }
}

/// Reads and checks what `--depth` needs: a pose run, the camera, a depth image and a mask of
/// the colour image's size, and the run's mesh.
fn depth_view(
    path: &Path,
    crop: &FileCrop,
    args: &PredictArgs,
    translation_run: bool,
) -> Result<DepthView> {
    if translation_run {
        bail!(
            "--depth: {} is a translation run; fitting its translation to depth needs a pose \
             run's rotation",
            args.checkpoint.display()
        );
    }
    let (intrinsics, _) = camera_intrinsics(crop, args)?;
    let depth = read_depth(path, intrinsics.depth_scale)?;
    let mask_path = args.mask.as_deref().context("--depth needs --mask")?;
    let mask = read_mask(mask_path)?;
    let size = (crop.width as u32, crop.height as u32);
    for (file, width, height) in [
        (path, depth.width, depth.height),
        (mask_path, mask.width, mask.height),
    ] {
        if (width, height) != size {
            bail!(
                "{}: {width} × {height} pixels, but --rgb is {} × {}",
                file.display(),
                size.0,
                size.1
            );
        }
    }
    let camera = PinholeCamera::new(
        intrinsics.fx,
        intrinsics.fy,
        intrinsics.cx,
        intrinsics.cy,
        size.0,
        size.1,
    )?;
    let info = RunInfo::read(&args.checkpoint)?;
    let mesh_path = info.dataset(None)?.model_path(info.obj_id);
    let mesh = load_mesh(&mesh_path, 0.001)
        .with_context(|| format!("{}: the run's mesh", mesh_path.display()))?
        .mesh;
    Ok(DepthView {
        depth: depth.pixels,
        mask: mask.pixels,
        camera,
        scene: Scene::new(std::slice::from_ref(&mesh)),
        mesh,
        obj_id: info.obj_id,
        sensor: args.frames.sensor,
    })
}

/// The crop of `rgb` in the box `--bbox x,y,w,h` (checked against the image).
fn box_crop(rgb: &Path, values: &[f64], size: usize) -> Result<FileCrop> {
    let &[x, y, width, height] = values else {
        bail!(
            "--bbox: 4 numbers x,y,w,h (the box's corner and size in pixels), got {}",
            values.len()
        );
    };
    let image_box = ImageBox {
        x,
        y,
        width,
        height,
    };
    match crop_file_box(rgb, &image_box, size, false) {
        Ok(crop) => Ok(crop),
        Err(CropError::BadBox(reason)) => bail!("--bbox {reason}"),
        Err(error) => Err(error.into()),
    }
}

/// Where the crop lies in the image of `--intrinsics` or `--camera` (checked).
fn crop_geometry(crop: &FileCrop, args: &PredictArgs) -> Result<CropGeometry> {
    let (intrinsics, source) = camera_intrinsics(crop, args)?;
    let geometry = crop.geometry(&intrinsics);
    geometry.validate(0).with_context(|| source)?;
    Ok(geometry)
}

/// The intrinsics of `--camera` or `--intrinsics`, and which flag gave them.
fn camera_intrinsics(crop: &FileCrop, args: &PredictArgs) -> Result<(Intrinsics, String)> {
    Ok(match (&args.camera, args.intrinsics.as_deref()) {
        (Some(path), _) => (camera_file(path, crop)?, path.display().to_string()),
        (None, Some(values)) => {
            let i = intrinsics_flag(values)?;
            let source = format!("--intrinsics {},{},{},{}", i.fx, i.fy, i.cx, i.cy);
            (i, source)
        }
        (None, None) => bail!(
            "--intrinsics fx,fy,cx,cy or --camera FILE: needed by the translation model, or a \
             rotation model in the line-of-sight frame, of {} (the camera's cam_K)",
            args.checkpoint.display()
        ),
    })
}

/// The intrinsics of `--intrinsics fx,fy,cx,cy`.
fn intrinsics_flag(values: &[f64]) -> Result<Intrinsics> {
    let &[fx, fy, cx, cy] = values else {
        bail!(
            "--intrinsics: 4 numbers fx,fy,cx,cy (the camera's cam_K), got {}",
            values.len()
        );
    };
    Ok(Intrinsics {
        fx,
        fy,
        cx,
        cy,
        depth_scale: 1.0,
    })
}

/// The intrinsics of the camera file of `--camera` (read as `ipdf synth --camera` reads it),
/// whose image size, where it gives one, is the cropped image's.
fn camera_file(path: &Path, crop: &FileCrop) -> Result<Intrinsics> {
    let image = (crop.width as u32, crop.height as u32);
    let BopCamera {
        camera,
        depth_scale,
    } = camera_from_json(&read_json(path)?, path, "", Some(image))?;
    for (key, given, actual) in [
        ("width", camera.width, image.0),
        ("height", camera.height, image.1),
    ] {
        if given != actual {
            bail!(
                "{}: {key} is {given}, but the image is {} × {} pixels (--camera names another \
                 camera's file?)",
                path.display(),
                image.0,
                image.1
            );
        }
    }
    Ok(Intrinsics {
        fx: camera.fx,
        fy: camera.fy,
        cx: camera.cx,
        cy: camera.cy,
        depth_scale,
    })
}

/// The most likely translation (`cam_t_m2c`, mm) and the summary of the distribution written
/// beside `--out`.
fn predict_translation(
    model: &TranslationPdf,
    crop: &FileCrop,
    geometry: &CropGeometry,
    args: &PredictArgs,
) -> Result<(Vector3<f64>, Value)> {
    let image = crop_tensor(&crop.pixels, model.config().network.input_size as usize);
    let prediction = translation::predict_translation(model, &image, geometry)?;
    let (centres, distribution) = (&prediction.centres, &prediction.distribution);
    let rows: Vec<f64> = centres
        .iter()
        .zip(&distribution.cells)
        .zip(&distribution.masses)
        .flat_map(|((c, &(level, _)), &mass)| [c.x, c.y, c.z, f64::from(level), mass])
        .collect();
    let path = translation_path(&args.out);
    write_f32(&path, &[centres.len() as u64, 5], &rows)?;
    let best = prediction.argmax;
    let t = best.translation;
    Ok((
        t,
        json!({
            "cam_t_m2c": [t.x, t.y, t.z],
            "score": best.score,
            "cells": centres.len(),
            "distribution": path,
        }),
    ))
}

/// `<out>_translation.npy` beside `<out>.npy`.
fn translation_path(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!("{stem}_translation.npy"))
}
