//! `ipdf pipeline`: the whole method on synthetic data, as one resumable run: synthesise the
//! uniform and textured datasets → pseudo-label them → train Single, Analytical and Pseudo
//! models per object on the uniform one → evaluate on its validation split → `report.md` /
//! `report.json` with the paper's tables filled by measured numbers, and figures. Each stage is
//! skipped when its outputs exist. The run's settings are recorded in `pipeline_config.json`
//! when it starts, and a rerun into the same folder with other settings is refused.
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;
use examples::atomic::{write_atomically, write_json};
use examples::bop::read_json;
use examples::dataset::{BopDataset, read_scene_gt};
use examples::evaluation::distribution_figure;
use examples::plots::{plot_training_curves, write_png};
use examples::run_info::RunInfo;
use examples::training_data::crop_files;
use ipdf_model::{CHECKPOINT_FILE, CheckpointInfo, ImplicitPdf, TRAIN_LOG, default_device};
use metrics::{RECALL_THRESHOLD, recall_min_log_density};
use serde_json::{Map, Value, json};
use std::io::Write;

use super::{eval, label, synth, train};

/// A size of run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// Minutes on a laptop CPU: 800 training frames per object, a small CNN on 48-pixel crops.
    Quick,
    /// The paper's scale (GPU advised): 20,000 frames per variant, ResNet-18 on 224-pixel crops,
    /// 50 epochs of 200 steps of 64; with and without occlusion, and two more backbones.
    Paper,
}

/// What a preset runs.
struct Plan {
    /// Training frames per object of the uniform dataset.
    frames: usize,
    /// Validation frames per object of the uniform dataset.
    val_frames: usize,
    /// Frames per object of the textured dataset (labelled, not trained on).
    texture_frames: usize,
    encoder: &'static str,
    input_size: usize,
    head: &'static str,
    epochs: u64,
    steps_per_epoch: u64,
    batch_size: usize,
    learning_rate: f64,
    /// Grid level of the training queries.
    query_level: u8,
    eval_level: u8,
    /// Occlusion settings of the Single/Analytical/Pseudo models.
    occlusion: &'static [bool],
    /// Encoders also trained on pseudo labels (the paper's backbone comparison).
    backbones: &'static [&'static str],
    /// Models trained at once, each on one CPU thread: small models leave a second core
    /// partly idle, so two at a time finish sooner than one on two threads.
    concurrent_models: usize,
}

impl Preset {
    fn plan(self) -> Plan {
        match self {
            Self::Quick => Plan {
                frames: 800,
                val_frames: 50,
                texture_frames: 20,
                encoder: "small-cnn",
                input_size: 48,
                head: "64,64",
                epochs: 32,
                steps_per_epoch: 50,
                batch_size: 16,
                learning_rate: 4e-3,
                query_level: 1,
                eval_level: 4,
                occlusion: &[false],
                backbones: &[],
                concurrent_models: 2,
            },
            Self::Paper => Plan {
                frames: 6667,
                val_frames: 500,
                texture_frames: 6667,
                encoder: "resnet18",
                input_size: 224,
                head: "256,256,256,256",
                epochs: 50,
                steps_per_epoch: 200,
                batch_size: 64,
                learning_rate: 1e-4,
                query_level: 2,
                eval_level: 4,
                occlusion: &[false, true],
                backbones: &["resnet18-2", "convnext-tiny"],
                concurrent_models: 1,
            },
        }
    }
}

/// Arguments of `ipdf pipeline`.
#[derive(Debug, clap::Args)]
pub struct PipelineArgs {
    /// How big a run.
    #[arg(long, value_enum, default_value = "quick")]
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
    /// Override the preset's epochs.
    #[arg(long)]
    pub epochs: Option<u64>,
    /// Override the preset's steps per epoch.
    #[arg(long)]
    pub steps_per_epoch: Option<u64>,
}

const OBJECTS: [&str; 3] = ["can", "box", "bowl"];
const VARIANTS: [&str; 2] = ["uniform", "texture"];
const LABELS: [&str; 3] = ["single", "analytical", "pseudo"];

/// A command's arguments parsed from words, with the command's own defaults.
fn parse<T: clap::Args>(words: &[String]) -> Result<T> {
    #[derive(Parser)]
    struct Wrap<T: clap::Args> {
        #[command(flatten)]
        inner: T,
    }
    let all = std::iter::once("ipdf".to_string()).chain(words.iter().cloned());
    Ok(Wrap::<T>::try_parse_from(all)?.inner)
}

/// Words from string slices and values.
macro_rules! words {
    ($($w:expr),* $(,)?) => { vec![$($w.to_string()),*] };
}

/// One trained model of the run.
struct ModelRun {
    object: &'static str,
    labels: &'static str,
    occlusion: bool,
    encoder: &'static str,
    dir: PathBuf,
}

/// Runs `job` on every item, `workers` at a time on threads of their own, each with one
/// libtorch thread, or more once fewer items are left than workers (`workers` ≤ 1: in turn,
/// libtorch's threads unchanged). Stops taking new items after the first error, which it
/// returns.
fn on_threads<T: Sync>(
    items: &[T],
    workers: usize,
    job: impl Fn(&T) -> Result<()> + Sync,
) -> Result<()> {
    if workers <= 1 {
        return items.iter().try_for_each(job);
    }
    let threads = tch::get_num_threads();
    let next = AtomicUsize::new(0);
    let work = || -> Result<()> {
        loop {
            let index = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(index) else {
                return Ok(());
            };
            let running = (items.len() - index).min(workers) as i32;
            tch::set_num_threads((threads / running).max(1));
            job(item).inspect_err(|_| next.store(items.len(), Ordering::Relaxed))?;
        }
    };
    let outcomes: Vec<Result<()>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers).map(|_| scope.spawn(work)).collect();
        handles
            .into_iter()
            .map(|handle| {
                handle
                    .join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("a training thread panicked")))
            })
            .collect()
    });
    // libtorch's thread count is partly process-wide (MKL's): put it back for what follows.
    tch::set_num_threads(threads);
    outcomes.into_iter().collect()
}

/// Runs `ipdf pipeline`; returns `report.json`.
pub fn run(args: &PipelineArgs, seed: u64) -> Result<Value> {
    let preset = args.preset.plan();
    let plan = Plan {
        frames: args.frames.unwrap_or(preset.frames),
        val_frames: args.val_frames.unwrap_or(preset.val_frames),
        texture_frames: args.texture_frames.unwrap_or(preset.texture_frames),
        epochs: args.epochs.unwrap_or(preset.epochs),
        steps_per_epoch: args.steps_per_epoch.unwrap_or(preset.steps_per_epoch),
        ..preset
    };
    let out = &args.out;
    std::fs::create_dir_all(out)?;
    let config = run_config(&plan, args.preset, seed);
    check_run_config(out, &config)?;
    write_json(&out.join(CONFIG_FILE), &config)?;
    let mut timing = Map::new();
    let mut stage = |name: &str, started: Instant| {
        timing.insert(name.to_string(), json!(started.elapsed().as_secs_f64()));
        eprintln!(
            "pipeline: {name} done in {:.0} s",
            started.elapsed().as_secs_f64()
        );
    };

    // 1. Datasets: the uniform one to train and validate on, the textured one (training split)
    // for the accuracy of its pseudo labels.
    let started = Instant::now();
    let splits = [
        ("uniform", "train", plan.frames, seed),
        ("uniform", "val", plan.val_frames, seed + 1),
        ("texture", "train", plan.texture_frames, seed),
    ];
    for (variant, split, frames, split_seed) in splits {
        let data = out.join("data").join(variant);
        let words = words![
            "--out",
            data.display(),
            "--variant",
            variant,
            "--frames",
            frames,
            "--split",
            split,
            "--frames-per-scene",
            1000
        ];
        synth::run(&parse(&words)?, split_seed)?;
    }
    stage("synth", started);

    // 2. Pseudo labels of the training splits, scored against the ground truth.
    let started = Instant::now();
    let mut label_scores = Map::new();
    for variant in VARIANTS {
        let data = out.join("data").join(variant);
        let report = out.join(format!("labels_{variant}.json"));
        if !report.exists() {
            let words = words!["--dataset", data.display(), "--report", report.display()];
            label::run(&parse(&words)?, seed)?;
        }
        let scores = read_json(&report)?;
        for (object, entry) in scores["objects"].as_object().into_iter().flatten() {
            let slot = label_scores
                .entry(object.clone())
                .or_insert_with(|| json!({}));
            slot[variant] =
                json!({"label_maad_deg": entry["label_maad_deg"], "coverage": entry["coverage"]});
        }
    }
    stage("label", started);

    // 3. Models: per object, Single, Analytical and Pseudo labels (with and without occlusion
    // in the paper preset), and the pseudo-label models of other backbones.
    let mut runs = Vec::new();
    for object in OBJECTS {
        for &occlusion in plan.occlusion {
            for labels in LABELS {
                runs.push((object, labels, occlusion, plan.encoder));
            }
        }
        for &encoder in plan.backbones {
            runs.push((object, "pseudo", false, encoder));
        }
    }
    let runs: Vec<ModelRun> = runs
        .into_iter()
        .map(|(object, labels, occlusion, encoder)| {
            let name = format!(
                "{labels}{}{}",
                if occlusion { "_occlusion" } else { "" },
                if encoder == plan.encoder {
                    String::new()
                } else {
                    format!("_{encoder}")
                }
            );
            ModelRun {
                object,
                labels,
                occlusion,
                encoder,
                dir: out.join("models").join(object).join(name),
            }
        })
        .collect();
    let started = Instant::now();
    let data = out.join("data").join("uniform");
    let total = plan.epochs * plan.steps_per_epoch;
    let mut pending = Vec::new();
    for run in &runs {
        if !(run.dir.join(CHECKPOINT_FILE).exists()
            && CheckpointInfo::read(&run.dir)?.step >= total)
        {
            pending.push(run);
        }
    }
    on_threads(&pending, plan.concurrent_models, |run| {
        let mut words = words![
            "--dataset",
            data.display(),
            "--labels",
            run.labels,
            "--object",
            run.object,
            "--out",
            run.dir.display(),
            "--encoder",
            run.encoder,
            "--input-size",
            plan.input_size,
            "--head",
            plan.head,
            "--epochs",
            plan.epochs,
            "--steps-per-epoch",
            plan.steps_per_epoch,
            "--batch-size",
            plan.batch_size,
            "--learning-rate",
            plan.learning_rate,
            "--query-level",
            plan.query_level,
        ];
        if run.occlusion {
            words.push("--occlusion".into());
        }
        eprintln!(
            "pipeline: training {} on {} labels{}",
            run.object,
            run.labels,
            if run.occlusion { " with occlusion" } else { "" }
        );
        train::run(&parse(&words)?, seed).map(drop)
    })?;
    stage("train", started);

    // 4. Scores on the validation split.
    let started = Instant::now();
    let mut evaluations = Vec::new();
    for run in &runs {
        let path = run.dir.join(format!("eval_level{}.json", plan.eval_level));
        if !path.exists() {
            let words = words![
                "--checkpoint",
                run.dir.display(),
                "--level",
                plan.eval_level,
                "--out",
                path.display()
            ];
            eval::run(&parse(&words)?)?;
        }
        evaluations.push(read_json(&path)?);
    }
    stage("eval", started);

    // 5. Figures: each model's distribution for the first validation image of its object, and
    // its training curves.
    let started = Instant::now();
    let figures = out.join("figures");
    let mut figure_names = Vec::new();
    for run in &runs {
        let stem = run
            .dir
            .strip_prefix(out.join("models"))
            .unwrap_or(&run.dir)
            .to_string_lossy()
            .replace('/', "_");
        let distribution = figures.join(format!("{stem}.png"));
        let curves = figures.join(format!("{stem}_curves.png"));
        if !distribution.exists() {
            write_png(
                &distribution,
                &first_validation_figure(run, &data, plan.eval_level.min(3))?,
            )?;
        }
        if !curves.exists() {
            let log = run.dir.join(TRAIN_LOG);
            let text = std::fs::read_to_string(&log)
                .with_context(|| format!("reading {}", log.display()))?;
            write_png(&curves, &plot_training_curves(&text, &log)?)?;
        }
        figure_names.push((run, stem));
    }
    stage("figures", started);

    let report = report_json(
        &plan,
        args.preset,
        &runs,
        &evaluations,
        label_scores,
        timing,
        seed,
    );
    write_json(&out.join("report.json"), &report)?;
    let markdown = out.join("report.md");
    let text = report_markdown(&report, &figure_names);
    write_atomically(&markdown, |f| Ok(f.write_all(text.as_bytes())?))?;
    eprintln!(
        "pipeline: report {} and {}, figures in {}",
        markdown.display(),
        out.join("report.json").display(),
        figures.display()
    );
    Ok(
        json!({"report": markdown, "report_json": out.join("report.json"), "figures": figures, "timing_s": report["timing_s"]}),
    )
}

/// The file in the run folder recording the settings the run was started with.
const CONFIG_FILE: &str = "pipeline_config.json";

/// The settings that decide a run's outputs, as `pipeline_config.json` and the `"config"` of
/// `report.json` hold them. Numbers pass through JSON text once, so that they compare equal to
/// what a file read back holds.
fn run_config(plan: &Plan, preset: Preset, seed: u64) -> Value {
    let value = json!({
        "preset": format!("{preset:?}").to_lowercase(), "seed": seed,
        "frames_per_object": plan.frames, "val_frames_per_object": plan.val_frames,
        "texture_frames_per_object": plan.texture_frames,
        "encoder": plan.encoder, "input_size": plan.input_size, "head": plan.head,
        "epochs": plan.epochs, "steps_per_epoch": plan.steps_per_epoch, "batch_size": plan.batch_size,
        "learning_rate": plan.learning_rate, "query_level": plan.query_level,
        "eval_level": plan.eval_level, "occlusion": plan.occlusion, "backbones": plan.backbones,
        "training_data": "uniform",
    });
    serde_json::from_str(&value.to_string()).unwrap_or(value)
}

/// The keys of [`run_config`] set by command-line flags, and the flags.
const FLAGS: [(&str, &str); 7] = [
    ("preset", "--preset"),
    ("seed", "--seed"),
    ("frames_per_object", "--frames"),
    ("val_frames_per_object", "--val-frames"),
    ("texture_frames_per_object", "--texture-frames"),
    ("epochs", "--epochs"),
    ("steps_per_epoch", "--steps-per-epoch"),
];

/// The command-line flag that sets a key of [`run_config`], for error messages.
fn flag_of(key: &str) -> String {
    let flag = FLAGS
        .iter()
        .find(|f| f.0 == key)
        .map_or("set by --preset", |f| f.1);
    format!(" ({flag})")
}

/// Refuses a run folder whose recorded settings differ from `config`, naming the first that
/// does: `pipeline_config.json`, or for a folder from an older version without one, the
/// `"config"` of its `report.json`. A folder with neither is a new run.
fn check_run_config(out: &Path, config: &Value) -> Result<()> {
    let config_path = out.join(CONFIG_FILE);
    let report_path = out.join("report.json");
    let (path, recorded) = if config_path.exists() {
        (&config_path, read_json(&config_path)?)
    } else if report_path.exists() {
        (&report_path, read_json(&report_path)?["config"].clone())
    } else {
        return Ok(());
    };
    let (Some(recorded), Some(config)) = (recorded.as_object(), config.as_object()) else {
        anyhow::bail!("{}: config: not a JSON object", path.display());
    };
    // The settings given on the command line first, so that the one named is the one changed.
    let first = FLAGS.iter().map(|&(key, _)| key);
    let rest = config
        .keys()
        .map(String::as_str)
        .filter(|key| !FLAGS.iter().any(|f| f.0 == *key));
    for key in first.chain(rest) {
        let Some(value) = config.get(key) else {
            continue;
        };
        // Keys an older report.json lacks are not compared.
        let Some(found) = recorded
            .get(key)
            .or((path == &config_path).then_some(&Value::Null))
        else {
            continue;
        };
        if found != value {
            anyhow::bail!(
                "{}: {key}{}: the run in {} was made with {found}, this run asks for {value}; \
                 rerun with the same settings to resume it, or choose another --out",
                path.display(),
                flag_of(key),
                out.display()
            );
        }
    }
    Ok(())
}

/// The distribution figure of `run`'s model for the first validation image of its object.
fn first_validation_figure(run: &ModelRun, data: &Path, level: u8) -> Result<image::RgbImage> {
    let info = RunInfo::read(&run.dir)?;
    let model = ImplicitPdf::load(&run.dir, default_device())?;
    let dataset = BopDataset::new(data);
    let models = examples::dataset::read_models_info(&dataset.models_info_path())?;
    for scene_id in dataset.scene_ids("val")? {
        let scene = dataset.scene("val", scene_id);
        for (im_id, instances) in read_scene_gt(&scene.gt_path())? {
            let Some((k, truth)) = instances
                .iter()
                .enumerate()
                .find(|(_, t)| t.obj_id == info.obj_id)
            else {
                continue;
            };
            let crop = crop_files(
                &scene.rgb_path(im_id),
                &scene.mask_visib_path(im_id, k),
                model.config().input_size as usize,
            )?;
            let group = models
                .get(&info.obj_id)
                .map(|m| m.symmetry.clone())
                .unwrap_or_default();
            let title = format!("{} {} LABELS", run.object, run.labels);
            return Ok(distribution_figure(
                &model,
                &crop,
                &group.expand(&truth.pose.rotation),
                level,
                &title,
            )?);
        }
    }
    anyhow::bail!("no validation image of {}", run.object)
}

/// `report.json`: `{"labels": {object: {variant: {"label_maad_deg", "coverage"}}},
/// "models": {labels: {object: {"llh", "maad_deg", "recall_maad_deg"}}}, "models_occlusion",
/// "backbones": {encoder: {object: …}}, "timing_s", "config"}`.
fn report_json(
    plan: &Plan,
    preset: Preset,
    runs: &[ModelRun],
    evaluations: &[Value],
    labels: Map<String, Value>,
    timing: Map<String, Value>,
    seed: u64,
) -> Value {
    let mut models = json!({});
    let mut occluded = json!({});
    let mut backbones = json!({});
    for (run, scores) in runs.iter().zip(evaluations) {
        let entry = json!({"llh": scores["llh"], "maad_deg": scores["maad_deg"], "recall_maad_deg": scores["recall_maad_deg"], "images": scores["images"]});
        let table = if run.encoder != plan.encoder {
            backbones
                .as_object_mut()
                .expect("object")
                .entry(run.encoder)
                .or_insert_with(|| json!({}))
        } else if run.occlusion {
            occluded
                .as_object_mut()
                .expect("object")
                .entry(run.labels)
                .or_insert_with(|| json!({}))
        } else {
            models
                .as_object_mut()
                .expect("object")
                .entry(run.labels)
                .or_insert_with(|| json!({}))
        };
        table[run.object] = entry;
    }
    json!({
        "labels": labels,
        "models": models,
        "models_occlusion": occluded,
        "backbones": backbones,
        "timing_s": timing,
        "config": run_config(plan, preset, seed),
    })
}

/// The paper's figures for comparison: (LLH, MAAD, Recall MAAD) of its Pseudo models, on
/// average over the objects, without and with occlusion.
const PAPER_PSEUDO: [(f64, f64, f64); 2] = [(3.79, 6.26, 2.18), (3.70, 7.72, 2.17)];

fn number(value: &Value, digits: usize) -> String {
    value
        .as_f64()
        .map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// A table of models by label type and object.
fn model_table(text: &mut String, models: &Value, rows: &[&str]) {
    text.push_str(
        "| labels | object | LLH ↑ | MAAD (°) ↓ | Recall MAAD (°) ↓ |\n|---|---|---|---|---|\n",
    );
    for &row in rows {
        let Some(objects) = models[row].as_object() else {
            continue;
        };
        for (object, s) in objects {
            text.push_str(&format!(
                "| {row} | {object} | {} | {} | {} |\n",
                number(&s["llh"], 2),
                number(&s["maad_deg"], 1),
                number(&s["recall_maad_deg"], 1)
            ));
        }
        let mean = |key: &str| {
            objects
                .values()
                .filter_map(|s| s[key].as_f64())
                .sum::<f64>()
                / objects.len().max(1) as f64
        };
        text.push_str(&format!(
            "| {row} | **average** | {:.2} | {:.1} | {:.1} |\n",
            mean("llh"),
            mean("maad_deg"),
            mean("recall_maad_deg")
        ));
    }
}

/// `report.md`: the same numbers as tables for people, and the figures.
fn report_markdown(report: &Value, figures: &[(&ModelRun, String)]) -> String {
    let config = &report["config"];
    let mut text = format!(
        "# ipdf-rs pipeline report ({} preset)\n\nTrained on the uniform-colour dataset ({} training and {} validation frames per object); \
         encoder {} on {} px crops, {} epochs × {} steps × {} images; scored on the validation split on the level-{} grid \
         (level 2 refined hierarchically; LLH at the ground-truth rotations themselves) against each instance's full ground-truth symmetry set.\n\n## Results by type of ground truth and object\n\n",
        config["preset"].as_str().unwrap_or(""),
        config["frames_per_object"],
        config["val_frames_per_object"],
        config["encoder"].as_str().unwrap_or(""),
        config["input_size"],
        config["epochs"],
        config["steps_per_epoch"],
        config["batch_size"],
        config["eval_level"]
    );
    model_table(&mut text, &report["models"], &LABELS);
    text.push_str(&format!(
        "\nThe paper's Pseudo models, averaged over can, box and bowl: LLH {}, MAAD {}°, Recall MAAD {}° \
         (with occlusion: {}, {}°, {}°).\n",
        PAPER_PSEUDO[0].0, PAPER_PSEUDO[0].1, PAPER_PSEUDO[0].2, PAPER_PSEUDO[1].0, PAPER_PSEUDO[1].1, PAPER_PSEUDO[1].2
    ));
    text.push_str(&format!(
        "\nRecall MAAD predicts a rotation where its cell's log density is at least {:.2} \
         (mass {RECALL_THRESHOLD} per level-4 cell, {:.0}× the uniform density): it reaches a \
         few degrees only where the model is about that sharp along the whole symmetry set.\n",
        recall_min_log_density(RECALL_THRESHOLD),
        (recall_min_log_density(RECALL_THRESHOLD) + std::f64::consts::PI.powi(2).ln()).exp()
    ));
    if report["models_occlusion"]
        .as_object()
        .is_some_and(|o| !o.is_empty())
    {
        text.push_str("\n## With occlusion augmentation\n\n");
        model_table(&mut text, &report["models_occlusion"], &LABELS);
    }
    if let Some(backbones) = report["backbones"].as_object().filter(|b| !b.is_empty()) {
        text.push_str("\n## Backbones (pseudo labels)\n\n");
        let rows: Vec<&str> = backbones.keys().map(String::as_str).collect();
        model_table(&mut text, &report["backbones"], &rows);
    }
    text.push_str("\n## Pseudo-label accuracy\n\nLabel MAAD: mean angle from a label to the nearest ground-truth symmetric pose; \
                   coverage: symmetry classes within 5° of a label (paper: can 1.44°/3.12°, box 4.14°/4.3°, bowl 1.42°/1.89°, Texture/Uniform).\n\n\
                   | object | label MAAD uniform (°) | label MAAD texture (°) | coverage uniform | coverage texture |\n|---|---|---|---|---|\n");
    for (object, entry) in report["labels"].as_object().into_iter().flatten() {
        let coverage = |v: &Value| {
            v.as_f64()
                .map_or("–".into(), |c| format!("{:.1}%", 100.0 * c))
        };
        text.push_str(&format!(
            "| {object} | {} | {} | {} | {} |\n",
            number(&entry["uniform"]["label_maad_deg"], 2),
            number(&entry["texture"]["label_maad_deg"], 2),
            coverage(&entry["uniform"]["coverage"]),
            coverage(&entry["texture"]["coverage"])
        ));
    }
    text.push_str("\n## Figures\n\nEach model's distribution for the first validation image of its object (marker area: probability; \
                   position: direction of the object's x-axis; colour: rotation about it; black: the ground-truth set), and its training curves.\n\n");
    for (run, stem) in figures {
        text.push_str(&format!(
            "- {} / {}: ![distribution](figures/{stem}.png) ![curves](figures/{stem}_curves.png)\n",
            run.object, run.labels
        ));
    }
    text.push_str(
        "\n## Time per stage (seconds)\n\nOf the invocation that wrote this report: a resumed \
         run counts only the work it did.\n\n| stage | seconds |\n|---|---|\n",
    );
    for (name, seconds) in report["timing_s"].as_object().into_iter().flatten() {
        text.push_str(&format!("| {name} | {} |\n", number(seconds, 0)));
    }
    text
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    #[test]
    fn every_item_runs_once_whatever_the_workers() {
        for workers in [1, 2, 3, 8] {
            let done = Mutex::new(Vec::new());
            let items: Vec<usize> = (0..9).collect();
            on_threads(&items, workers, |&i| {
                done.lock().unwrap().push(i);
                Ok(())
            })
            .unwrap();
            let mut done = done.into_inner().unwrap();
            done.sort_unstable();
            assert_eq!(done, items, "{workers} workers");
        }
    }

    #[test]
    fn the_first_error_stops_new_items_and_is_returned() {
        for workers in [1, 2] {
            let started = AtomicUsize::new(0);
            let items: Vec<usize> = (0..50).collect();
            let outcome = on_threads(&items, workers, |&i| {
                started.fetch_add(1, Ordering::Relaxed);
                if i == 3 {
                    anyhow::bail!("item {i} failed");
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
                Ok(())
            });
            assert_eq!(outcome.unwrap_err().to_string(), "item 3 failed");
            // Only items taken before item 3 failed (the others take 20 ms each) were started.
            assert!(started.into_inner() <= 3 + 2 * workers, "{workers} workers");
        }
    }

    #[test]
    fn libtorch_threads_are_put_back() {
        let before = tch::get_num_threads();
        on_threads(&[0, 1, 2], 2, |_| Ok(())).unwrap();
        assert_eq!(tch::get_num_threads(), before);
    }
}
