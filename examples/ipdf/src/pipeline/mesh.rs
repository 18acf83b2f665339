//! `ipdf pipeline --mesh`: one object of the user's, from its mesh and camera to a pose model,
//! as one resumable run: randomised renders of the mesh (its own texture or vertex colours, off
//! centre, rolled, among distractors and occluders, with a depth sensor's readings) → pseudo
//! labels of the training renders (no pose read) → a Pseudo rotation model and its translation
//! model → scores on the validation renders and, given one, on a real BOP split →
//! `report.md` / `report.json` and figures. The settings are recorded in
//! `pipeline_config.json`, and a rerun with other settings is refused.
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use bop_dataset::{
    BopDataset, FileError, read_json_as, read_models_info, write_atomically, write_json,
    write_models_info,
};
use depth_render::SensorPreset;
use ipdf_model::rotation::{ImplicitPdf, MAX_EXTRA_VIEWS};
use ipdf_model::{EncoderKind, TRAIN_LOG, default_device, load_backbone};
use pseudo_label::LabelReport;
use serde::{Deserialize, Serialize};
use synth_data::{
    Placement, Randomization, SynthObject, SynthOptions, Variant, ViewRange, synthesize,
};

use super::config::{Plan, check_and_record};
use super::report::LabelAccuracy;
use super::{PipelineSummary, StageTimes, first_instance_figure, label_split, on_threads};
use super::{score_labels, train_request, write_figure, write_report};
use crate::Error;
use crate::eval::instances::markdown;
use crate::eval::{DEPTH_HYPOTHESES, EvalRequest, EvalResult, evaluate_run};
use crate::plots::{plot_training_curves, write_png};
use crate::progress::bar;
use crate::training::{
    TRANSLATION_DIR, Target, TrainRequest, ensemble_requests, is_trained, name_members, train_model,
};

/// A real BOP split to score the models on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RealSplit {
    /// The dataset folder (its `models/` gives the object's symmetries and ADD(-S) points).
    pub dataset: PathBuf,
    /// The split (`test`, …).
    pub split: String,
    /// The object's id in that dataset.
    pub obj_id: u32,
}

/// The user's object and where it is seen.
#[derive(Debug, Clone)]
pub struct MeshRequest {
    /// The object, loaded from `mesh`.
    pub object: SynthObject,
    /// Its mesh file, as given.
    pub mesh: PathBuf,
    /// Metres per mesh unit.
    pub mesh_scale: f64,
    /// The camera file, as given.
    pub camera_file: PathBuf,
    /// The camera read from it.
    pub camera: bop_dataset::BopCamera,
    /// Nearest and farthest camera distance of the renders (metres).
    pub distance: (f64, f64),
    /// What of the renders' look is drawn at random ([`Randomization::ALL`]: everything).
    pub randomization: Randomization,
    /// How the object rests in the renders.
    pub placement: Placement,
    /// The real split to score on, if any.
    pub real: Option<RealSplit>,
}

/// `pipeline_config.json` of a mesh run, and the `"config"` of its `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshConfig {
    /// What the run does.
    #[serde(flatten)]
    pub plan: Plan,
    /// The run's seed.
    pub seed: u64,
    /// The mesh file, as given.
    pub mesh: PathBuf,
    /// Metres per mesh unit.
    pub mesh_scale: f64,
    /// The camera file, as given.
    pub camera: PathBuf,
    /// Nearest and farthest camera distance of the renders (metres).
    pub distance_m: [f64; 2],
    /// The parts of the renders' look drawn at random (`lights`, `backgrounds`, `textures`,
    /// `camera`).
    pub randomize: Vec<String>,
    /// How the object rests in the renders (`arranged`, …).
    pub placement: String,
    /// The real split scored, if any.
    pub real: Option<RealSplit>,
    /// The dataset trained on.
    pub training_data: String,
}

/// `report.json` of a mesh run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshReport {
    /// The object's name (the mesh file's stem).
    pub object: String,
    /// The pseudo labels of the training renders against the renders' truth.
    pub labels: LabelAccuracy,
    /// The models' scores on the validation renders.
    pub renders: EvalResult,
    /// Their scores on the real split, per instance too, if one was given.
    pub real: Option<EvalResult>,
    /// Seconds per stage of the invocation that wrote the report.
    pub timing_s: BTreeMap<String, f64>,
    /// The run's settings.
    pub config: MeshConfig,
}

/// The renders' folder in the run.
const DATA: &str = "data";

/// The models' folder (the rotation model; its translation model in `translation/`).
const MODEL: &str = "model";

/// Test-time views of each crop the rotation model's scores average over: every view there is.
/// On the ten real YCB-Video objects' models they raised the validation renders' LLH of each
/// and turned one more real instance into a true pose (docs/experiments.md, "Views of the crop
/// at test time"); the demo's runs score the crop alone, as the paper does.
const VIEWS: usize = MAX_EXTRA_VIEWS;

/// The radius (degrees) of the ball whose heaviest centre is each crop's rotation estimate
/// ([`EvalRequest::ball_deg`]): the estimate most often within 15° of the truth. On the real
/// YCB-Video objects' models it was nearer the truth than the argmax for most instances and
/// validation renders (docs/experiments.md, "The heaviest ball"); the demo's runs score the
/// argmax, as the paper does.
const BALL_DEG: f64 = 15.0;

/// Runs (or resumes) the pipeline of `plan` for the object of `request` into `out`.
pub fn run_mesh_pipeline(
    out: &Path,
    plan: &Plan,
    request: &MeshRequest,
    seed: u64,
) -> Result<PipelineSummary, Error> {
    let config = MeshConfig {
        plan: plan.clone(),
        seed,
        mesh: request.mesh.clone(),
        mesh_scale: request.mesh_scale,
        camera: request.camera_file.clone(),
        distance_m: [request.distance.0, request.distance.1],
        randomize: request
            .randomization
            .names()
            .into_iter()
            .map(String::from)
            .collect(),
        placement: request.placement.name().into(),
        real: request.real.clone(),
        training_data: "randomised renders".into(),
    };
    let (data, model) = (out.join(DATA), out.join(MODEL));
    check_encoder(plan, &model)?;
    check_and_record(out, &config)?;
    let real = request.real.as_ref();
    if let Some(real) = real {
        warn_without_masks(real)?;
    }
    let mut stages = StageTimes::of(out)?;
    stages.run("synth", || synthesize_renders(&data, plan, request, seed))?;
    if let Some(real) = real {
        adopt_symmetries(&data, real)?;
    }
    let labels = stages.run("label", || label_renders(out, &data, plan, seed))?;
    stages.run("train", || train_pose(&data, &model, plan, seed))?;
    let (renders, real_scores) = stages.run("eval", || score(out, &model, plan, real))?;
    let figures = out.join("figures");
    let object = &request.object.name;
    stages.run("figures", || {
        draw_figures(&figures, &data, &model, plan, object, real)
    })?;

    let report = MeshReport {
        object: object.clone(),
        labels,
        renders,
        real: real_scores,
        timing_s: stages.seconds,
        config,
    };
    write_report(out, &report, &report.to_markdown(), report.timing_s.clone())
}

/// Warns, before anything is rendered, when no scene of the real split has masks
/// (`mask_visib/`, or `mask/`): its instances will be scored on crops cut around their boxes,
/// clutter included, which the models, trained on masked crops, read poorly.
fn warn_without_masks(real: &RealSplit) -> Result<(), Error> {
    let dataset = BopDataset::new(&real.dataset);
    let masked = dataset
        .scene_ids(&real.split)?
        .into_iter()
        .any(|id| dataset.scene(&real.split, id).has_masks());
    if !masked {
        eprintln!(
            "warning: split {:?} of {} has no visible masks (mask_visib/): its instances will \
             be scored on crops cut around their boxes, clutter included, which models trained \
             on masked renders read poorly; give it a segmenter's masks for scores that mean \
             what they do on masks",
            real.split,
            real.dataset.display()
        );
    }
    Ok(())
}

/// Stage 1: the training and validation renders (complete scenes are skipped).
fn synthesize_renders(
    data: &Path,
    plan: &Plan,
    request: &MeshRequest,
    seed: u64,
) -> Result<(), Error> {
    let objects = [request.object.clone()];
    for (split, frames, split_seed) in [
        ("train", plan.frames, seed),
        ("val", plan.val_frames, seed + 1),
    ] {
        let options = SynthOptions {
            frames,
            frames_per_scene: frames,
            variant: Variant::Texture,
            camera: request.camera,
            view: ViewRange {
                distance: request.distance,
                off_centre: 1.0,
                roll_deg: 30.0,
                placement: request.placement,
                ..ViewRange::default()
            },
            distractors: 2,
            occluders: 2,
            sensor: plan.sensor.map(SensorPreset::sensor),
            mask_errors: None,
            randomization: request.randomization,
            seed: split_seed,
        };
        let progress = bar(frames as u64, "frames");
        synthesize(&BopDataset::new(data), split, &objects, &options, &progress)?;
        progress.finish_and_clear();
    }
    Ok(())
}

/// With a real split, the renders' object takes the symmetries its `models_info.json` gives
/// the object there (the mesh is scored in that object's frame, so they are the mesh's), and
/// its labels and validation renders are scored against every symmetric pose rather than the
/// rendered one alone. Nothing trained reads them.
fn adopt_symmetries(data: &Path, real: &RealSplit) -> Result<(), Error> {
    let real_info = BopDataset::new(&real.dataset).models_info_path();
    let symmetry = read_models_info(&real_info)?
        .remove(&real.obj_id)
        .ok_or_else(|| FileError::new(&real_info, real.obj_id.to_string(), "no such object"))?
        .symmetry;
    let path = BopDataset::new(data).models_info_path();
    let mut models = read_models_info(&path)?;
    for info in models.values_mut() {
        info.symmetry.clone_from(&symmetry);
    }
    write_models_info(&path, &models)?;
    Ok(())
}

/// Stage 2: pseudo labels of the training renders, scored against their truth
/// (`labels.json`, kept: a rerun reads it back).
fn label_renders(out: &Path, data: &Path, plan: &Plan, seed: u64) -> Result<LabelAccuracy, Error> {
    let path = out.join("labels.json");
    if !path.exists() {
        label_split(data, plan, seed)?;
        score_labels(data, "randomised")?.write(&path)?;
    }
    let report: LabelReport = read_json_as(&path)?;
    report
        .objects
        .into_values()
        .next()
        .map(|scores| LabelAccuracy {
            label_maad_deg: scores.label_maad_deg,
            coverage: scores.coverage,
        })
        .ok_or_else(|| Error::option("labels", format!("{}: no object", path.display())))
}

/// Refuses, before any render, an encoder the training would refuse: a freeze the encoder
/// cannot make or without weights to keep, or pretrained weights that do not fit it (a
/// missing file, with where they come from; another network's). The weights are read only
/// while a model that starts from them is still to be trained: a finished run's report is
/// written again without them.
fn check_encoder(plan: &Plan, model: &Path) -> Result<(), Error> {
    let config = train_request(plan, Path::new(""), Target::Rotation, 0).model;
    config.validate()?;
    let Some(path) = &plan.pretrained else {
        if plan.frozen_blocks > 0 {
            return Err(Error::option(
                "frozen_blocks",
                format!(
                    "{} blocks frozen, but no --pretrained weights to keep",
                    plan.frozen_blocks
                ),
            ));
        }
        return Ok(());
    };
    let pending = untrained_models(Path::new(""), model, plan, 0)?;
    if pending.iter().any(|request| request.pretrained.is_some()) {
        if !path.is_file() {
            let source = if plan.encoder == EncoderKind::EfficientnetLite0 {
                " (EfficientNet-Lite0's ImageNet weights: `make setup` puts them in the \
                 repository's .pretrained/; --pretrained names another place)"
            } else {
                ""
            };
            return Err(Error::option(
                "pretrained",
                format!("{}: no such file{source}", path.display()),
            ));
        }
        let mut model = ImplicitPdf::new(config, tch::Device::Cpu)?;
        load_backbone(&mut model, path)?;
    }
    Ok(())
}

/// The models of stage 3 not trained yet: each member of the rotation ensemble in `model`, and
/// the translation model beside them.
fn untrained_models(
    data: &Path,
    model: &Path,
    plan: &Plan,
    seed: u64,
) -> Result<Vec<TrainRequest>, Error> {
    let rotation = TrainRequest {
        out: model.to_path_buf(),
        ..train_request(plan, data, Target::Rotation, seed)
    };
    let translation = TrainRequest {
        out: model.join(TRANSLATION_DIR),
        ..train_request(plan, data, Target::Translation, seed)
    };
    let mut pending = Vec::new();
    for request in ensemble_requests(&rotation, plan.rotation_members)?
        .into_iter()
        .chain([translation])
    {
        if !is_trained(&request.out, plan.total_steps(request.target))? {
            pending.push(request);
        }
    }
    Ok(pending)
}

/// Stage 3: the rotation model in `model` (each member of its ensemble) and its translation
/// model, side by side.
fn train_pose(data: &Path, model: &Path, plan: &Plan, seed: u64) -> Result<(), Error> {
    let pending = untrained_models(data, model, plan, seed)?;
    on_threads(&pending, plan.concurrent_models, |request| {
        eprintln!("pipeline: training the {} model", request.target.name());
        let progress = bar(plan.total_steps(request.target), "steps");
        train_model(request, &progress)?;
        progress.finish_and_clear();
        Ok(())
    })?;
    name_members(model, plan.rotation_members)
}

/// Stage 4: scores on the validation renders (`eval_renders.json`) and on the real split
/// (`eval_real.json`, each instance's in `eval_real.md`), both kept.
fn score(
    out: &Path,
    model: &Path,
    plan: &Plan,
    real: Option<&RealSplit>,
) -> Result<(EvalResult, Option<EvalResult>), Error> {
    let renders = EvalRequest {
        per_instance: true,
        views: VIEWS,
        ball_deg: Some(BALL_DEG),
        ..EvalRequest::new(model.to_path_buf(), "val", plan.eval_level)
    };
    let renders = cached(&out.join("eval_renders.json"), &renders)?;
    let Some(real) = real else {
        return Ok((renders, None));
    };
    let request = EvalRequest {
        dataset: Some(real.dataset.clone()),
        obj_id: Some(real.obj_id),
        per_instance: true,
        depth_hypotheses: DEPTH_HYPOTHESES,
        sensor: plan.depth_sensor(),
        views: VIEWS,
        ball_deg: Some(BALL_DEG),
        ..EvalRequest::new(model.to_path_buf(), &real.split, plan.eval_level)
    };
    let path = out.join("eval_real.json");
    let result = cached(&path, &request)?;
    if let Some(accuracy) = &result.accuracy {
        let what = format!(
            "{}, object {} of {}, split {}",
            result.object,
            real.obj_id,
            real.dataset.display(),
            real.split
        );
        let table = markdown(&result.heading(&what), &result.instances, accuracy);
        write_atomically(&path.with_extension("md"), |f| {
            f.write_all(table.as_bytes())
        })?;
    }
    Ok((renders, Some(result)))
}

/// The scores of `request`, read from `path` where an earlier run wrote them.
fn cached(path: &Path, request: &EvalRequest) -> Result<EvalResult, Error> {
    if path.exists() {
        return Ok(read_json_as(path)?);
    }
    let progress = bar(0, "images");
    let result = evaluate_run(request, &progress)?;
    progress.finish_and_clear();
    if let Some(warning) = &result.warning {
        eprintln!("warning: {warning}");
    }
    write_json(path, &result)?;
    Ok(result)
}

/// Stage 5: both models' training curves and the rotation model's distribution on the first
/// real instance (else the first validation render); existing figures are kept.
fn draw_figures(
    figures: &Path,
    data: &Path,
    model: &Path,
    plan: &Plan,
    object: &str,
    real: Option<&RealSplit>,
) -> Result<(), Error> {
    for (name, dir) in [
        ("rotation_curves", model.to_path_buf()),
        ("translation_curves", model.join(TRANSLATION_DIR)),
    ] {
        write_figure(&figures.join(format!("{name}.png")), || {
            let log = dir.join(TRAIN_LOG);
            let text = std::fs::read_to_string(&log)
                .map_err(|e| bop_dataset::FileError::new(&log, "file", e.to_string()))?;
            plot_training_curves(&text, &log)
        })?;
    }
    let (name, dataset, split, obj_id) = match real {
        Some(real) => (
            "real",
            real.dataset.as_path(),
            real.split.as_str(),
            real.obj_id,
        ),
        None => ("renders", data, "val", 1),
    };
    let path = figures.join(format!("distribution_{name}.png"));
    if path.exists() {
        return Ok(());
    }
    let rotation = ImplicitPdf::load_ensemble(model, default_device())?;
    let title = format!("{object}: its Pseudo model on the first {name} instance");
    let level = plan.eval_level.min(3);
    let dataset = BopDataset::new(dataset);
    if let Some(figure) =
        first_instance_figure(&rotation, &dataset, split, obj_id, level, VIEWS, &title)?
    {
        write_png(&path, &figure)?;
    }
    Ok(())
}

impl MeshReport {
    /// The report as Markdown: the settings, the labels' accuracy, the scores on renders and
    /// on the real split (each instance's), the time per stage.
    pub fn to_markdown(&self) -> String {
        let c = &self.config;
        let mut out = self.settings_markdown();
        let against = if c.real.is_some() {
            "against the rendered pose and its symmetries, which the real split's \
             models_info.json gives"
        } else {
            "against the rendered pose alone: the mesh's symmetries are not known here, so a \
             symmetric object's other poses count as errors"
        };
        out += &format!(
            "Pseudo labels of the training renders: a label within 5° of the truth for {:.0}% \
             of the instances; {:.1}° from a label to the truth on average ({against}).\n\n",
            100.0 * self.labels.coverage,
            self.labels.label_maad_deg
        );
        let r = &self.renders;
        out += &format!(
            "On {} validation renders (grid level {}): LLH {:.2}, MAAD {:.1}°, Recall MAAD \
             {:.1}°",
            r.images, r.level, r.llh, r.maad_deg, r.recall_maad_deg
        );
        if let Some(a) = &r.accuracy {
            out += &format!(
                ", Acc@15° {:.0}%, median rotation error {:.1}°",
                100.0 * a.acc_15,
                a.median_rotation_error_deg
            );
        }
        if let Some(t) = &r.translation {
            out += &format!(", translation error median {:.1} mm", t.median_error_mm);
        }
        if let Some(t) = r
            .accuracy
            .as_ref()
            .and_then(|a| a.median_fitted_translation_error_mm)
        {
            out += &format!(" ({t:.1} mm fitted to the renders' depth)");
        }
        out += &format!(" ({against}).\n\n");
        if let Some(real) = &self.real
            && let Some(accuracy) = &real.accuracy
        {
            out += &markdown("Real frames", &real.instances, accuracy);
            out += "\n";
        }
        if let Some(warning) = self.real.as_ref().and_then(|real| real.warning.as_ref()) {
            out += &format!("Warning: {warning}.\n\n");
        }
        out += "\nSeconds per stage:";
        for (stage, seconds) in &self.timing_s {
            out += &format!(" {stage} {seconds:.0},");
        }
        out.pop();
        out += ".\n";
        out
    }

    /// The report's heading and the run's settings, as a paragraph.
    fn settings_markdown(&self) -> String {
        let c = &self.config;
        let p = &c.plan;
        format!(
            "# {}: a pose model from its mesh\n\n{} preset, seed {}: {} training and {} \
             validation renders of `{}` (randomised: {}; {}), {}{}{} on {}-pixel crops, {} \
             epochs of {} steps of {} (translation {} epochs), occlusion{}.\n\n",
            self.object,
            p.preset.name(),
            c.seed,
            p.frames,
            p.val_frames,
            c.mesh.display(),
            if c.randomize.is_empty() {
                "nothing".to_string()
            } else {
                c.randomize.join(", ")
            },
            p.sensor
                .map_or("clean depth".to_string(), |s| format!("{} depth", s.name())),
            p.encoder.name(),
            match &p.pretrained {
                Some(path) if p.frozen_blocks > 0 => format!(
                    " from `{}` ({} blocks frozen)",
                    path.display(),
                    p.frozen_blocks
                ),
                Some(path) => format!(" from `{}`", path.display()),
                None => String::new(),
            },
            match (p.rotation_members, p.translation_encoder) {
                (1, None) => String::new(),
                (1, Some(t)) => format!(" (translation: {})", t.name()),
                (k, None) => format!(" (rotation: an ensemble of {k})"),
                (k, Some(t)) =>
                    format!(" (rotation: an ensemble of {k}; translation: {})", t.name()),
            },
            p.input_size,
            p.epochs,
            p.steps_per_epoch,
            p.batch_size,
            p.translation_epochs,
            if p.blur > 0.0 {
                format!(" and blur up to σ = {} px", p.blur)
            } else {
                String::new()
            },
        )
    }
}
