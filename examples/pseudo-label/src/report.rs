//! Scores pseudo labels against the ground truth, where a dataset has one (`ipdf label
//! --report`): per object, the label MAAD (mean over labels of the angle to the nearest
//! rotation of the ground-truth symmetry set, the paper's table "Evaluation of the pseudo
//! ground-truth orientation labels") and the coverage of the symmetry set; where the reference
//! sets A of `ipdf label --reference` were made, each instance's completeness and precision
//! against A, with or without a ground truth.
use std::collections::BTreeMap;

use std::io::Write;

use bop_dataset::{
    BopDataset, FileError, GtInstance, ModelInfo, PseudoInstance, PseudoLabel, RotationRepairs,
    SceneDir, read_models_info, read_pseudo_gt, read_scene_gt_info, read_scene_gt_repaired,
    write_atomically, write_json,
};
use ipdf_metrics::SymmetryGroup;

use serde::{Deserialize, Serialize};

use crate::LabelError;

/// A symmetric pose counts as covered when a label lies within this angle (degrees).
pub const COVERAGE_ANGLE_DEG: f64 = 5.0;

/// The lower ends of the bins of [`ObjectLabelScores::by_visibility`]: instances under 45%
/// visible, 45–70% and from 70%.
pub const VISIBILITY_BINS: [f64; 3] = [0.0, 0.45, 0.7];

/// Instances of one bin of visible fraction, how many of them are labelled, and how well.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VisibilityBin {
    /// The bin's lower end: instances with `visib_fract` from here to the next bin's.
    pub min_visible: f64,
    /// Instances in the bin.
    pub instances: usize,
    /// Of those, instances with at least one label.
    pub labelled: usize,
    /// Their labels.
    #[serde(default)]
    pub labels: usize,
    /// Mean over those labels of the angle to the nearest ground-truth symmetric rotation
    /// (degrees; 0 without labels).
    #[serde(default)]
    pub label_maad_deg: f64,
    /// Labelled instances of the bin with a label farther than 5° from every symmetric pose.
    #[serde(default)]
    pub off_instances: usize,
}

/// The scores of one object's labels.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ObjectLabelScores {
    /// The object's id.
    pub obj_id: u32,
    /// Instances with a ground-truth pose and a pseudo-label entry.
    pub instances: usize,
    /// Of those, instances with at least one label.
    pub labelled: usize,
    /// `labelled / instances`.
    pub labelled_fraction: f64,
    /// Instances and labelled instances by the visible fraction of the object
    /// (`scene_gt_info.json`'s `visib_fract`, [`VISIBILITY_BINS`]); empty where no scene has
    /// that file.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_visibility: Vec<VisibilityBin>,
    /// Labelled instances with a label farther than 5° from every ground-truth symmetric
    /// rotation: a near-symmetry or a wrong pose taken for a symmetry.
    pub off_instances: usize,
    /// The 5th, 25th, 50th, 75th and 95th percentiles of the labelled instances' best scores.
    pub scores: Option<[f64; 5]>,
    /// The same of the unlabelled instances' best poses (those that have one).
    pub rejected_scores: Option<[f64; 5]>,
    /// Labels scored.
    pub labels: usize,
    /// Mean over labels of the angle to the nearest ground-truth symmetric rotation (degrees).
    pub label_maad_deg: f64,
    /// Each label's angle to the nearest ground-truth symmetric rotation (degrees), for figures;
    /// not written to the report file.
    #[serde(skip)]
    pub errors_deg: Vec<f64>,
    /// Mean over labelled instances of the fraction of symmetry classes
    /// ([`ipdf_metrics::SymmetryGroup::classes`]: the identity and each discrete symmetry, with its
    /// continuous orbit) within 5° of a label.
    pub coverage: f64,
    /// Against the reference sets A of `ipdf label --reference` (`scene_reference_gt.json`),
    /// where they were made: each labelled instance with a non-empty A.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub against_reference: Vec<InstanceAgainstReference>,
    /// Mean over `against_reference` of the completeness (the share of A within 5° of a
    /// label).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub completeness: Option<f64>,
    /// Mean over `against_reference` of the precision (the share of labels within 5° of A).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub precision: Option<f64>,
}

/// One instance's labels against its reference set A.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct InstanceAgainstReference {
    /// Its scene.
    pub scene_id: u32,
    /// Its image.
    pub im_id: u32,
    /// Its index in the image (mask order).
    pub instance: usize,
    /// Its labels.
    pub labels: usize,
    /// The poses of A.
    pub reference: usize,
    /// The share of A within 5° of a label.
    pub completeness: f64,
    /// The share of labels within 5° of A.
    pub precision: f64,
}

/// The scores of a split's labels: `labels.json` of `ipdf label --report`, `{"variant",
/// "objects": {name: {"obj_id", "instances", "labelled", "labelled_fraction", "off_instances",
/// "by_visibility": [{"min_visible", "instances", "labelled", "labels", "label_maad_deg",
/// "off_instances"}, …], "scores", "rejected_scores",
/// "labels", "label_maad_deg", "coverage", and where reference sets were made "completeness",
/// "precision", "against_reference": [{"scene_id", "im_id", "instance", "labels", "reference",
/// "completeness", "precision"}, …]}}}`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LabelReport {
    /// The dataset variant (`dataset_info.json`) or its folder's name.
    pub variant: String,
    /// Per object, by its name (`dataset_info.json`) or `obj_NNNNNN`.
    pub objects: BTreeMap<String, ObjectLabelScores>,
    /// Ground-truth rotations orthonormal only to published precision, read as their nearest
    /// rotations (absent when none were).
    #[serde(default, skip_serializing_if = "RotationRepairs::is_empty")]
    pub repaired_rotations: RotationRepairs,
}

impl LabelReport {
    /// Writes the report as JSON to `path` and as a markdown table beside it (`.md`),
    /// atomically.
    pub fn write(&self, path: &std::path::Path) -> Result<(), FileError> {
        write_json(path, self)?;
        write_atomically(&path.with_extension("md"), |out| {
            out.write_all(self.to_markdown().as_bytes())
        })
    }

    /// A markdown table of the same, one row per object in id order.
    pub fn to_markdown(&self) -> String {
        let mut text = format!(
            "Pseudo-label accuracy ({}): label MAAD = mean angle from a label to the nearest \
             ground-truth symmetric pose; coverage = symmetry classes within {COVERAGE_ANGLE_DEG}° \
             of a label; off = labelled instances with a label farther than \
             {COVERAGE_ANGLE_DEG}° from every symmetric pose; scores = median (5th–95th \
             percentile) of the best score, in the sensor's expected errors; by visibility = \
             labelled of the instances under 45%, 45–70% and from 70% visible, and their \
             label MAAD and off instances; completeness and precision = mean over the \
             instances with a reference set A (`ipdf label --reference`) of the share of A \
             within {COVERAGE_ANGLE_DEG}° of a label and of the labels within \
             {COVERAGE_ANGLE_DEG}° of A.\n\n\
             | object | instances | labelled | by visibility | labels | label MAAD (°) | \
             coverage | off | scores, labelled | scores, unlabelled | label MAAD (°), off, by \
             visibility | completeness, precision |\n\
             |---|---|---|---|---|---|---|---|---|---|---|---|\n",
            self.variant
        );
        let mut rows: Vec<_> = self.objects.iter().collect();
        rows.sort_by_key(|(_, s)| s.obj_id);
        for (name, s) in rows {
            let spread = |p: &Option<[f64; 5]>| match p {
                Some(p) => format!("{:.2} ({:.2}–{:.2})", p[2], p[0], p[4]),
                None => "–".into(),
            };
            let bins = |cell: &dyn Fn(&VisibilityBin) -> String| {
                if s.by_visibility.is_empty() {
                    "–".to_string()
                } else {
                    let cells: Vec<String> = s.by_visibility.iter().map(cell).collect();
                    cells.join(" · ")
                }
            };
            let by_visibility = bins(&|b| format!("{}/{}", b.labelled, b.instances));
            let accuracy_by_visibility = bins(&|b| match b.labels {
                0 => "–".into(),
                _ => format!("{:.2}, {}", b.label_maad_deg, b.off_instances),
            });
            let against_reference = match (s.completeness, s.precision) {
                (Some(c), Some(p)) => format!(
                    "{:.1}%, {:.1}% ({} instances)",
                    100.0 * c,
                    100.0 * p,
                    s.against_reference.len()
                ),
                _ => "–".into(),
            };
            // Without a ground truth (instances scored against A alone), nothing to show.
            let (label_maad, coverage) = if s.instances == 0 {
                ("–".to_string(), "–".to_string())
            } else {
                (
                    format!("{:.2}", s.label_maad_deg),
                    format!("{:.1}%", 100.0 * s.coverage),
                )
            };
            text += &format!(
                "| {} | {} | {} ({:.1}%) | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                name,
                s.instances,
                s.labelled,
                100.0 * s.labelled_fraction,
                by_visibility,
                s.labels,
                label_maad,
                coverage,
                s.off_instances,
                spread(&s.scores),
                spread(&s.rejected_scores),
                accuracy_by_visibility,
                against_reference,
            );
        }
        text
    }
}

/// Scores the pseudo labels of `split` against its `scene_gt.json` and its
/// `scene_reference_gt.json`, scene by scene (scenes without labels, or with neither of the
/// two, are skipped). `names` maps object ids to names.
pub fn report(
    dataset: &BopDataset,
    split: &str,
    names: &BTreeMap<u32, String>,
    variant: &str,
) -> Result<LabelReport, LabelError> {
    let models = read_models_info(&dataset.models_info_path())?;
    let mut sums: BTreeMap<u32, ObjectSums> = BTreeMap::new();
    let mut repairs = RotationRepairs::default();
    for scene_id in dataset.scene_ids(split)? {
        let scene = dataset.scene(split, scene_id);
        let scored = scene.gt_path().exists() || scene.reference_gt_path().exists();
        if !scene.pseudo_gt_path().exists() || !scored {
            continue;
        }
        repairs.merge(&score_scene(&scene, &models, &mut sums)?);
    }
    let objects = sums
        .into_iter()
        .map(|(obj_id, sums)| {
            let name = names
                .get(&obj_id)
                .cloned()
                .unwrap_or_else(|| format!("obj_{obj_id:06}"));
            (name, sums.finish())
        })
        .collect();
    Ok(LabelReport {
        variant: variant.to_string(),
        objects,
        repaired_rotations: repairs,
    })
}

/// Adds the instances of `scene` that have a pseudo-label entry to the sums of their objects:
/// against the ground truth where `scene_gt.json` has their pose, against the reference set A
/// where `scene_reference_gt.json` has one (a scene with A and no ground truth, such as real
/// frames of a user's own camera, gets its completeness and precision alone); an error when
/// the labels and the ground truth name different objects. Returns the ground-truth rotations
/// read as their nearest rotations.
fn score_scene(
    scene: &SceneDir,
    models: &BTreeMap<u32, ModelInfo>,
    sums: &mut BTreeMap<u32, ObjectSums>,
) -> Result<RotationRepairs, LabelError> {
    let (gt, repairs) = if scene.gt_path().exists() {
        read_scene_gt_repaired(&scene.gt_path())?
    } else {
        Default::default()
    };
    let pseudo = read_pseudo_gt(&scene.pseudo_gt_path())?;
    let info = if scene.gt_info_path().exists() {
        Some(read_scene_gt_info(&scene.gt_info_path())?)
    } else {
        None
    };
    let references = if scene.reference_gt_path().exists() {
        Some(read_pseudo_gt(&scene.reference_gt_path())?)
    } else {
        None
    };
    for (im_id, instances) in &pseudo {
        for (k, instance) in instances.iter().enumerate() {
            let truth = gt.get(im_id).and_then(|list| list.get(k));
            let reference = references.as_ref().and_then(|r| r.get(im_id)?.get(k));
            if let Some(truth) = truth
                && truth.obj_id != instance.obj_id
            {
                return Err(FileError::new(
                    &scene.pseudo_gt_path(),
                    format!("{im_id}[{k}].obj_id"),
                    format!("{} but scene_gt.json has {}", instance.obj_id, truth.obj_id),
                )
                .into());
            }
            if truth.is_none() && reference.is_none() {
                continue;
            }
            let sums = sums
                .entry(instance.obj_id)
                .or_insert_with(|| ObjectSums::new(instance.obj_id));
            if let Some(truth) = truth {
                let group = models
                    .get(&truth.obj_id)
                    .map(|m| m.symmetry.clone())
                    .unwrap_or_default();
                let visible = info
                    .as_ref()
                    .and_then(|info| info.get(im_id)?.get(k))
                    .map(|i| i.visib_fract);
                sums.add(instance, truth, &group, visible);
            }
            if let Some(reference) = reference {
                sums.add_reference(&instance.labels, &reference.labels, (scene.id, *im_id, k));
            }
        }
    }
    Ok(repairs)
}

/// One object's scores while its instances come in: counts in `scores`, sums to divide at
/// the end.
struct ObjectSums {
    scores: ObjectLabelScores,
    /// Of every label's angle to the nearest ground-truth symmetric rotation (degrees).
    error_sum: f64,
    /// Of every labelled instance's fraction of symmetry classes covered.
    coverage_sum: f64,
    /// The best score of each labelled instance (its first label's).
    accepted: Vec<f64>,
    /// The best pose's score of each unlabelled instance that has one.
    rejected: Vec<f64>,
}

impl ObjectSums {
    fn new(obj_id: u32) -> Self {
        Self {
            scores: ObjectLabelScores {
                obj_id,
                ..Default::default()
            },
            error_sum: 0.0,
            coverage_sum: 0.0,
            accepted: Vec::new(),
            rejected: Vec::new(),
        }
    }

    /// Adds an instance: its labels against the `truth` expanded by `group`, in the bin of its
    /// `visible` fraction where it is known.
    fn add(
        &mut self,
        instance: &PseudoInstance,
        truth: &GtInstance,
        group: &SymmetryGroup,
        visible: Option<f64>,
    ) {
        self.scores.instances += 1;
        let bin = visible.map(|visible| {
            VISIBILITY_BINS
                .iter()
                .rposition(|&m| visible >= m)
                .unwrap_or(0)
        });
        if let Some(bin) = bin {
            let bins = &mut self.scores.by_visibility;
            if bins.is_empty() {
                bins.extend(VISIBILITY_BINS.map(|min_visible| VisibilityBin {
                    min_visible,
                    ..Default::default()
                }));
            }
            bins[bin].instances += 1;
            bins[bin].labelled += usize::from(!instance.labels.is_empty());
        }
        match (instance.labels.first(), &instance.best) {
            (Some(label), _) => self.accepted.push(label.score),
            (None, Some(best)) => self.rejected.push(best.score),
            (None, None) => {}
        }
        if instance.labels.is_empty() {
            return;
        }
        self.scores.labelled += 1;
        // Per label, the distance to each symmetry class of the ground truth.
        let distances: Vec<Vec<f64>> = instance
            .labels
            .iter()
            .map(|label| group.class_distances(&truth.pose.rotation, &label.pose.rotation))
            .collect();
        self.add_labels(&distances, bin);
    }

    /// Adds the labels of a labelled instance, given by their `distances` to each symmetry
    /// class of the ground truth (radians), in visibility bin `bin`.
    fn add_labels(&mut self, distances: &[Vec<f64>], bin: Option<usize>) {
        let mut off = false;
        let first = self.scores.errors_deg.len();
        for per_class in distances {
            let error = per_class
                .iter()
                .fold(f64::INFINITY, |a, &b| a.min(b))
                .to_degrees();
            off |= error > COVERAGE_ANGLE_DEG;
            self.error_sum += error;
            self.scores.errors_deg.push(error);
            self.scores.labels += 1;
        }
        if let Some(bin) = bin {
            let errors = &self.scores.errors_deg[first..];
            let bin = &mut self.scores.by_visibility[bin];
            bin.labels += errors.len();
            // The sum for now: divided by the count once all are in.
            for error in errors {
                bin.label_maad_deg += error;
            }
            bin.off_instances += usize::from(off);
        }
        let classes = distances[0].len();
        let covered = (0..classes)
            .filter(|&c| {
                distances
                    .iter()
                    .any(|d| d[c].to_degrees() <= COVERAGE_ANGLE_DEG)
            })
            .count();
        self.coverage_sum += covered as f64 / classes as f64;
        self.scores.off_instances += usize::from(off);
    }

    /// Adds the labels of instance `at` (scene, image, index) against its reference set
    /// `reference`, when both are non-empty.
    fn add_reference(
        &mut self,
        labels: &[PseudoLabel],
        reference: &[PseudoLabel],
        at: (u32, u32, usize),
    ) {
        let rotations =
            |set: &[PseudoLabel]| -> Vec<_> { set.iter().map(|l| l.pose.rotation).collect() };
        let (labels, reference) = (rotations(labels), rotations(reference));
        let angle = COVERAGE_ANGLE_DEG.to_radians();
        let (Some(completeness), Some(precision)) = (
            ipdf_metrics::completeness(&labels, &reference, angle),
            ipdf_metrics::precision(&labels, &reference, angle),
        ) else {
            return;
        };
        self.scores
            .against_reference
            .push(InstanceAgainstReference {
                scene_id: at.0,
                im_id: at.1,
                instance: at.2,
                labels: labels.len(),
                reference: reference.len(),
                completeness,
                precision,
            });
    }

    /// The scores: sums divided by their counts, percentiles of the best scores.
    fn finish(self) -> ObjectLabelScores {
        let mut scores = self.scores;
        scores.label_maad_deg = self.error_sum / scores.labels.max(1) as f64;
        for bin in &mut scores.by_visibility {
            bin.label_maad_deg /= bin.labels.max(1) as f64;
        }
        scores.coverage = self.coverage_sum / scores.labelled.max(1) as f64;
        scores.labelled_fraction = scores.labelled as f64 / scores.instances.max(1) as f64;
        let against = &scores.against_reference;
        let mean = |value: fn(&InstanceAgainstReference) -> f64| {
            (!against.is_empty())
                .then(|| against.iter().map(value).sum::<f64>() / against.len() as f64)
        };
        scores.completeness = mean(|i| i.completeness);
        scores.precision = mean(|i| i.precision);
        scores.scores = percentiles(self.accepted);
        scores.rejected_scores = percentiles(self.rejected);
        scores
    }
}

/// The 5th, 25th, 50th, 75th and 95th percentiles (nearest rank) of `values`; `None` when empty.
fn percentiles(mut values: Vec<f64>) -> Option<[f64; 5]> {
    values.retain(|v| v.is_finite());
    values.sort_by(f64::total_cmp);
    let last = values.len().checked_sub(1)?;
    Some([0.05, 0.25, 0.5, 0.75, 0.95].map(|q| values[(q * last as f64).round() as usize]))
}

#[cfg(test)]
mod tests {
    use bop_dataset::write_models_info;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::*;

    /// Poses turned `degrees` about the camera's z axis, 0.5 m away.
    fn turned(degrees: &[f64]) -> Vec<PseudoLabel> {
        degrees
            .iter()
            .map(|d| PseudoLabel {
                pose: Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, 0.5),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), d.to_radians()),
                ),
                score: 0.8,
            })
            .collect()
    }

    /// A dataset of object 1 (`models_info.json` only) with an empty scene 0 of split `test`
    /// and no ground truth: the dataset and its scene.
    fn split_without_truth(dir: &std::path::Path) -> (BopDataset, SceneDir) {
        let dataset = BopDataset::new(dir);
        let info = ModelInfo {
            diameter: 100.0,
            min: None,
            size: None,
            symmetry: SymmetryGroup::default(),
        };
        std::fs::create_dir_all(dir.join("models")).unwrap();
        write_models_info(&dataset.models_info_path(), &BTreeMap::from([(1, info)])).unwrap();
        let scene = dataset.scene("test", 0);
        std::fs::create_dir_all(scene.pseudo_gt_path().parent().unwrap()).unwrap();
        (dataset, scene)
    }

    /// The pose sets of one instance of object 1 in image 0, written to `path`.
    fn write_sets(path: &std::path::Path, labels: Vec<PseudoLabel>) {
        let instance = PseudoInstance {
            obj_id: 1,
            labels,
            ..Default::default()
        };
        bop_dataset::write_pseudo_gt(path, &BTreeMap::from([(0, vec![instance])])).unwrap();
    }

    /// A split without `scene_gt.json` (a user's own frames) whose labels and reference sets
    /// were written: each instance's completeness and precision are reported, worked out by
    /// hand from the turns (labels at 0°, 10°, 20° and 90°; A every 3° from 0.5° to 30.5°, of
    /// which 27.5° and 30.5° lie more than 5° from a label, and no pose of A lies near 90°),
    /// and the ground-truth scores are left empty.
    #[test]
    fn a_split_without_ground_truth_gets_completeness_and_precision_alone() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, scene) = split_without_truth(dir.path());
        let reference: Vec<f64> = (0..11).map(|k| 0.5 + 3.0 * f64::from(k)).collect();
        write_sets(&scene.pseudo_gt_path(), turned(&[0.0, 10.0, 20.0, 90.0]));
        write_sets(&scene.reference_gt_path(), turned(&reference));
        assert!(!scene.gt_path().exists());

        let scores = report(&dataset, "test", &BTreeMap::new(), "own").unwrap();
        let object = &scores.objects["obj_000001"];
        assert_eq!(object.instances, 0);
        assert_eq!(object.against_reference.len(), 1);
        assert!((object.completeness.unwrap() - 9.0 / 11.0).abs() < 1e-12);
        assert!((object.precision.unwrap() - 0.75).abs() < 1e-12);
        let row = scores.to_markdown().lines().last().unwrap().to_string();
        assert!(row.contains("| – | – |"), "{row}");
        assert!(row.contains("81.8%, 75.0% (1 instances)"), "{row}");
    }

    /// A malformed `scene_reference_gt.json` in a split without ground truth is refused,
    /// naming the file, not skipped.
    #[test]
    fn a_malformed_reference_file_without_ground_truth_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, scene) = split_without_truth(dir.path());
        write_sets(&scene.pseudo_gt_path(), turned(&[0.0]));
        std::fs::write(
            scene.reference_gt_path(),
            r#"{"0": [{"obj_id": 1, "labels": [{"cam_R_m2c": [1, 0]}]}]}"#,
        )
        .unwrap();
        let error = report(&dataset, "test", &BTreeMap::new(), "own")
            .unwrap_err()
            .to_string();
        assert!(error.contains("scene_reference_gt.json"), "{error}");
    }
}
