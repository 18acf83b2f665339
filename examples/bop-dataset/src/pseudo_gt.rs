//! `scene_pseudo_gt.json`: the pseudo ground-truth pose sets of `ipdf label`, keyed like
//! `scene_gt.json` (image id → instances in mask order):
//! `{"obj_id": 1, "labels": [{"cam_R_m2c": [9], "cam_t_m2c": [3], "score": s}, …]}`, plus an
//! `"error"` string where labelling the instance failed and a `"warning"` where it succeeded
//! with a doubt (e.g. an observed cloud larger than the model).
use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use serde_json::{Value, json};

use crate::FileError;
use crate::json::{
    entries_by_id, id_at, number, pose_from_json, pose_to_json, read_json, write_json_by_id,
};

/// One pseudo label: a pose and its render-and-compare score.
#[derive(Debug, Clone, PartialEq)]
pub struct PseudoLabel {
    /// Model→camera pose (metres).
    pub pose: Isometry3<f64>,
    /// Render-and-compare score: the mean per-pixel depth difference in units of the sensor's
    /// expected error (lower is better; about 0.8 for the true pose on the sensor's noise).
    pub score: f64,
}

/// The pseudo labels of one object instance.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PseudoInstance {
    /// The object's id.
    pub obj_id: u32,
    /// The pose set, best score first (empty when labelling failed).
    pub labels: Vec<PseudoLabel>,
    /// Why labelling failed.
    pub error: Option<String>,
    /// A doubt about a labelled instance.
    pub warning: Option<String>,
    /// For an instance whose poses all scored above the threshold: the best of them, for
    /// inspection (`"best"` beside `"error"`).
    pub best: Option<PseudoLabel>,
}

/// Reads `scene_pseudo_gt.json`.
pub fn read_pseudo_gt(path: &Path) -> Result<BTreeMap<u32, Vec<PseudoInstance>>, FileError> {
    let value = read_json(path)?;
    let text = |item: &Value, key: &str, prefix: &str| -> Result<Option<String>, FileError> {
        match item.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => Err(FileError::new(
                path,
                format!("{prefix}{key}"),
                "expected a string",
            )),
        }
    };
    entries_by_id(&value, path)?
        .into_iter()
        .map(|(im_id, entry)| {
            let list = entry.as_array().ok_or_else(|| {
                FileError::new(path, im_id.to_string(), "expected a list of instances")
            })?;
            let instances = list
                .iter()
                .enumerate()
                .map(|(k, item)| {
                    let prefix = format!("{im_id}[{k}].");
                    let labels = item
                        .get("labels")
                        .and_then(Value::as_array)
                        .ok_or_else(|| {
                            FileError::new(path, format!("{prefix}labels"), "expected a list")
                        })?
                        .iter()
                        .enumerate()
                        .map(|(j, label)| read_label(label, path, &format!("{prefix}labels[{j}].")))
                        .collect::<Result<_, FileError>>()?;
                    let best = match item.get("best") {
                        None | Some(Value::Null) => None,
                        Some(best) => Some(read_label(best, path, &format!("{prefix}best."))?),
                    };
                    Ok(PseudoInstance {
                        obj_id: id_at(item, "obj_id", path, &prefix)?,
                        labels,
                        error: text(item, "error", &prefix)?,
                        warning: text(item, "warning", &prefix)?,
                        best,
                    })
                })
                .collect::<Result<_, FileError>>()?;
            Ok((im_id, instances))
        })
        .collect()
}

/// Writes `scene_pseudo_gt.json` atomically (a killed run leaves the old file or none).
pub fn write_pseudo_gt(
    path: &Path,
    labels: &BTreeMap<u32, Vec<PseudoInstance>>,
) -> Result<(), FileError> {
    let entries = labels
        .iter()
        .map(|(&id, instances)| {
            let list: Vec<Value> = instances
                .iter()
                .map(|instance| {
                    let labels: Vec<Value> = instance.labels.iter().map(label_to_json).collect();
                    let mut entry = json!({"obj_id": instance.obj_id, "labels": labels});
                    if let Some(best) = &instance.best {
                        entry["best"] = label_to_json(best);
                    }
                    if let Some(error) = &instance.error {
                        entry["error"] = json!(error);
                    }
                    if let Some(warning) = &instance.warning {
                        entry["warning"] = json!(warning);
                    }
                    entry
                })
                .collect();
            (id, Value::from(list))
        })
        .collect();
    write_json_by_id(path, &entries)
}

/// `{"cam_R_m2c", "cam_t_m2c", "score"}` of `label`.
fn label_to_json(label: &PseudoLabel) -> Value {
    let mut entry = pose_to_json(&label.pose);
    entry["score"] = json!(label.score);
    entry
}

/// A label's pose and score from `value`, fields named after `prefix`.
fn read_label(value: &Value, path: &Path, prefix: &str) -> Result<PseudoLabel, FileError> {
    Ok(PseudoLabel {
        pose: pose_from_json(value, path, prefix)?,
        score: number(value, "score", path, prefix)?,
    })
}
