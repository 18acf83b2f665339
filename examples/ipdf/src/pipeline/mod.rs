//! `ipdf pipeline`: the whole method on synthetic data, as one resumable run: synthesise the
//! uniform and textured datasets → pseudo-label them → train Single, Analytical and Pseudo
//! models per object on the uniform one (Analytical and Pseudo with a translation model too:
//! a 6D pose) → evaluate on its validation split → `report.md` /
//! `report.json` with the paper's tables filled by measured numbers, and figures. Each stage
//! calls the libraries with typed options, and is skipped when its outputs exist. The run's
//! settings are recorded in `pipeline_config.json` when it starts, and a rerun into the same
//! folder with other settings is refused.
pub(crate) mod config;
mod mesh;
mod report;
mod workers;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use bop_dataset::{
    BopDataset, read_json_as, read_models_info, read_scene_camera, read_scene_gt, write_atomically,
    write_json,
};
use depth_render::SensorPreset;
use ipdf_model::rotation::ImplicitPdf;
use ipdf_model::translation::TranslationPdf;
use ipdf_model::{ModelConfig, TRAIN_LOG, default_device};
use pseudo_label::{DatasetOptions, LabelOptions, LabelReport, Shard, label_dataset};
use serde::{Deserialize, Serialize};
use synth_data::{ObjectKind, SynthObject, SynthOptions, Variant, synthesize};

pub use config::{CONFIG_FILE, PRETRAINED_WEIGHTS, PipelineConfig, Plan, Preset};
pub use mesh::{MeshConfig, MeshReport, MeshRequest, RealSplit, run_mesh_pipeline};
pub use report::{FigureEntry, LabelAccuracy, ModelScores, Report, ScoreTable};
pub use workers::on_threads;

use crate::Error;
use crate::eval::rotation::{crop_turn, distribution_figure};
use crate::eval::translation::predict_translation;
use crate::eval::{EvalRequest, EvalResult, eval_file, evaluate_run};
use crate::plots::{plot_label_errors, plot_training_curves, plot_translation, write_png};
use crate::progress::bar;
use crate::run_info::RunInfo;
use crate::training::{
    TRANSLATION_DIR, Target, TrainRequest, ensemble_requests, is_trained, name_members, train_model,
};
use crate::training_data::{
    CropSource, ExampleOptions, LabelSource, crop_files, intrinsics_of, load_examples,
    to_unit_floats,
};

/// The objects of the run.
const OBJECTS: [ObjectKind; 3] = [ObjectKind::Can, ObjectKind::Box, ObjectKind::Bowl];

/// What `ipdf pipeline` prints: where the report and figures are, and the time per stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PipelineSummary {
    /// `report.md`.
    pub report: PathBuf,
    /// `report.json`.
    pub report_json: PathBuf,
    /// The figures' folder.
    pub figures: PathBuf,
    /// Seconds per stage of this invocation.
    pub timing_s: BTreeMap<String, f64>,
}

/// Validation crops per epoch of the pipeline's translation models.
const TRANSLATION_VALIDATION: usize = 16;

/// One trained model of the run: a rotation model in `dir`, with a translation model in
/// `dir/translation` where `pose`: the Analytical and Pseudo runs of the main encoder. Single
/// label sets hold the same translations as Analytical ones (the objects' symmetries keep
/// their origin in place), so their translation model would be the Analytical one: measured,
/// the two were bit-identical.
#[derive(Debug, Clone, PartialEq)]
struct ModelRun {
    object: ObjectKind,
    labels: LabelSource,
    occlusion: bool,
    encoder: ipdf_model::EncoderKind,
    pose: bool,
    dir: PathBuf,
}

impl ModelRun {
    /// The folder of its model of `target` (rotation or translation).
    fn dir_of(&self, target: Target) -> PathBuf {
        match target {
            Target::Translation => self.dir.join(TRANSLATION_DIR),
            _ => self.dir.clone(),
        }
    }

    /// The models it trains.
    fn targets(&self) -> &'static [Target] {
        if self.pose {
            &[Target::Rotation, Target::Translation]
        } else {
            &[Target::Rotation]
        }
    }
}

/// Runs (or resumes) the pipeline of `plan` into `out`.
pub fn run_pipeline(out: &Path, plan: &Plan, seed: u64) -> Result<PipelineSummary, Error> {
    config::check_and_record(out, &plan.config(seed))?;
    let mut stages = StageTimes::of(out)?;
    stages.run("synth", || synthesize_datasets(out, plan, seed))?;
    let labels = stages.run("label", || label_datasets(out, plan, seed))?;
    let runs = model_runs(out, plan);
    stages.run("train", || train_models(out, plan, &runs, seed))?;
    let scores = stages.run("eval", || evaluate_models(plan, &runs))?;
    let figures = stages.run("figures", || draw_figures(out, plan, &runs))?;

    let report = report_of(plan, &runs, &scores, labels, stages.seconds, seed);
    let text = report.to_markdown(&figures);
    write_report(out, &report, &text, report.timing_s.clone())
}

/// The run folder's seconds per stage, summed over the invocations that ran it: a resumed
/// run adds what it spends to what the earlier ones spent, so `timing_s` is the run's cost
/// however often it was stopped (a stage stopped halfway counts from its next invocation).
pub const TIMING_FILE: &str = "timing.json";

/// Seconds per stage of a run folder ([`TIMING_FILE`]).
#[derive(Debug)]
struct StageTimes {
    path: PathBuf,
    seconds: BTreeMap<String, f64>,
}

impl StageTimes {
    /// The stage times `out` holds so far (none in a new folder).
    fn of(out: &Path) -> Result<Self, Error> {
        let path = out.join(TIMING_FILE);
        let seconds = if path.exists() {
            read_json_as(&path)?
        } else {
            BTreeMap::new()
        };
        Ok(Self { path, seconds })
    }

    /// Runs the stage `name`, adding how long it took to the folder's record, and printing it.
    fn run<T>(&mut self, name: &str, stage: impl FnOnce() -> Result<T, Error>) -> Result<T, Error> {
        let started = Instant::now();
        let result = stage()?;
        let seconds = started.elapsed().as_secs_f64();
        *self.seconds.entry(name.to_string()).or_default() += seconds;
        write_json(&self.path, &self.seconds)?;
        eprintln!("pipeline: {name} done in {seconds:.0} s");
        Ok(result)
    }
}

/// Writes a run's `report.json` (`report`) and `report.md` (`markdown`) into `out`; returns
/// where they and the figures are.
fn write_report(
    out: &Path,
    report: &impl Serialize,
    markdown: &str,
    timing_s: BTreeMap<String, f64>,
) -> Result<PipelineSummary, Error> {
    let summary = PipelineSummary {
        report: out.join("report.md"),
        report_json: out.join("report.json"),
        figures: out.join("figures"),
        timing_s,
    };
    write_json(&summary.report_json, report)?;
    write_atomically(&summary.report, |f| f.write_all(markdown.as_bytes()))?;
    eprintln!(
        "pipeline: report {} and {}, figures in {}",
        summary.report.display(),
        summary.report_json.display(),
        summary.figures.display()
    );
    Ok(summary)
}

/// The dataset folder of `variant`.
fn data_dir(out: &Path, variant: Variant) -> PathBuf {
    out.join("data").join(variant.name())
}

/// Stage 1, datasets: the uniform one to train and validate on, the textured one (training
/// split) for the accuracy of its pseudo labels, with the plan's sensor's depth. Complete
/// scenes are skipped.
fn synthesize_datasets(out: &Path, plan: &Plan, seed: u64) -> Result<(), Error> {
    let splits = [
        (Variant::Uniform, "train", plan.frames, seed),
        (Variant::Uniform, "val", plan.val_frames, seed + 1),
        (Variant::Texture, "train", plan.texture_frames, seed),
    ];
    for (variant, split, frames, split_seed) in splits {
        let objects = OBJECTS
            .into_iter()
            .map(SynthObject::built_in)
            .collect::<Result<Vec<_>, _>>()?;
        let options = SynthOptions {
            frames,
            variant,
            seed: split_seed,
            sensor: plan.sensor.map(SensorPreset::sensor),
            ..SynthOptions::default()
        };
        let progress = bar((frames * objects.len()) as u64, "frames");
        let dataset = BopDataset::new(&data_dir(out, variant));
        synthesize(&dataset, split, &objects, &options, &progress)?;
        progress.finish_and_clear();
    }
    Ok(())
}

/// Stage 2, pseudo labels of the training splits, scores in the plan's sensor's expected errors
/// (the Kinect's for clean depth), scored against the ground truth (`labels_{variant}.json`,
/// kept: a rerun reads them back).
fn label_datasets(
    out: &Path,
    plan: &Plan,
    seed: u64,
) -> Result<BTreeMap<String, BTreeMap<String, LabelAccuracy>>, Error> {
    let mut accuracy: BTreeMap<String, BTreeMap<String, LabelAccuracy>> = BTreeMap::new();
    for variant in Variant::ALL {
        let path = out.join(format!("labels_{}.json", variant.name()));
        if !path.exists() {
            label_split(&data_dir(out, variant), plan, seed)?;
            score_labels(&data_dir(out, variant), variant.name())?.write(&path)?;
        }
        let report: LabelReport = read_json_as(&path)?;
        for (object, scores) in report.objects {
            accuracy.entry(object).or_default().insert(
                variant.name().into(),
                LabelAccuracy {
                    label_maad_deg: scores.label_maad_deg,
                    coverage: scores.coverage,
                },
            );
        }
    }
    Ok(accuracy)
}

/// Pseudo-labels the training split of the dataset in `data` (its scenes not labelled yet),
/// with scores in the plan's sensor's expected errors (the Kinect's for clean depth).
fn label_split(data: &Path, plan: &Plan, seed: u64) -> Result<(), Error> {
    let dataset = BopDataset::open(data, "models")?;
    let dataset_options = DatasetOptions {
        split: "train".into(),
        mesh_scale: 1e-3,
        obj_id: None,
        shard: Shard::ALL,
        relabel: false,
    };
    let options = LabelOptions {
        seed,
        sensor: plan.depth_sensor(),
        appearance_margin: plan.appearance_margin,
        ..LabelOptions::default()
    };
    let progress = bar(dataset.image_count("train")? as u64, "images");
    label_dataset(&dataset, &dataset_options, &options, &progress)?;
    progress.finish_and_clear();
    Ok(())
}

/// The pseudo labels of the training split of the dataset in `data` scored against its ground
/// truth (the per-label errors included, which `labels_{variant}.json` does not keep).
fn score_labels(data: &Path, variant: &str) -> Result<LabelReport, Error> {
    let dataset = BopDataset::open(data, "models")?;
    let names = dataset.read_info()?.unwrap_or_default().names;
    Ok(pseudo_label::report(&dataset, "train", &names, variant)?)
}

/// Stage 3, the models: per object, Single, Analytical and Pseudo labels (with and without
/// occlusion in the paper preset), the Analytical and Pseudo ones with a translation model
/// too, and the pseudo-label rotation models of other backbones.
fn model_runs(out: &Path, plan: &Plan) -> Vec<ModelRun> {
    let mut runs = Vec::new();
    for object in OBJECTS {
        for &occlusion in &plan.occlusion {
            for labels in [
                LabelSource::Single,
                LabelSource::Analytical,
                LabelSource::Pseudo,
            ] {
                runs.push((object, labels, occlusion, plan.encoder));
            }
        }
        for &encoder in &plan.backbones {
            runs.push((object, LabelSource::Pseudo, false, encoder));
        }
    }
    runs.into_iter()
        .map(|(object, labels, occlusion, encoder)| {
            let occluded = if occlusion { "_occlusion" } else { "" };
            let backbone = if encoder == plan.encoder {
                String::new()
            } else {
                format!("_{}", encoder.name())
            };
            let name = format!("{}{occluded}{backbone}", labels.name());
            ModelRun {
                object,
                labels,
                occlusion,
                encoder,
                pose: encoder == plan.encoder && labels != LabelSource::Single,
                dir: out.join("models").join(object.name()).join(name),
            }
        })
        .collect()
}

/// Stage 3: trains the models not trained yet (each member of a rotation model's ensemble),
/// `plan.concurrent_models` at a time, those of the most steps first.
fn train_models(out: &Path, plan: &Plan, runs: &[ModelRun], seed: u64) -> Result<(), Error> {
    let data = data_dir(out, Variant::Uniform);
    let mut pending = Vec::new();
    for run in runs {
        for &target in run.targets() {
            let request = TrainRequest {
                object_name: Some(run.object.name().into()),
                labels: run.labels,
                model: ModelConfig {
                    encoder: run.encoder,
                    ..train_request(plan, &data, target, seed).model
                },
                occlusion: run.occlusion,
                out: run.dir_of(target),
                ..train_request(plan, &data, target, seed)
            };
            for member in ensemble_requests(&request, plan.members_of(target))? {
                if !is_trained(&member.out, plan.total_steps(target))? {
                    pending.push((run, member));
                }
            }
        }
    }
    // The longest first, so that the last ones to finish are short: the demo's translation
    // models take half a rotation model's steps.
    pending.sort_by_key(|(_, request)| std::cmp::Reverse(plan.total_steps(request.target)));
    on_threads(&pending, plan.concurrent_models, |(run, request)| {
        eprintln!(
            "pipeline: training {}'s {} on {} labels{}",
            run.object.name(),
            request.target.name(),
            run.labels.name(),
            if run.occlusion { " with occlusion" } else { "" }
        );
        let progress = bar(plan.total_steps(request.target), "steps");
        train_model(request, &progress)?;
        progress.finish_and_clear();
        Ok(())
    })?;
    for run in runs {
        if run.targets().contains(&Target::Rotation) {
            name_members(&run.dir_of(Target::Rotation), plan.rotation_members)?;
        }
    }
    Ok(())
}

/// How the plan trains a model of `target` on the `train` split of the dataset in `data`,
/// validated on its `val` split: the plan's encoder of `target` (with the plan's pretrained
/// weights where it is the plan's encoder), Pseudo labels, the plan's first occlusion
/// setting and its blur, object 1, into `data/model`: callers set what differs.
fn train_request(plan: &Plan, data: &Path, target: Target, seed: u64) -> TrainRequest {
    let encoder = plan.encoder_of(target);
    // The pretrained weights and the freeze are the plan's encoder's.
    let pretrained = encoder == plan.encoder;
    TrainRequest {
        dataset: data.to_path_buf(),
        models_dir: "models".into(),
        split: "train".into(),
        val_split: "val".into(),
        obj_id: None,
        object_name: None,
        labels: LabelSource::Pseudo,
        target,
        model: ModelConfig {
            encoder,
            input_size: plan.input_size as i64,
            head_sizes: plan.head.clone(),
            seed,
            rotation_frame: plan.rotation_frame,
            frozen_blocks: if pretrained { plan.frozen_blocks } else { 0 },
            ..ModelConfig::default()
        },
        epochs: plan.epochs_of(target),
        steps_per_epoch: plan.steps_per_epoch,
        batch_size: plan.batch_size,
        learning_rate: plan.learning_rate_of(target),
        occlusion: plan.occlusion.first().copied().unwrap_or(false),
        blur: plan.blur,
        crop: CropSource::Mask,
        query_level: plan.query_level,
        translation_queries: plan.translation_queries,
        continuous_steps: 36,
        pretrained: plan.pretrained.clone().filter(|_| pretrained),
        // A translation model's validation refines an octree per crop (about 0.6 s per
        // epoch for 50 crops of the quick preset): 16 crops give the curve.
        validation_images: (target == Target::Translation).then_some(TRANSLATION_VALIDATION),
        out: data.join("model"),
        seed,
    }
}

/// Stage 4, scores on the validation split (`eval_levelN.json` per run, kept), the runs not
/// scored yet `plan.concurrent_models` at a time, as in training.
fn evaluate_models(plan: &Plan, runs: &[ModelRun]) -> Result<Vec<EvalResult>, Error> {
    let pending: Vec<&ModelRun> = runs
        .iter()
        .filter(|run| !eval_file(&run.dir, plan.eval_level).exists())
        .collect();
    on_threads(&pending, plan.concurrent_models, |run| {
        let request = EvalRequest::new(run.dir.clone(), "val", plan.eval_level);
        let progress = bar(0, "images");
        write_json(
            &eval_file(&run.dir, plan.eval_level),
            &evaluate_run(&request, &progress)?,
        )?;
        progress.finish_and_clear();
        Ok(())
    })?;
    runs.iter()
        .map(|run| Ok(read_json_as(&eval_file(&run.dir, plan.eval_level))?))
        .collect()
}

/// Stage 5, figures: each model's distribution for the first validation image of its object,
/// and its training curves (existing figures are kept).
fn draw_figures(out: &Path, plan: &Plan, runs: &[ModelRun]) -> Result<Vec<FigureEntry>, Error> {
    let figures = out.join("figures");
    let data = data_dir(out, Variant::Uniform);
    let mut entries = Vec::new();
    for run in runs {
        let stem = run
            .dir
            .strip_prefix(out.join("models"))
            .unwrap_or(&run.dir)
            .to_string_lossy()
            .replace('/', "_");
        write_figure(&figures.join(format!("{stem}.png")), || {
            first_validation_figure(run, &data, plan.eval_level.min(3))
        })?;
        write_figure(&figures.join(format!("{stem}_curves.png")), || {
            let log = run.dir.join(TRAIN_LOG);
            let text = std::fs::read_to_string(&log)
                .map_err(|e| bop_dataset::FileError::new(&log, "file", e.to_string()))?;
            plot_training_curves(&text, &log)
        })?;
        if run.pose {
            write_figure(&figures.join(format!("{stem}_translation.png")), || {
                first_translation_figure(run, &data)
            })?;
        }
        entries.push(FigureEntry {
            object: run.object.name().into(),
            labels: run.labels.name().into(),
            stem,
            translation: run.pose,
        });
    }
    draw_label_errors(out, &figures.join(LABEL_ERRORS_FIGURE))?;
    Ok(entries)
}

/// The figure of the pseudo-label errors of both datasets, per object.
const LABEL_ERRORS_FIGURE: &str = "label_errors.png";

/// Draws [`LABEL_ERRORS_FIGURE`] from the labels and ground truth of the training splits (the
/// report files hold the means only), unless it exists.
fn draw_label_errors(out: &Path, path: &Path) -> Result<(), Error> {
    if path.exists() {
        return Ok(());
    }
    let reports = Variant::ALL
        .into_iter()
        .map(|variant| score_labels(&data_dir(out, variant), variant.name()))
        .collect::<Result<Vec<_>, _>>()?;
    let panels: Vec<(&str, &LabelReport)> = Variant::ALL
        .iter()
        .map(|v| v.name())
        .zip(&reports)
        .collect();
    write_png(path, &plot_label_errors(&panels)?)?;
    Ok(())
}

/// The distribution figure of `run`'s model for the first validation image of its object.
fn first_validation_figure(
    run: &ModelRun,
    data: &Path,
    level: u8,
) -> Result<image::RgbImage, Error> {
    let info = RunInfo::read(&run.dir)?;
    let models = ImplicitPdf::load_ensemble(&run.dir, default_device())?;
    let title = format!(
        "{}, trained on {} labels",
        run.object.name(),
        run.labels.name()
    );
    first_instance_figure(
        &models,
        &BopDataset::new(data),
        "val",
        info.obj_id,
        level,
        0,
        &title,
    )?
    .ok_or_else(|| {
        Error::option(
            "dataset",
            format!("no validation image of {}", run.object.name()),
        )
    })
}

/// The distribution figure of `models` (one model, or an ensemble's members) for the first
/// instance of object `obj_id` in `split` with a visible mask (its image term averaged over
/// `views` test-time views), against its true poses under the symmetries of the dataset's
/// `models_info.json`; `None` where there is none.
fn first_instance_figure(
    models: &[ImplicitPdf],
    dataset: &BopDataset,
    split: &str,
    obj_id: u32,
    level: u8,
    views: usize,
    title: &str,
) -> Result<Option<image::RgbImage>, Error> {
    let infos = read_models_info(&dataset.models_info_path())?;
    let group = infos
        .get(&obj_id)
        .map(|m| m.symmetry.clone())
        .unwrap_or_default();
    for scene_id in dataset.scene_ids(split)? {
        let scene = dataset.scene(split, scene_id);
        for (im_id, instances) in read_scene_gt(&scene.gt_path())? {
            for (k, truth) in instances.iter().enumerate() {
                let mask = scene.mask_visib_path(im_id, k);
                if truth.obj_id != obj_id || !mask.exists() {
                    continue;
                }
                let size = models[0].config().input_size as usize;
                let crop = crop_files(&scene.rgb_path(im_id), &mask, size)?;
                let cameras = read_scene_camera(&scene.camera_path())?;
                let turn = crop_turn(&models[0], &crop, &intrinsics_of(&cameras, &scene, im_id)?);
                let truths = group.expand(&truth.pose.rotation);
                let figure =
                    distribution_figure(models, &crop.pixels, &turn, &truths, level, views, title)?;
                return Ok(Some(figure));
            }
        }
    }
    Ok(None)
}

/// Writes the figure `draw` makes to `path`, unless `path` exists.
fn write_figure(
    path: &Path,
    draw: impl FnOnce() -> Result<image::RgbImage, Error>,
) -> Result<(), Error> {
    if !path.exists() {
        write_png(path, &draw()?)?;
    }
    Ok(())
}

/// The translation distribution of `run`'s translation model for the first validation image of
/// its object, against the ground truth.
fn first_translation_figure(run: &ModelRun, data: &Path) -> Result<image::RgbImage, Error> {
    let dir = run.dir_of(Target::Translation);
    let info = RunInfo::read(&dir)?;
    let model = TranslationPdf::load(&dir, default_device())?;
    let size = model.config().network.input_size as usize;
    let examples = load_examples(
        &BopDataset::new(data),
        &ExampleOptions::evaluation("val", info.obj_id, size),
    )?;
    let (Some(geometry), Some(truth)) = (
        examples.geometry.first(),
        examples.truth_poses.as_ref().and_then(|t| t.first()),
    ) else {
        return Err(Error::option(
            "dataset",
            format!("no validation image of {}", run.object.name()),
        ));
    };
    let crop = to_unit_floats(&examples.crops.get(0));
    let prediction = predict_translation(&model, &crop, geometry)?;
    let title = format!(
        "{}, translation trained on {} labels: offset from the ground truth",
        run.object.name(),
        run.labels.name()
    );
    plot_translation(
        &prediction.centres,
        &prediction.distribution.masses,
        &truth.translation.vector,
        &prediction.argmax.translation,
        &title,
    )
}

/// `report.json` of the run.
fn report_of(
    plan: &Plan,
    runs: &[ModelRun],
    scores: &[EvalResult],
    labels: BTreeMap<String, BTreeMap<String, LabelAccuracy>>,
    timing_s: BTreeMap<String, f64>,
    seed: u64,
) -> Report {
    let mut report = Report {
        labels,
        models: ScoreTable::new(),
        models_occlusion: ScoreTable::new(),
        backbones: ScoreTable::new(),
        timing_s,
        config: plan.config(seed),
        cpu_kernels: ipdf_model::kernel_settings()
            .into_iter()
            .map(|(name, value)| (name.to_string(), value.unwrap_or_else(|| "unset".into())))
            .collect(),
    };
    for (run, result) in runs.iter().zip(scores) {
        let (table, row) = if run.encoder != plan.encoder {
            (&mut report.backbones, run.encoder.name())
        } else if run.occlusion {
            (&mut report.models_occlusion, run.labels.name())
        } else {
            (&mut report.models, run.labels.name())
        };
        let entry = ModelScores {
            llh: result.llh,
            maad_deg: result.maad_deg,
            recall_maad_deg: result.recall_maad_deg,
            images: result.images,
            under_resolution: result.under_resolution,
            translation: result.translation,
            pose: result.pose,
        };
        table
            .entry(row.to_string())
            .or_default()
            .insert(run.object.name().to_string(), entry);
    }
    report
}
