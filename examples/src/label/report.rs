//! Scores pseudo labels against the ground truth, where a dataset has one (`ipdf label
//! --report`): per object, the label MAAD (mean over labels of the angle to the nearest
//! rotation of the ground-truth symmetry set, the paper's table "Evaluation of the pseudo
//! ground-truth orientation labels") and the coverage of the symmetry set.
use std::collections::BTreeMap;

use serde_json::{Value, json};

use crate::dataset::{BopDataset, read_models_info, read_pseudo_gt, read_scene_gt};
use crate::{FileError, PipelineError};

/// A symmetric pose counts as covered when a label lies within this angle (degrees).
pub const COVERAGE_ANGLE_DEG: f64 = 5.0;

/// The scores of one object's labels.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObjectLabelScores {
    /// The object's name (`dataset_info.json`) or `obj_NNNNNN`.
    pub name: String,
    /// Instances with a ground-truth pose and a pseudo-label entry.
    pub instances: usize,
    /// Of those, instances with at least one label.
    pub labelled: usize,
    /// Labels scored.
    pub labels: usize,
    /// Mean over labels of the angle to the nearest ground-truth symmetric rotation (degrees).
    pub label_maad_deg: f64,
    /// Mean over labelled instances of the fraction of symmetry classes
    /// ([`metrics::SymmetryGroup::classes`]: the identity and each discrete symmetry, with its
    /// continuous orbit) within 5° of a label.
    pub coverage: f64,
}

/// The scores of a split's labels, by object id.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LabelReport {
    /// The dataset variant (`dataset_info.json`) or its folder's name.
    pub variant: String,
    /// Per object.
    pub objects: BTreeMap<u32, ObjectLabelScores>,
}

impl LabelReport {
    /// `{"variant", "objects": {name: {"obj_id", "instances", "labelled", "labels",
    /// "label_maad_deg", "coverage"}}}`.
    pub fn to_json(&self) -> Value {
        let objects: serde_json::Map<String, Value> = self
            .objects
            .iter()
            .map(|(&obj_id, s)| {
                (
                    s.name.clone(),
                    json!({
                        "obj_id": obj_id, "instances": s.instances, "labelled": s.labelled,
                        "labels": s.labels, "label_maad_deg": s.label_maad_deg,
                        "coverage": s.coverage,
                    }),
                )
            })
            .collect();
        json!({"variant": self.variant, "objects": objects})
    }

    /// A markdown table of the same.
    pub fn to_markdown(&self) -> String {
        let mut text = format!(
            "Pseudo-label accuracy ({}): label MAAD = mean angle from a label to the nearest \
             ground-truth symmetric pose; coverage = symmetry classes within {COVERAGE_ANGLE_DEG}° \
             of a label.\n\n| object | instances | labelled | labels | label MAAD (°) | coverage |\n\
             |---|---|---|---|---|---|\n",
            self.variant
        );
        for s in self.objects.values() {
            text += &format!(
                "| {} | {} | {} | {} | {:.2} | {:.1}% |\n",
                s.name,
                s.instances,
                s.labelled,
                s.labels,
                s.label_maad_deg,
                100.0 * s.coverage
            );
        }
        text
    }
}

/// Scores the pseudo labels of `split` against its `scene_gt.json`, scene by scene (scenes
/// without both files are skipped). `names` maps object ids to names.
pub fn report(
    dataset: &BopDataset,
    split: &str,
    names: &BTreeMap<u32, String>,
    variant: &str,
) -> Result<LabelReport, PipelineError> {
    let models = read_models_info(&dataset.models_info_path())?;
    let mut sums: BTreeMap<u32, (ObjectLabelScores, f64, f64)> = BTreeMap::new();
    for scene_id in dataset.scene_ids(split)? {
        let scene = dataset.scene(split, scene_id);
        if !scene.pseudo_gt_path().exists() || !scene.gt_path().exists() {
            continue;
        }
        let gt = read_scene_gt(&scene.gt_path())?;
        let pseudo = read_pseudo_gt(&scene.pseudo_gt_path())?;
        for (im_id, instances) in &pseudo {
            for (k, instance) in instances.iter().enumerate() {
                let Some(truth) = gt.get(im_id).and_then(|list| list.get(k)) else {
                    continue;
                };
                if truth.obj_id != instance.obj_id {
                    return Err(FileError::new(
                        &scene.pseudo_gt_path(),
                        format!("{im_id}[{k}].obj_id"),
                        format!("{} but scene_gt.json has {}", instance.obj_id, truth.obj_id),
                    )
                    .into());
                }
                let group = models
                    .get(&truth.obj_id)
                    .map(|m| m.symmetry.clone())
                    .unwrap_or_default();
                let entry = sums.entry(truth.obj_id).or_insert_with(|| {
                    let name = names
                        .get(&truth.obj_id)
                        .cloned()
                        .unwrap_or_else(|| format!("obj_{:06}", truth.obj_id));
                    (
                        ObjectLabelScores {
                            name,
                            ..Default::default()
                        },
                        0.0,
                        0.0,
                    )
                });
                entry.0.instances += 1;
                if instance.labels.is_empty() {
                    continue;
                }
                entry.0.labelled += 1;
                // Per label, the distance to each symmetry class of the ground truth.
                let distances: Vec<Vec<f64>> = instance
                    .labels
                    .iter()
                    .map(|label| group.class_distances(&truth.pose.rotation, &label.pose.rotation))
                    .collect();
                for per_class in &distances {
                    entry.1 += per_class
                        .iter()
                        .fold(f64::INFINITY, |a, &b| a.min(b))
                        .to_degrees();
                    entry.0.labels += 1;
                }
                let classes = distances[0].len();
                let covered = (0..classes)
                    .filter(|&c| {
                        distances
                            .iter()
                            .any(|d| d[c].to_degrees() <= COVERAGE_ANGLE_DEG)
                    })
                    .count();
                entry.2 += covered as f64 / classes as f64;
            }
        }
    }
    let objects = sums
        .into_iter()
        .map(|(obj_id, (mut scores, maad_sum, coverage_sum))| {
            scores.label_maad_deg = maad_sum / scores.labels.max(1) as f64;
            scores.coverage = coverage_sum / scores.labelled.max(1) as f64;
            (obj_id, scores)
        })
        .collect();
    Ok(LabelReport {
        variant: variant.to_string(),
        objects,
    })
}
