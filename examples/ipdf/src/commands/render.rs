//! `ipdf render`: a mesh at a BOP pose seen by a BOP camera, written as BOP depth (and
//! optionally RGB and mask) PNGs.
use std::path::PathBuf;
use std::time::Instant;

use super::choice::choice;
use super::{check_extension, warn_repairs};
use anyhow::{Context, Result, bail};
use depth_render::{Instance, Lighting, Material, Scene, SensorPreset, Window, check_mesh_size};
use serde_json::json;
use synth_data::SynthObject;

/// Surface colouring of `--rgb`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Texture {
    /// Light grey, or the mesh's own surface when it has one: the texture image it names (PLY
    /// `comment TextureFile`, OBJ `map_Kd`), else its vertex colours.
    Uniform,
    /// Model-space patches of random colour: breaks the visual symmetry, not the geometric one.
    Patches,
}

/// Arguments of `ipdf render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Mesh file (.ply or .obj).
    #[arg(long)]
    pub mesh: PathBuf,
    /// Factor from the mesh's units to metres (BOP meshes are in millimetres).
    #[arg(long, default_value_t = 0.001)]
    pub mesh_scale: f64,
    /// Camera JSON: `cam_K` (row-major 9), `width`, `height` (or BOP's `fx fy cx cy width height`).
    #[arg(long)]
    pub camera: PathBuf,
    /// Pose JSON: `cam_R_m2c` (row-major 9) and `cam_t_m2c` (mm), model→camera.
    #[arg(long)]
    pub pose: PathBuf,
    /// Depth PNG to write: uint16 in units of `--depth-scale` mm, 0 where nothing is hit.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the shaded RGB image (PNG).
    #[arg(long)]
    pub rgb: Option<PathBuf>,
    /// Also write the object mask (8-bit PNG, 255 on the object).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Millimetres per depth unit (BOP's `depth_scale`; default: the camera file's
    /// `depth_scale`, else 1). A value that contradicts the camera file's is refused.
    #[arg(long)]
    pub depth_scale: Option<f64>,
    /// Colouring of the RGB image.
    #[arg(long, value_enum, default_value = "uniform")]
    pub texture: Texture,
    /// Write what this depth sensor reads instead of clean depth: axial and lateral noise,
    /// quantisation, shadows, dropped pixels, a 1 px misregistration (see
    /// `depth_render::DepthSensor`).
    #[arg(long, value_parser = choice::<SensorPreset>())]
    pub sensor: Option<SensorPreset>,
}

/// Runs `ipdf render`; returns `{"width", "height", "pixels", "bbox", "depth_min_m",
/// "depth_max_m", "depth_scale", "render_ms"}` (and a `"warning"` when nothing is in view) (`bbox` = `[u0, v0, u1, v1]` of the visible object, exclusive
/// ends, or null).
pub fn run(args: &RenderArgs, seed: u64) -> Result<serde_json::Value> {
    check_extension("--out", &args.out, "png", "the depth image (16-bit PNG)")?;
    if let Some(path) = &args.rgb {
        check_extension("--rgb", path, "png", "the colour image (PNG)")?;
    }
    if let Some(path) = &args.mask {
        check_extension("--mask", path, "png", "the mask (8-bit PNG)")?;
    }
    let (object, repairs) = SynthObject::from_mesh_file(&args.mesh, args.mesh_scale)?;
    warn_repairs(&args.mesh, &repairs);
    let mesh = object.mesh;
    check_mesh_size(&mesh, &args.mesh, args.mesh_scale, "--mesh-scale")?;
    let camera_json = bop_dataset::read_json(&args.camera)?;
    let camera = bop_dataset::camera_from_json(&camera_json, &args.camera, "", None)?;
    let depth_scale = depth_scale(args, &camera_json, camera.depth_scale)?;
    let camera = camera.camera;
    let pose = bop_dataset::pose_from_json(&bop_dataset::read_json(&args.pose)?, &args.pose, "")?;
    let material = match (args.texture, object.appearance) {
        (Texture::Patches, _) => Material::Patches { cell: 0.02, seed },
        (Texture::Uniform, Some(own)) => own,
        (Texture::Uniform, None) => Material::Uniform([0.8, 0.8, 0.8]),
    };
    let scene = Scene::new(&[mesh]);
    let instances = [Instance::new(0, pose)];
    let start = Instant::now();
    let rendering = scene.render(&camera, &instances, Window::full(&camera))?;
    let render_ms = start.elapsed().as_secs_f64() * 1e3;
    let (width, height) = (camera.width, camera.height);
    let noisy;
    let depth = if let Some(sensor) = args.sensor {
        noisy = sensor.sensor().apply(&rendering.depth, &camera, seed);
        &noisy
    } else {
        &rendering.depth
    };
    bop_dataset::write_depth(&args.out, depth, width, height, depth_scale)?;
    if let Some(path) = &args.rgb {
        let rgb = scene
            .shade(
                &camera,
                &instances,
                &[material],
                &Lighting::default(),
                &rendering,
            )
            .context("shading")?;
        bop_dataset::write_rgb(path, &rgb, width, height)?;
    }
    let mask: Vec<bool> = rendering.instance.iter().map(Option::is_some).collect();
    if let Some(path) = &args.mask {
        bop_dataset::write_mask(path, &mask, width, height)?;
    }
    let bbox = bop_dataset::mask_box(&mask, width as usize);
    // The depth written: with --sensor, what the sensor reads, its dropped pixels excluded.
    let depths = depth
        .iter()
        .zip(&mask)
        .filter(|(d, m)| **m && **d > 0.0)
        .map(|(d, _)| f64::from(*d));
    let pixels = mask.iter().filter(|m| **m).count();
    let mut result = json!({
        "width": width,
        "height": height,
        "pixels": pixels,
        "bbox": bbox,
        "depth_min_m": depths.clone().reduce(f64::min),
        "depth_max_m": depths.reduce(f64::max),
        "depth_scale": depth_scale,
        "render_ms": render_ms,
        "mesh_repairs": repairs,
    });
    if pixels == 0 {
        let warning = "the object is not in view: check the pose (cam_t_m2c is in millimetres, \
                       along the camera's +z)";
        eprintln!("warning: {warning}");
        result["warning"] = json!(warning);
    }
    Ok(result)
}

/// Millimetres per depth unit: `--depth-scale`, else the camera file's `depth_scale`, else 1;
/// refuses a flag that contradicts the file.
fn depth_scale(args: &RenderArgs, camera_json: &serde_json::Value, in_file: f64) -> Result<f64> {
    let file_has_it = camera_json.get("depth_scale").is_some();
    let scale = match args.depth_scale {
        Some(flag) if file_has_it && (flag - in_file).abs() > 1e-9 * in_file.abs() => bail!(
            "--depth-scale {flag} contradicts depth_scale {in_file} of {}: leave the flag out \
             to use the file's",
            args.camera.display()
        ),
        Some(flag) => flag,
        None if file_has_it => in_file,
        None => 1.0,
    };
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--depth-scale must be positive, got {scale}");
    }
    Ok(scale)
}
