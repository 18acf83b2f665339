//! `report.json` (for machines) and `report.md` (the same as tables for people).
use std::collections::BTreeMap;

use ipdf_metrics::{RECALL_THRESHOLD, recall_min_log_density};
use serde::{Deserialize, Serialize};

use super::config::PipelineConfig;
use crate::eval::translation::{ADD_S_AUC_FRACTION, PoseEval, TranslationEval};
use crate::training_data::LabelSource;
use ipdf_model::rotation::UNDER_RESOLUTION_LIMIT;

/// The scores of one model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModelScores {
    /// Mean log-likelihood of the ground-truth sets.
    pub llh: f64,
    /// Mean absolute angular deviation (degrees).
    pub maad_deg: f64,
    /// Recall MAAD (degrees).
    pub recall_maad_deg: f64,
    /// Validation crops scored.
    pub images: usize,
    /// How far the evaluation grid is from resolving the model's peaks
    /// ([`ipdf_model::rotation::Predictor::under_resolution`]).
    #[serde(default)]
    pub under_resolution: f64,
    /// The scores of its translation model, when it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<TranslationEval>,
    /// The two models' scores as a 6D pose, when it has a translation model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseEval>,
}

/// Models by row (label type or encoder), then by object.
pub type ScoreTable = BTreeMap<String, BTreeMap<String, ModelScores>>;

/// The accuracy of one dataset variant's pseudo labels of one object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LabelAccuracy {
    /// Mean angle from a label to the nearest ground-truth symmetric pose (degrees).
    pub label_maad_deg: f64,
    /// Fraction of symmetry classes within 5° of a label.
    pub coverage: f64,
}

/// `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Pseudo-label accuracy by object, then by dataset variant (`uniform`, `texture`).
    pub labels: BTreeMap<String, BTreeMap<String, LabelAccuracy>>,
    /// Models by label type (`single`, `analytical`, `pseudo`), then object.
    pub models: ScoreTable,
    /// The same with occlusion augmentation (paper preset).
    pub models_occlusion: ScoreTable,
    /// Pseudo-label models of other encoders, by encoder, then object.
    pub backbones: ScoreTable,
    /// Seconds per stage of the invocation that wrote the report.
    pub timing_s: BTreeMap<String, f64>,
    /// The run's settings.
    pub config: PipelineConfig,
    /// libtorch's CPU kernel settings of the invocation that wrote the report
    /// ([`ipdf_model::REPRODUCIBLE_CPU_KERNELS`]; `unset`: chosen per CPU).
    #[serde(default)]
    pub cpu_kernels: BTreeMap<String, String>,
}

/// One model's figures: `figures/{stem}.png` and `figures/{stem}_curves.png`, and
/// `figures/{stem}_translation.png` for a pose.
#[derive(Debug, Clone, PartialEq)]
pub struct FigureEntry {
    /// The object.
    pub object: String,
    /// The label type.
    pub labels: String,
    /// The figures' file stem.
    pub stem: String,
    /// Whether it has a translation model's figure.
    pub translation: bool,
}

/// The rows of the Single / Analytical / Pseudo tables.
const LABELS: [&str; 3] = [
    LabelSource::Single.name(),
    LabelSource::Analytical.name(),
    LabelSource::Pseudo.name(),
];

/// The paper's figures for comparison: (LLH, MAAD, Recall MAAD) of its Pseudo models, on
/// average over the objects, without and with occlusion.
const PAPER_PSEUDO: [(f64, f64, f64); 2] = [(3.79, 6.26, 2.18), (3.70, 7.72, 2.17)];

/// A table of models by row and object, each row with its average.
fn model_table(text: &mut String, table: &ScoreTable, rows: &[&str]) {
    text.push_str(
        "| labels | object | LLH ↑ | MAAD (°) ↓ | Recall MAAD (°) ↓ |\n|---|---|---|---|---|\n",
    );
    for &row in rows {
        let Some(objects) = table.get(row) else {
            continue;
        };
        for (object, s) in objects {
            text.push_str(&format!(
                "| {row} | {object} | {:.2} | {:.1} | {:.1} |\n",
                s.llh, s.maad_deg, s.recall_maad_deg
            ));
        }
        let mean = |score: fn(&ModelScores) -> f64| {
            objects.values().map(score).sum::<f64>() / objects.len().max(1) as f64
        };
        text.push_str(&format!(
            "| {row} | **average** | {:.2} | {:.1} | {:.1} |\n",
            mean(|s| s.llh),
            mean(|s| s.maad_deg),
            mean(|s| s.recall_maad_deg)
        ));
    }
}

/// The translation and 6D-pose table of the models that have a translation model, each row
/// with its average.
fn pose_table(text: &mut String, table: &ScoreTable, rows: &[&str]) {
    text.push_str(&format!(
        "| labels | object | translation LLH ↑ | median error (mm) ↓ | mean error (mm) ↓ | median depth / lateral error (mm) | joint LLH ↑ | ADD-S AUC (to {:.0}% of the diameter) ↑ |\n|---|---|---|---|---|---|---|---|\n",
        100.0 * ADD_S_AUC_FRACTION
    ));
    for &row in rows {
        let Some(objects) = table.get(row) else {
            continue;
        };
        let poses: Vec<(&String, TranslationEval, PoseEval)> = objects
            .iter()
            .filter_map(|(object, s)| Some((object, s.translation?, s.pose?)))
            .collect();
        for (object, t, p) in &poses {
            text.push_str(&format!(
                "| {row} | {object} | {:.2} | {:.1} | {:.1} | {:.1} / {:.1} | {:.2} | {:.3} |\n",
                t.llh,
                t.median_error_mm,
                t.mean_error_mm,
                t.median_depth_error_mm,
                t.median_lateral_error_mm,
                p.joint_llh,
                p.add_s_auc
            ));
        }
        if poses.is_empty() {
            continue;
        }
        let n = poses.len() as f64;
        let mean = |score: &dyn Fn(&TranslationEval, &PoseEval) -> f64| {
            poses.iter().map(|(_, t, p)| score(t, p)).sum::<f64>() / n
        };
        text.push_str(&format!(
            "| {row} | **average** | {:.2} | {:.1} | {:.1} | {:.1} / {:.1} | {:.2} | {:.3} |\n",
            mean(&|t, _| t.llh),
            mean(&|t, _| t.median_error_mm),
            mean(&|t, _| t.mean_error_mm),
            mean(&|t, _| t.median_depth_error_mm),
            mean(&|t, _| t.median_lateral_error_mm),
            mean(&|_, p| p.joint_llh),
            mean(&|_, p| p.add_s_auc)
        ));
    }
}

impl Report {
    /// `report.md`: the same numbers as tables for people, and the figures.
    pub fn to_markdown(&self, figures: &[FigureEntry]) -> String {
        let config = &self.config;
        let mut text = format!(
            "# ipdf-rs pipeline report ({} preset)\n\nTrained on the uniform-colour dataset ({} training and {} validation frames per object); \
             encoder {} on {} px crops, {} epochs × {} steps × {} images; scored on the validation split on the level-{} grid \
             (level 2 refined hierarchically; LLH at the ground-truth rotations themselves) against each instance's full ground-truth symmetry set.\n\n## Results by type of ground truth and object\n\n",
            config.plan.preset.name(),
            config.plan.frames,
            config.plan.val_frames,
            config.plan.encoder.name(),
            config.plan.input_size,
            config.plan.epochs,
            config.plan.steps_per_epoch,
            config.plan.batch_size,
            config.plan.eval_level
        );
        model_table(&mut text, &self.models, &LABELS);
        let [plain, occluded] = PAPER_PSEUDO;
        text.push_str(&format!(
            "\nThe paper's Pseudo models, averaged over can, box and bowl: LLH {}, MAAD {}°, Recall MAAD {}° \
             (with occlusion: {}, {}°, {}°).\n",
            plain.0, plain.1, plain.2, occluded.0, occluded.1, occluded.2
        ));
        text.push_str(&format!(
            "\nRecall MAAD predicts a rotation where its cell's log density is at least {:.2} \
             (mass {RECALL_THRESHOLD} per level-4 cell, {:.0}× the uniform density): it reaches a \
             few degrees only where the model is about that sharp along the whole symmetry set.\n",
            recall_min_log_density(RECALL_THRESHOLD),
            (recall_min_log_density(RECALL_THRESHOLD) + std::f64::consts::PI.powi(2).ln()).exp()
        ));
        self.resolution_note(&mut text);
        self.pose_section(&mut text);
        if !self.models_occlusion.is_empty() {
            text.push_str("\n## With occlusion augmentation\n\n");
            model_table(&mut text, &self.models_occlusion, &LABELS);
        }
        if !self.backbones.is_empty() {
            text.push_str("\n## Backbones (pseudo labels)\n\n");
            let rows: Vec<&str> = self.backbones.keys().map(String::as_str).collect();
            model_table(&mut text, &self.backbones, &rows);
        }
        self.label_table(&mut text);
        text.push_str("\n## Figures\n\nEach model's distribution for the first validation image of its object (marker area: probability; \
                       position: direction of the object's x-axis; colour: rotation about it; black: the ground-truth set), and its training curves.\n\n");
        for figure in figures {
            let stem = &figure.stem;
            let translation = if figure.translation {
                format!(" ![translation](figures/{stem}_translation.png)")
            } else {
                String::new()
            };
            text.push_str(&format!(
                "- {} / {}: ![distribution](figures/{stem}.png) ![curves](figures/{stem}_curves.png){translation}\n",
                figure.object, figure.labels
            ));
        }
        text.push_str(
            "\n## Time per stage (seconds)\n\nOf the invocation that wrote this report: a resumed \
             run counts only the work it did.\n\n| stage | seconds |\n|---|---|\n",
        );
        for (name, seconds) in &self.timing_s {
            text.push_str(&format!("| {name} | {seconds:.0} |\n"));
        }
        let kernels: Vec<String> = self
            .cpu_kernels
            .iter()
            .map(|(name, value)| format!("`{name}={value}`"))
            .collect();
        text.push_str(&format!(
            "\nlibtorch's CPU kernels: {} (see `ipdf_model::REPRODUCIBLE_CPU_KERNELS`).\n",
            kernels.join(", ")
        ));
        text
    }

    /// The translation models' table, with and without occlusion, when there are any.
    fn pose_section(&self, text: &mut String) {
        let has_pose = |table: &ScoreTable| {
            table
                .values()
                .any(|objects| objects.values().any(|s| s.translation.is_some()))
        };
        if !has_pose(&self.models) {
            return;
        }
        let cell = self
            .models
            .values()
            .flat_map(|objects| objects.values())
            .find_map(|s| s.translation)
            .map_or(0.0, |t| t.cell_mm);
        text.push_str(&format!(
            "\n## Translation and 6D pose\n\nThe Analytical and Pseudo models above each have a \
             translation model trained on the translations of the same label sets (Single's would \
             be Analytical's). Translation LLH: mean ln p(t | I) at the ground-truth translation, \
             density per mm³, from a hierarchical distribution down to {cell:.0} mm cells; errors \
             of the most likely translation (gradient ascent from the best cells), split along and \
             across the line of sight; joint LLH: rotation LLH + translation LLH; ADD-S AUC: the \
             6D pose of the two most likely values, thresholds up to {:.0}% of the object's \
             diameter (BOP).\n\n",
            100.0 * ADD_S_AUC_FRACTION
        ));
        pose_table(text, &self.models, &LABELS);
        if has_pose(&self.models_occlusion) {
            text.push_str("\nWith occlusion augmentation:\n\n");
            pose_table(text, &self.models_occlusion, &LABELS);
        }
    }

    /// Whether the evaluation grid resolved every model's peaks, naming the models it did not.
    fn resolution_note(&self, text: &mut String) {
        let mut entries: Vec<(String, f64)> =
            [&self.models, &self.models_occlusion, &self.backbones]
                .into_iter()
                .flat_map(|table| {
                    table.iter().flat_map(|(row, objects)| {
                        objects.iter().map(move |(object, scores)| {
                            (format!("{object} {row}"), scores.under_resolution)
                        })
                    })
                })
                .collect();
        entries.sort_by(|a, b| b.1.total_cmp(&a.1));
        let Some((worst, value)) = entries.first() else {
            return;
        };
        let unresolved: Vec<&str> = entries
            .iter()
            .filter(|(_, u)| *u > UNDER_RESOLUTION_LIMIT)
            .map(|(name, _)| name.as_str())
            .collect();
        text.push_str(&format!(
            "\nUnder-resolution (how much splitting the heaviest cells changes their mass, as \
             |ln| of the factor; above {UNDER_RESOLUTION_LIMIT} the scores mislead): at most \
             {value:.2} ({worst}).{}\n",
            if unresolved.is_empty() {
                String::new()
            } else {
                format!(
                    " Not resolved at this level, so unreliable: {}.",
                    unresolved.join(", ")
                )
            }
        ));
    }

    /// The pseudo-label accuracy table.
    fn label_table(&self, text: &mut String) {
        text.push_str("\n## Pseudo-label accuracy\n\nLabel MAAD: mean angle from a label to the nearest ground-truth symmetric pose; \
                       coverage: symmetry classes within 5° of a label (paper: can 1.44°/3.12°, box 4.14°/4.3°, bowl 1.42°/1.89°, Texture/Uniform).\n\n\
                       | object | label MAAD uniform (°) | label MAAD texture (°) | coverage uniform | coverage texture |\n|---|---|---|---|---|\n");
        for (object, variants) in &self.labels {
            let cell = |variant: &str, show: &dyn Fn(&LabelAccuracy) -> String| {
                variants.get(variant).map_or("–".into(), show)
            };
            let maad = |a: &LabelAccuracy| format!("{:.2}", a.label_maad_deg);
            let coverage = |a: &LabelAccuracy| format!("{:.1}%", 100.0 * a.coverage);
            text.push_str(&format!(
                "| {object} | {} | {} | {} | {} |\n",
                cell("uniform", &maad),
                cell("texture", &maad),
                cell("uniform", &coverage),
                cell("texture", &coverage)
            ));
        }
        text.push_str(
            "\nEvery label's error, as a cumulative distribution per object and dataset: \
             ![label errors](figures/label_errors.png)\n",
        );
    }
}
