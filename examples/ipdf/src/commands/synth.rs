//! `ipdf synth`: a synthetic RGB-D dataset in BOP format (see `ipdf::synth`).
use super::choice::choice;
use super::{check_distance, load_mesh};
use std::path::PathBuf;

use anyhow::{Result, bail};
use bop_dataset::BopDataset;
use bop_dataset::{camera_from_json, read_json};
use depth_render::{MaskErrors, SensorPreset};
use ipdf::progress::bar;
use serde_json::json;
use synth_data::{
    ObjectKind, Placement, Randomization, SynthObject, SynthOptions, Variant, ViewRange, synthesize,
};

/// Arguments of `ipdf synth`.
#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// Dataset folder (created; a rerun with the same options completes unfinished scenes, one
    /// with other options is refused: see the split's `synth_options.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// Built-in objects, comma-separated (object ids from 1 in this order).
    #[arg(
        long,
        value_parser = choice::<ObjectKind>(),
        value_delimiter = ',',
        default_value = "can,box,bowl"
    )]
    pub objects: Vec<ObjectKind>,
    /// Mesh files (.ply/.obj) to use instead of built-in objects (no known symmetry).
    #[arg(long, value_delimiter = ',', conflicts_with = "objects")]
    pub mesh: Vec<PathBuf>,
    /// Metres per mesh unit of `--mesh` (BOP meshes are in millimetres).
    #[arg(long, default_value_t = 0.001)]
    pub mesh_scale: f64,
    /// `uniform`: one flat colour per object; `texture`: a `--mesh` file's own texture image
    /// (PLY `comment TextureFile`, OBJ `map_Kd`) or vertex colours where it has them, else
    /// colour patches that break the visual symmetry but not the geometric one.
    #[arg(long, value_parser = choice::<Variant>(), default_value = "uniform")]
    pub variant: Variant,
    /// Frames per object.
    #[arg(long, default_value_t = 1000)]
    pub frames: usize,
    /// Frames per scene folder.
    #[arg(long, default_value_t = 1000)]
    pub frames_per_scene: usize,
    /// Split folder to write (`train`, `val`, …): one plain folder name.
    #[arg(long, default_value = "train")]
    pub split: String,
    /// Distractor objects per frame (occluders, not annotated), 10–18 cm from the object's
    /// origin and never inside it.
    #[arg(long, default_value_t = 0)]
    pub distractors: usize,
    /// Objects per frame placed between the object and the camera (within 20° of the line of
    /// sight, 7–10 cm in front of its origin, farther where they would stand inside it), hiding
    /// part of it: a distractor shape or, one time in
    /// four, an upright panel as wide as the object's bounding radius and 1.6 times as tall.
    #[arg(long, default_value_t = 0)]
    pub occluders: usize,
    /// Write what this depth sensor reads instead of clean depth: axial and lateral noise,
    /// quantisation, shadows, dropped pixels, a 1 px misregistration (see
    /// `depth_render::DepthSensor`).
    #[arg(long, value_parser = choice::<SensorPreset>())]
    pub sensor: Option<SensorPreset>,
    /// Give the visible masks (`mask_visib`) a detector's errors: grown or shrunk by up to this
    /// many pixels, a fifth of the boundary pixels flipped (0: exact masks).
    #[arg(long, default_value_t = 0)]
    pub mask_errors: u32,
    /// Camera JSON (`cam_K` or `fx fy cx cy`, `width`, `height`, `depth_scale`); default a
    /// 640 × 480 camera with T-LESS's focal lengths and 0.1 mm depth units.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Lowest and highest camera elevation above the table (degrees).
    #[arg(long, num_args = 2, value_names = ["LOW", "HIGH"], default_values_t = [15.0, 80.0])]
    pub elevation: Vec<f64>,
    /// Nearest and farthest camera distance (metres).
    #[arg(long, num_args = 2, value_names = ["NEAR", "FAR"], default_values_t = [0.5, 1.0])]
    pub distance: Vec<f64>,
    /// Where the object appears: 0 in the middle of the image (the camera looks at it), 1
    /// anywhere it stays inside the image, as in real frames.
    #[arg(long, default_value_t = 0.0)]
    pub off_centre: f64,
    /// Roll the camera about its line of sight by up to this many degrees either way.
    #[arg(long, default_value_t = 0.0)]
    pub roll: f64,
    /// How the object comes to rest on the table: `tossed` (each face of its convex hull by
    /// the chance of landing on it), `arranged` (half the frames on a face drawn uniformly from
    /// those it stands on firmly, as objects set down for a camera stand: boxes on their ends,
    /// bottles upright) or `leaning` (arranged, a third of the frames tilted 5–45° off the face,
    /// as objects propped on a neighbour in clutter).
    #[arg(long, value_parser = choice::<Placement>(), default_value = "tossed")]
    pub placement: Placement,
    /// Domain randomisation, drawn per frame: `all` (alone: `--randomize`) or a comma list of
    /// `lights` (direction, strength, colour, ambient, highlight), `backgrounds` (procedural
    /// table and background textures), `textures` (distractors and occluders in procedural
    /// textures or the objects' own) and `camera` (blur, exposure, white balance, noise, tone
    /// curve, JPEG quality). The objects keep their `--variant` look, but with `textures` a
    /// mesh without texture or vertex colours wears a random surface per frame in the texture
    /// variant instead of fixed colour patches.
    #[arg(long, num_args = 0..=1, default_missing_value = "all", value_name = "PARTS")]
    pub randomize: Option<String>,
}

/// Runs `ipdf synth`; returns `{"dataset", "split", "frames", "rendered", "scenes",
/// "seconds", "frames_per_s"}`.
pub fn run(args: &SynthArgs, seed: u64) -> Result<serde_json::Value> {
    let (low, high) = (args.elevation[0], args.elevation[1]);
    if !(0.0..=90.0).contains(&low) || !(low..=90.0).contains(&high) {
        bail!("--elevation must be two angles with 0 ≤ LOW ≤ HIGH ≤ 90, got {low} {high}");
    }
    let (near, far) = (args.distance[0], args.distance[1]);
    check_distance(near, far)?;
    if !(0.0..=1.0).contains(&args.off_centre) {
        bail!("--off-centre must be in 0..=1, got {}", args.off_centre);
    }
    if !(0.0..=180.0).contains(&args.roll) {
        bail!("--roll must be in 0..=180 degrees, got {}", args.roll);
    }
    let objects = if args.mesh.is_empty() {
        args.objects
            .iter()
            .map(|&kind| SynthObject::built_in(kind))
            .collect::<Result<Vec<_>, _>>()?
    } else {
        args.mesh
            .iter()
            .map(|path| load_mesh(path, args.mesh_scale))
            .collect::<Result<Vec<_>>>()?
    };
    let camera = match &args.camera {
        Some(path) => camera_from_json(&read_json(path)?, path, "", None)?,
        None => SynthOptions::t_less_camera(),
    };
    let options = SynthOptions {
        frames: args.frames,
        frames_per_scene: args.frames_per_scene,
        variant: args.variant,
        camera,
        view: ViewRange {
            elevation_deg: (low, high),
            distance: (near, far),
            off_centre: args.off_centre,
            roll_deg: args.roll,
            placement: args.placement,
            ..ViewRange::default()
        },
        distractors: args.distractors,
        occluders: args.occluders,
        sensor: args.sensor.map(SensorPreset::sensor),
        mask_errors: (args.mask_errors > 0).then(|| MaskErrors {
            max_shift_px: args.mask_errors,
            ..MaskErrors::default()
        }),
        randomization: match &args.randomize {
            Some(parts) => Randomization::parse(parts)?,
            None => Randomization::NONE,
        },
        seed,
    };
    let dataset = BopDataset::new(&args.out);
    let progress = bar((args.frames * objects.len()) as u64, "frames");
    let summary = synthesize(&dataset, &args.split, &objects, &options, &progress)?;
    progress.finish_and_clear();
    Ok(json!({
        "dataset": args.out,
        "split": args.split,
        "frames": summary.frames,
        "rendered": summary.rendered,
        "repaired": summary.repaired,
        "scenes": summary.scenes,
        "seconds": summary.seconds,
        "frames_per_s": summary.rendered as f64 / summary.seconds.max(1e-9),
    }))
}
