//! `ipdf render`: a mesh at a BOP pose seen by a BOP camera, written as BOP depth (and
//! optionally RGB and mask) PNGs.
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use depth_render::{DepthNoise, Instance, Lighting, Material, Scene, Window, load_mesh};
use serde_json::json;

/// Surface colouring of `--rgb`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Texture {
    /// Light grey, or the mesh's vertex colours when it has them.
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
    /// Millimetres per depth unit (BOP's `depth_scale`).
    #[arg(long, default_value_t = 1.0)]
    pub depth_scale: f64,
    /// Colouring of the RGB image.
    #[arg(long, value_enum, default_value = "uniform")]
    pub texture: Texture,
    /// Add Kinect-like depth noise (Gaussian growing with depth, 1 mm steps, edge dropout).
    #[arg(long)]
    pub noise: bool,
}

/// Runs `ipdf render`; returns `{"width", "height", "pixels", "bbox", "depth_min_m",
/// "depth_max_m", "render_ms"}` (`bbox` = `[u0, v0, u1, v1]` of the visible object, exclusive
/// ends, or null).
pub fn run(args: &RenderArgs, seed: u64) -> Result<serde_json::Value> {
    if !(args.depth_scale.is_finite() && args.depth_scale > 0.0) {
        anyhow::bail!("--depth-scale must be positive, got {}", args.depth_scale);
    }
    let mesh = load_mesh(&args.mesh, args.mesh_scale)?;
    let camera = bop_dataset::camera_from_json(
        &bop_dataset::read_json(&args.camera)?,
        &args.camera,
        "",
        None,
    )?
    .camera;
    let pose = bop_dataset::pose_from_json(&bop_dataset::read_json(&args.pose)?, &args.pose, "")?;
    let material = match (args.texture, mesh.colors()) {
        (Texture::Patches, _) => Material::Patches { cell: 0.02, seed },
        (Texture::Uniform, Some(_)) => Material::VertexColors,
        (Texture::Uniform, None) => Material::Uniform([0.8, 0.8, 0.8]),
    };
    let scene = Scene::new(&[mesh]);
    let instances = [Instance::new(0, pose)];
    let start = Instant::now();
    let rendering = scene.render(&camera, &instances, Window::full(&camera))?;
    let render_ms = start.elapsed().as_secs_f64() * 1e3;
    let (width, height) = (camera.width, camera.height);
    let noisy;
    let depth = if args.noise {
        noisy = DepthNoise::default().apply(&rendering.depth, width as usize, seed);
        &noisy
    } else {
        &rendering.depth
    };
    bop_dataset::write_depth(&args.out, depth, width, height, args.depth_scale)?;
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
    let depths = rendering
        .depth
        .iter()
        .zip(&mask)
        .filter(|(_, m)| **m)
        .map(|(d, _)| f64::from(*d));
    let pixels = mask.iter().filter(|m| **m).count();
    Ok(json!({
        "width": width,
        "height": height,
        "pixels": pixels,
        "bbox": bbox,
        "depth_min_m": depths.clone().reduce(f64::min),
        "depth_max_m": depths.reduce(f64::max),
        "render_ms": render_ms,
    }))
}
