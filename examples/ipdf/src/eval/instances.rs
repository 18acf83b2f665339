//! Scores per instance, as real frames are scored: the most likely rotation's angle to the
//! nearest true pose under the object's symmetries, Acc@15° and Acc@30°, its VSD to the truth
//! where the frame has depth (a true pose by what the camera sees), the truth's LLH
//! against the uniform density, and for pose runs the translation error and ADD(-S) at 10% of
//! the diameter (BOP's convention: ADD for objects without symmetries, ADD-S for those with).
//! [`markdown`] writes them as a table.
use std::fmt::Write as _;

use ipdf_metrics::{add, add_s, translation_error};
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};
use so3_grid::geodesic_distance;

use crate::Error;
use crate::eval::rotation::RotationEvaluation;
use crate::eval::surface::VSD_CORRECT;
use crate::eval::translation::ObjectModel;
use crate::median::median;
use crate::training_data::Examples;

/// The thresholds of the rotation accuracies (degrees).
pub const ACCURACY_THRESHOLDS_DEG: [f64; 2] = [15.0, 30.0];
/// ADD(-S) counts a pose correct under this fraction of the object's diameter (BOP, YCB-Video,
/// LINEMOD).
pub const ADD_FRACTION: f64 = 0.1;

/// The log-density of the uniform distribution on SO(3) (volume π²): the LLH of a model that
/// has learnt nothing.
pub fn uniform_llh() -> f64 {
    -(std::f64::consts::PI.powi(2)).ln()
}

/// One instance's scores: a row of `ipdf eval`'s `"instances"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstanceScore {
    /// Scene id.
    pub scene_id: u32,
    /// Image id.
    pub im_id: u32,
    /// The instance's index in the image (`scene_gt.json` order).
    pub instance: usize,
    /// Visible fraction (`visib_fract` of `scene_gt_info.json`), where the split has it.
    pub visib_fract: Option<f64>,
    /// Angle of the most likely rotation to the nearest true pose under the object's
    /// symmetries, degrees (continuous symmetries in 200 steps: within 0.9° of exact).
    pub rotation_error_deg: f64,
    /// BOP's VSD (δ 15 mm, τ 20 mm) of the most likely rotation, turned about the object's
    /// centre from the truth, against the truth, judged on the frame's depth image where it
    /// has one: under 0.3 the camera cannot tell the rotation from the truth
    /// ([`crate::eval::surface::rotation_vsd`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vsd: Option<f64>,
    /// Mean log-density of the ground-truth set (nats; the uniform density scores −2.29).
    pub llh: f64,
    /// MAAD against the ground-truth set, degrees (`ipdf eval`'s `maad_deg` is their mean).
    #[serde(default)]
    pub maad_deg: f64,
    /// Recall MAAD against the ground-truth set, degrees: how far the farthest-reaching
    /// members of the set lie from the predicted cells (`ipdf eval`'s `recall_maad_deg` is
    /// their mean).
    #[serde(default)]
    pub recall_maad_deg: f64,
    /// Distance of the most likely translation from the truth (mm), for pose runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation_error_mm: Option<f64>,
    /// ADD, or ADD-S for a symmetric object, of the most likely pose (mm), for pose runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub add_mm: Option<f64>,
    /// Distance from the truth of the most likely pose's translation fitted to the frame's
    /// depth inside the instance's visible mask (mm; [`crate::depth_fit`]), for pose runs on
    /// frames with depth and masks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_translation_error_mm: Option<f64>,
    /// ADD(-S) of the most likely rotation with that fitted translation (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_add_mm: Option<f64>,
    /// Angle to the nearest true pose of the pose found from the rotation model's hypotheses
    /// and the frame's depth (degrees; [`crate::eval::surface::depth_refined_poses`]), where
    /// asked for and the frame has depth and a mask.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_rotation_error_deg: Option<f64>,
    /// Its rotation's VSD to the truth, as [`InstanceScore::vsd`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_vsd: Option<f64>,
    /// Its translation's distance from the truth (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_translation_error_mm: Option<f64>,
    /// Its ADD(-S) (mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_add_mm: Option<f64>,
}

/// The scores over all instances: `ipdf eval`'s `"accuracy"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// Instances scored.
    pub instances: usize,
    /// The least visible fraction scored (`--min-visib`; instances without one are scored).
    pub min_visib: f64,
    /// Share of instances whose rotation error is under 15°.
    pub acc_15: f64,
    /// Share under 30°.
    pub acc_30: f64,
    /// Share whose most likely rotation is a true pose: under 15° from the truth's symmetries,
    /// or under 0.3 in VSD (instances without a depth image by the angle alone); where the
    /// split has depth images.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acc_15_or_vsd: Option<f64>,
    /// Median rotation error, degrees.
    pub median_rotation_error_deg: f64,
    /// Share of instances whose truth is denser than the uniform density.
    pub above_uniform: f64,
    /// The uniform density's LLH (−ln π²).
    pub uniform_llh: f64,
    /// `ADD` or `ADD-S`, for pose runs and poses refined with depth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub add_metric: Option<String>,
    /// Share of instances under 10% of the diameter in ADD(-S), for pose runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub add_accuracy: Option<f64>,
    /// Median translation error (mm), for pose runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_translation_error_mm: Option<f64>,
    /// Median error of the translations fitted to the frames' depth (mm), over the instances
    /// that have one, for pose runs on frames with depth and masks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_fitted_translation_error_mm: Option<f64>,
    /// Share of those instances under 10% of the diameter in ADD(-S) with the fitted
    /// translation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_add_accuracy: Option<f64>,
    /// For the poses found from the hypotheses and the depth, where asked for: the share of
    /// instances (those without one counted as wrong) on a true pose, under 15° or 0.3 in VSD…
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_acc_15_or_vsd: Option<f64>,
    /// …their median rotation error (degrees, over the instances that have one)…
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_refined_rotation_error_deg: Option<f64>,
    /// …their median translation error (mm)…
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_refined_translation_error_mm: Option<f64>,
    /// …and the share of instances under 10% of the diameter in ADD(-S).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_add_accuracy: Option<f64>,
}

/// The most likely translations of a pose run and the object ADD(-S) is measured on.
pub struct PoseParts<'a> {
    /// Each crop's most likely translation (mm).
    pub translations: &'a [Vector3<f64>],
    /// The object's surface points, diameter and symmetry.
    pub object: &'a ObjectModel,
    /// Each crop's most likely pose's translation fitted to its frame's depth (mm), where it
    /// could be (empty: none fitted).
    pub fitted: &'a [Option<Vector3<f64>>],
}

/// The poses found from each crop's rotation hypotheses and its frame's depth
/// ([`crate::eval::surface::depth_refined_poses`]).
pub struct RefinedParts<'a> {
    /// Each crop's pose (translation in mm), where one was found.
    pub poses: &'a [Option<Isometry3<f64>>],
    /// Each crop's VSD of that pose's rotation to the truth, as [`InstanceScore::vsd`].
    pub vsd: &'a [Option<f64>],
    /// The object's surface points, diameter and symmetry.
    pub object: &'a ObjectModel,
}

/// Each instance's scores and their summary, from each crop's scores and most likely rotation
/// in `evaluation` (and, for pose runs, the translations; where asked for, the poses refined
/// with depth). `vsd` holds each instance's [`InstanceScore::vsd`] (empty: none computed).
pub fn score_instances(
    examples: &Examples,
    evaluation: &RotationEvaluation,
    pose: Option<&PoseParts>,
    refined: Option<&RefinedParts>,
    vsd: &[Option<f64>],
    min_visib: f64,
) -> Result<(Vec<InstanceScore>, Accuracy), Error> {
    let rotations = &evaluation.estimates;
    let truth_sets = examples.required_truth_sets()?;
    let truth_poses = examples.required_truth_poses()?;
    let mut rows = Vec::with_capacity(truth_sets.len());
    for (i, at) in examples.instances.iter().enumerate() {
        let nearest = |rotation| {
            truth_sets[i]
                .iter()
                .map(|truth| geodesic_distance(truth, rotation))
                .fold(f64::INFINITY, f64::min)
                .to_degrees()
        };
        let estimate = pose.map(|p| Isometry3::from_parts(p.translations[i].into(), rotations[i]));
        let fitted = pose.and_then(|p| {
            let t = p.fitted.get(i).copied().flatten()?;
            Some(Isometry3::from_parts(t.into(), rotations[i]))
        });
        let truth = &truth_poses[i];
        let add_on = |object: &ObjectModel, e: Isometry3<f64>| {
            if object.symmetric {
                add_s(&object.points, &e, truth)
            } else {
                add(&object.points, &e, truth)
            }
        };
        let add_of = |e: Isometry3<f64>| pose.map(|p| add_on(p.object, e));
        let found = refined.and_then(|r| r.poses.get(i).copied().flatten());
        rows.push(InstanceScore {
            scene_id: at.scene_id,
            im_id: at.im_id,
            instance: at.instance,
            visib_fract: examples.visible_fractions[i],
            rotation_error_deg: nearest(&rotations[i]),
            vsd: vsd.get(i).copied().flatten(),
            llh: evaluation.llh[i],
            maad_deg: evaluation.maad_deg[i],
            recall_maad_deg: evaluation.recall_maad_deg[i],
            translation_error_mm: estimate
                .map(|e| translation_error(&e.translation.vector, &truth.translation.vector)),
            add_mm: estimate.and_then(add_of),
            fitted_translation_error_mm: fitted
                .map(|e| translation_error(&e.translation.vector, &truth.translation.vector)),
            fitted_add_mm: fitted.and_then(add_of),
            refined_rotation_error_deg: found.as_ref().map(|p| nearest(&p.rotation)),
            refined_vsd: refined.and_then(|r| r.vsd.get(i).copied().flatten()),
            refined_translation_error_mm: found
                .map(|p| translation_error(&p.translation.vector, &truth.translation.vector)),
            refined_add_mm: refined.zip(found).map(|(r, p)| add_on(r.object, p)),
        });
    }
    let accuracy = summarise(&rows, pose, refined.map(|r| r.object), min_visib);
    Ok((rows, accuracy))
}

fn summarise(
    rows: &[InstanceScore],
    pose: Option<&PoseParts>,
    refined: Option<&ObjectModel>,
    min_visib: f64,
) -> Accuracy {
    let n = rows.len().max(1) as f64;
    let share =
        |test: &dyn Fn(&InstanceScore) -> bool| rows.iter().filter(|r| test(r)).count() as f64 / n;
    let [low, high] = ACCURACY_THRESHOLDS_DEG;
    let mut errors: Vec<f64> = rows.iter().map(|r| r.rotation_error_deg).collect();
    let mut translations: Vec<f64> = rows.iter().filter_map(|r| r.translation_error_mm).collect();
    let mut fitted: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.fitted_translation_error_mm)
        .collect();
    let fitted_rows = fitted.len().max(1) as f64;
    let true_pose = |error: Option<f64>, vsd: Option<f64>| {
        error.is_some_and(|e| e < ACCURACY_THRESHOLDS_DEG[0])
            || vsd.is_some_and(|v| v < VSD_CORRECT)
    };
    let mut refined_rotations: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.refined_rotation_error_deg)
        .collect();
    let mut refined_translations: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.refined_translation_error_mm)
        .collect();
    Accuracy {
        instances: rows.len(),
        min_visib,
        acc_15: share(&|r| r.rotation_error_deg < low),
        acc_30: share(&|r| r.rotation_error_deg < high),
        acc_15_or_vsd: rows.iter().any(|r| r.vsd.is_some()).then(|| {
            share(&|r| r.rotation_error_deg < low || r.vsd.is_some_and(|v| v < VSD_CORRECT))
        }),
        median_rotation_error_deg: median(&mut errors),
        above_uniform: share(&|r| r.llh > uniform_llh()),
        uniform_llh: uniform_llh(),
        add_metric: pose
            .map(|p| p.object)
            .or(refined)
            .map(|o| if o.symmetric { "ADD-S" } else { "ADD" }.to_string()),
        add_accuracy: pose.map(|p| {
            share(&|r| {
                r.add_mm
                    .is_some_and(|d| d < ADD_FRACTION * p.object.diameter_mm)
            })
        }),
        median_translation_error_mm: pose.map(|_| median(&mut translations)),
        fitted_add_accuracy: pose.filter(|_| !fitted.is_empty()).map(|p| {
            let under = |r: &&InstanceScore| {
                r.fitted_add_mm
                    .is_some_and(|d| d < ADD_FRACTION * p.object.diameter_mm)
            };
            rows.iter().filter(under).count() as f64 / fitted_rows
        }),
        median_fitted_translation_error_mm: (!fitted.is_empty()).then(|| median(&mut fitted)),
        refined_acc_15_or_vsd: refined
            .map(|_| share(&|r| true_pose(r.refined_rotation_error_deg, r.refined_vsd))),
        median_refined_rotation_error_deg: refined
            .filter(|_| !refined_rotations.is_empty())
            .map(|_| median(&mut refined_rotations)),
        median_refined_translation_error_mm: refined
            .filter(|_| !refined_translations.is_empty())
            .map(|_| median(&mut refined_translations)),
        refined_add_accuracy: refined.map(|object| {
            share(&|r| {
                r.refined_add_mm
                    .is_some_and(|d| d < ADD_FRACTION * object.diameter_mm)
            })
        }),
    }
}

/// The instances and their summary as a Markdown table, under a heading naming `what`.
pub fn markdown(what: &str, rows: &[InstanceScore], accuracy: &Accuracy) -> String {
    let columns = Columns::of(accuracy);
    let mut out = format!("## {what}\n\n");
    columns.write_header(&mut out);
    for row in rows {
        columns.write_row(&mut out, row);
    }
    columns.write_summary(&mut out, accuracy);
    out
}

/// Which of the table's optional column groups a run has: the pose's (its ADD(-S) metric's
/// name) with or without the translation fitted to depth, and the refined pose's.
struct Columns<'a> {
    pose: Option<&'a str>,
    fitted: bool,
    refined: Option<&'a str>,
}

/// A value with one decimal, or a dash for none.
fn one_decimal(value: Option<f64>) -> String {
    value.map_or("—".to_string(), |v| format!("{v:.1}"))
}

impl<'a> Columns<'a> {
    fn of(accuracy: &'a Accuracy) -> Self {
        Self {
            pose: accuracy
                .median_translation_error_mm
                .and(accuracy.add_metric.as_deref()),
            fitted: accuracy.median_fitted_translation_error_mm.is_some(),
            refined: accuracy
                .refined_acc_15_or_vsd
                .and(accuracy.add_metric.as_deref()),
        }
    }

    /// The header line and the rule under it.
    fn write_header(&self, out: &mut String) {
        out.push_str(
            "| scene | image | instance | visible | rotation error (°) | VSD | LLH | MAAD (°) | Recall MAAD (°) |",
        );
        let mut rule = String::from("|---|---|---|---|---|---|---|---|---|");
        if let Some(metric) = self.pose {
            let _ = write!(out, " translation error (mm) | {metric} (mm) |");
            rule.push_str("---|---|");
            if self.fitted {
                let _ = write!(
                    out,
                    " translation fitted to depth: error (mm) | its {metric} (mm) |"
                );
                rule.push_str("---|---|");
            }
        }
        if let Some(metric) = self.refined {
            let _ = write!(
                out,
                " refined with depth: rotation error (°) | its VSD | translation error (mm) | its {metric} (mm) |"
            );
            rule.push_str("---|---|---|---|");
        }
        let _ = writeln!(out, "\n{rule}");
    }

    /// One instance's line.
    fn write_row(&self, out: &mut String, r: &InstanceScore) {
        let visible = r
            .visib_fract
            .map_or("—".to_string(), |v| format!("{:.0}%", 100.0 * v));
        let vsd = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.2}"));
        let _ = write!(
            out,
            "| {} | {} | {} | {visible} | {:.1} | {} | {:.2} | {:.1} | {:.1} |",
            r.scene_id,
            r.im_id,
            r.instance,
            r.rotation_error_deg,
            vsd(r.vsd),
            r.llh,
            r.maad_deg,
            r.recall_maad_deg
        );
        if self.pose.is_some() {
            let (t, add) = (r.translation_error_mm, r.add_mm);
            let _ = write!(out, " {} | {} |", one_decimal(t), one_decimal(add));
            if self.fitted {
                let (t, add) = (r.fitted_translation_error_mm, r.fitted_add_mm);
                let _ = write!(out, " {} | {} |", one_decimal(t), one_decimal(add));
            }
        }
        if self.refined.is_some() {
            let _ = write!(
                out,
                " {} | {} | {} | {} |",
                one_decimal(r.refined_rotation_error_deg),
                vsd(r.refined_vsd),
                one_decimal(r.refined_translation_error_mm),
                one_decimal(r.refined_add_mm)
            );
        }
        out.push('\n');
    }

    /// The summary sentence under the table.
    fn write_summary(&self, out: &mut String, a: &Accuracy) {
        let _ = write!(
            out,
            "\n{} instances (visible fraction ≥ {}): Acc@15° {:.0}%, Acc@30° {:.0}%, median rotation \
             error {:.1}°, truth denser than uniform (LLH > {:.2}) for {:.0}%",
            a.instances,
            a.min_visib,
            100.0 * a.acc_15,
            100.0 * a.acc_30,
            a.median_rotation_error_deg,
            a.uniform_llh,
            100.0 * a.above_uniform
        );
        if let Some(share) = a.acc_15_or_vsd {
            let _ = write!(
                out,
                "; a true pose (under 15° or VSD under {VSD_CORRECT}) for {:.0}%",
                100.0 * share
            );
        }
        if let (Some(metric), Some(share), Some(t)) =
            (self.pose, a.add_accuracy, a.median_translation_error_mm)
        {
            let _ = write!(
                out,
                "; {metric} under 10% of the diameter {:.0}%, median translation error {t:.1} mm",
                100.0 * share
            );
        }
        if let (Some(metric), Some(share), Some(t)) = (
            self.pose,
            a.fitted_add_accuracy,
            a.median_fitted_translation_error_mm,
        ) {
            let _ = write!(
                out,
                "; with the translation fitted to depth, {metric} under 10% of the diameter \
                 {:.0}%, median translation error {t:.1} mm",
                100.0 * share
            );
        }
        if let (Some(metric), Some(share), Some(add_share)) = (
            self.refined,
            a.refined_acc_15_or_vsd,
            a.refined_add_accuracy,
        ) {
            let median_of =
                |v: Option<f64>, unit: &str| v.map_or("—".into(), |v| format!("{v:.1}{unit}"));
            let _ = write!(
                out,
                "; refined with depth from the rotation model's hypotheses, a true pose for \
                 {:.0}%, median rotation error {}, median translation error {}, {metric} under \
                 10% of the diameter {:.0}%",
                100.0 * share,
                median_of(a.median_refined_rotation_error_deg, "°"),
                median_of(a.median_refined_translation_error_mm, " mm"),
                100.0 * add_share
            );
        }
        out.push_str(".\n");
    }
}
