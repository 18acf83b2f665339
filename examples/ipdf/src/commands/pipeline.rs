//! `ipdf pipeline`: the whole method on synthetic data, or with `--mesh` on one object of the
//! user's (see `ipdf::pipeline`); this module maps the flags onto a [`Plan`].
use std::path::PathBuf;

use anyhow::{Context, Result};
use bop_dataset::{BopDataset, camera_from_json, read_json};
use depth_render::SensorPreset;
use ipdf::pipeline::{MeshRequest, Plan, Preset, RealSplit, run_mesh_pipeline, run_pipeline};
use ipdf::training::MAX_MEMBERS;
use ipdf_model::EncoderKind;
use ipdf_model::rotation::RotationFrame;
use synth_data::{Placement, Randomization};

use super::choice::choice;
use super::train::parse_encoder;
use super::{check_distance, load_mesh};

/// Arguments of `ipdf pipeline`.
#[derive(Debug, clap::Args)]
pub struct PipelineArgs {
    /// How big a run (each preset's settings: docs/guide.md, "The presets"; the flags below
    /// override them).
    #[arg(long, value_parser = choice::<Preset>(), default_value = "quick")]
    pub preset: Preset,
    /// Run folder (a rerun with the same settings skips finished stages; one with other
    /// settings is refused: see `pipeline_config.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// Override the preset's training frames per object (uniform dataset).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Override the preset's validation frames per object.
    #[arg(long)]
    pub val_frames: Option<usize>,
    /// Override the preset's frames per object of the textured dataset.
    #[arg(long)]
    pub texture_frames: Option<usize>,
    /// The depth camera whose readings the datasets' depth imitates and the labelling expects,
    /// instead of the preset's (every preset: a Kinect v1).
    #[arg(long, value_parser = choice::<SensorPreset>(), conflicts_with = "clean_depth")]
    pub sensor: Option<SensorPreset>,
    /// Clean rendered depth instead of a sensor's readings.
    #[arg(long)]
    pub clean_depth: bool,
    /// Label with the mesh's colours too (`ipdf label --appearance-margin`): labels whose
    /// colours match the render worse than the best label's by more than this are dropped
    /// (0, every preset's: off; 0.2 is the measured choice).
    #[arg(long, value_parser = super::parse_appearance_margin)]
    pub appearance_margin: Option<f64>,
    /// Override the preset's epochs (of the translation models too, unless
    /// --translation-epochs is given).
    #[arg(long)]
    pub epochs: Option<u64>,
    /// Override the preset's epochs of the translation models.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub translation_epochs: Option<u64>,
    /// Override the preset's image encoder, of the rotation and (unless
    /// --translation-encoder is given) the translation models (`ipdf train --encoder`).
    #[arg(long, value_parser = parse_encoder)]
    pub encoder: Option<EncoderKind>,
    /// The translation model's encoder, instead of --encoder's.
    #[arg(long, value_parser = parse_encoder, requires = "mesh")]
    pub translation_encoder: Option<EncoderKind>,
    /// Weights --encoder starts from, in the models it encodes for (`ipdf train --pretrained`;
    /// efficientnet-lite0's ImageNet weights: .pretrained/efficientnet-lite0.safetensors, from
    /// `make setup`).
    #[arg(long, requires = "mesh")]
    pub pretrained: Option<PathBuf>,
    /// Keep the encoder's stem and first N blocks as --pretrained (or the pretrained preset)
    /// gives them (`ipdf train --freeze-encoder`).
    #[arg(long, requires = "mesh")]
    pub freeze_encoder: Option<usize>,
    /// Override the preset's peak learning rate (of the translation models too, unless
    /// --translation-learning-rate is given).
    #[arg(long, value_parser = super::parse_learning_rate)]
    pub learning_rate: Option<f64>,
    /// Override the preset's peak learning rate of the translation models.
    #[arg(long, value_parser = super::parse_learning_rate)]
    pub translation_learning_rate: Option<f64>,
    /// Override the preset's steps per epoch.
    #[arg(long)]
    pub steps_per_epoch: Option<u64>,
    /// The frame the rotation models learn in, instead of the preset's (`ipdf train
    /// --rotation-frame`): the built-in objects' runs learn in the camera's, a `--mesh` run in
    /// the line of sight's.
    #[arg(long, value_parser = choice::<RotationFrame>())]
    pub rotation_frame: Option<RotationFrame>,
    /// Rotation models per ensemble instead of the preset's one (`ipdf train --members`): each
    /// costs a rotation training; the ensemble's density is the members' geometric mean.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_MEMBERS as u64))]
    pub rotation_members: Option<u64>,
    /// One object of your own instead of the built-in three (.ply/.obj, its texture image or
    /// vertex colours shown): randomised renders of it, pseudo labels, a rotation and a
    /// translation model, scored on the renders and on `--real` (needs `--camera`).
    #[arg(
        long,
        requires = "camera",
        conflicts_with = "texture_frames",
        required_if_eq("preset", "pretrained")
    )]
    pub mesh: Option<PathBuf>,
    /// Metres per `--mesh` unit (BOP meshes are in millimetres).
    #[arg(long, default_value_t = 0.001, requires = "mesh")]
    pub mesh_scale: f64,
    /// The camera of `--mesh`'s renders: JSON with `cam_K` or `fx fy cx cy`, `width`, `height`,
    /// `depth_scale` (your camera's; a BOP `camera.json` will do).
    #[arg(long, requires = "mesh")]
    pub camera: Option<PathBuf>,
    /// Nearest and farthest camera distance of `--mesh`'s renders (metres; default the range
    /// of a tabletop RGB-D camera, which YCB-Video's, LINEMOD's and T-LESS's test frames lie in).
    #[arg(long, num_args = 2, value_names = ["NEAR", "FAR"], default_values_t = [0.45, 1.2],
          requires = "mesh")]
    pub distance: Vec<f64>,
    /// What of `--mesh`'s renders' look is drawn at random, per frame: `all`, `none` or a comma
    /// list of `lights`, `backgrounds`, `textures` and `camera` (see `ipdf synth --randomize`).
    #[arg(long, default_value = "all", value_name = "PARTS", requires = "mesh")]
    pub randomize: String,
    /// How the object rests in `--mesh`'s renders (see `ipdf synth --placement`): `arranged`,
    /// or `leaning` where the user's scenes prop objects on one another.
    #[arg(long, value_parser = choice::<Placement>(), default_value = "arranged",
          requires = "mesh")]
    pub placement: Placement,
    /// A real BOP dataset to score `--mesh`'s models on (its `models/` gives the object's
    /// symmetries and ADD(-S) points; nothing of it is used in training).
    #[arg(long, requires_all = ["mesh", "obj_id"])]
    pub real: Option<PathBuf>,
    /// The split of `--real` scored.
    #[arg(long, default_value = "test", requires = "real")]
    pub real_split: String,
    /// The object's id in `--real`.
    #[arg(long, requires = "real")]
    pub obj_id: Option<u32>,
}

/// Runs `ipdf pipeline`; returns where the report is and the time per stage.
pub fn run(args: &PipelineArgs, seed: u64) -> Result<serde_json::Value> {
    let Some(mesh) = &args.mesh else {
        let plan = plan(args, args.preset.plan());
        return Ok(serde_json::to_value(run_pipeline(&args.out, &plan, seed)?)?);
    };
    let (near, far) = (args.distance[0], args.distance[1]);
    check_distance(near, far)?;
    let camera_file = args.camera.clone().context("--mesh needs --camera")?;
    let real = match (&args.real, args.obj_id) {
        (Some(dataset), Some(obj_id)) => Some(RealSplit {
            dataset: dataset.clone(),
            split: args.real_split.clone(),
            obj_id,
        }),
        _ => None,
    };
    if let Some(real) = &real {
        // A mistyped --real or --real-split is refused now, not after the training.
        BopDataset::new(&real.dataset).scene_ids(&real.split)?;
    }
    let request = MeshRequest {
        object: load_mesh(mesh, args.mesh_scale)?,
        mesh: mesh.clone(),
        mesh_scale: args.mesh_scale,
        camera: camera_from_json(&read_json(&camera_file)?, &camera_file, "", None)?,
        camera_file,
        distance: (near, far),
        randomization: Randomization::parse(&args.randomize)?,
        placement: args.placement,
        real,
    };
    let plan = plan(args, args.preset.mesh_plan());
    Ok(serde_json::to_value(run_mesh_pipeline(
        &args.out, &plan, &request, seed,
    )?)?)
}

/// `preset` with the flags' overrides.
fn plan(args: &PipelineArgs, preset: Plan) -> Plan {
    Plan {
        frames: args.frames.unwrap_or(preset.frames),
        val_frames: args.val_frames.unwrap_or(preset.val_frames),
        texture_frames: args.texture_frames.unwrap_or(preset.texture_frames),
        sensor: if args.clean_depth {
            None
        } else {
            args.sensor.or(preset.sensor)
        },
        epochs: args.epochs.unwrap_or(preset.epochs),
        appearance_margin: args.appearance_margin.unwrap_or(preset.appearance_margin),
        rotation_frame: args.rotation_frame.unwrap_or(preset.rotation_frame),
        rotation_members: args
            .rotation_members
            .map_or(preset.rotation_members, |k| k as usize),
        translation_epochs: args
            .translation_epochs
            .or(args.epochs)
            .unwrap_or(preset.translation_epochs),
        steps_per_epoch: args.steps_per_epoch.unwrap_or(preset.steps_per_epoch),
        encoder: args.encoder.unwrap_or(preset.encoder),
        translation_encoder: args.translation_encoder.or(preset.translation_encoder),
        learning_rate: args.learning_rate.unwrap_or(preset.learning_rate),
        translation_learning_rate: args
            .translation_learning_rate
            .or(args.learning_rate)
            .unwrap_or(preset.translation_learning_rate),
        pretrained: args.pretrained.clone().or(preset.pretrained),
        frozen_blocks: args.freeze_encoder.unwrap_or(preset.frozen_blocks),
        ..preset
    }
}
