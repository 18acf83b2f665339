//! The per-scene JSON files: `scene_camera.json`, `scene_gt.json`, `scene_gt_info.json`.
use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::FileError;
use crate::json::{
    Intrinsics, entries_by_id, id_at, intrinsics_from_json, number, numbers_at, pose_from_json,
    pose_to_json, read_json, write_json_by_id,
};

/// One object instance of `scene_gt.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct GtInstance {
    /// The object's id (`models/obj_NNNNNN.ply`).
    pub obj_id: u32,
    /// Model→camera pose (metres).
    pub pose: Isometry3<f64>,
}

/// One instance of `scene_gt_info.json`: boxes are `[x, y, width, height]` in pixels
/// (`[-1, -1, -1, -1]` when empty, as in BOP).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtInfo {
    /// Box of the full silhouette (also where occluded).
    pub bbox_obj: [i64; 4],
    /// Box of the visible part.
    pub bbox_visib: [i64; 4],
    /// Pixels of the full silhouette.
    pub px_count_all: u64,
    /// Pixels of the full silhouette with a depth reading.
    pub px_count_valid: u64,
    /// Visible pixels with a depth reading.
    pub px_count_visib: u64,
    /// `px_count_visib / px_count_all` (0 for an empty silhouette).
    pub visib_fract: f64,
}

/// Reads `scene_camera.json`: image id → intrinsics and depth scale.
pub fn read_scene_camera(path: &Path) -> Result<BTreeMap<u32, Intrinsics>, FileError> {
    let value = read_json(path)?;
    entries_by_id(&value, path)?
        .into_iter()
        .map(|(im_id, entry)| {
            Ok((
                im_id,
                intrinsics_from_json(entry, path, &format!("{im_id}."))?,
            ))
        })
        .collect()
}

/// Writes `scene_camera.json` atomically.
pub fn write_scene_camera(
    path: &Path,
    cameras: &BTreeMap<u32, Intrinsics>,
) -> Result<(), FileError> {
    write_json_by_id(
        path,
        &cameras.iter().map(|(&id, c)| (id, c.to_json())).collect(),
    )
}

/// One image's instances, each with its key prefix for errors (`"12[0]."`).
type Instances<'a> = Vec<(String, &'a Value)>;

/// The list under each image id of a per-image file.
fn instance_lists<'a>(
    value: &'a Value,
    path: &Path,
) -> Result<Vec<(u32, Instances<'a>)>, FileError> {
    entries_by_id(value, path)?
        .into_iter()
        .map(|(im_id, entry)| {
            let list = entry.as_array().ok_or_else(|| {
                FileError::new(path, im_id.to_string(), "expected a list of instances")
            })?;
            let items = list
                .iter()
                .enumerate()
                .map(|(k, item)| (format!("{im_id}[{k}]."), item))
                .collect();
            Ok((im_id, items))
        })
        .collect()
}

/// Reads `scene_gt.json`: image id → its instances in mask order. Rotations orthonormal only to
/// published precision are read as their nearest rotations
/// ([`so3_grid::rotation_from_matrix`]); [`read_scene_gt_repaired`] counts them.
pub fn read_scene_gt(path: &Path) -> Result<BTreeMap<u32, Vec<GtInstance>>, FileError> {
    Ok(read_scene_gt_repaired(path)?.0)
}

/// The rotations of pose files that were orthonormal only to published precision (beyond
/// [`so3_grid::ORTHONORMALITY_TOLERANCE`]) and were read as their nearest rotations.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RotationRepairs {
    /// Rotations repaired.
    pub count: usize,
    /// The largest |RᵀR − I| entry among them.
    pub worst_orthogonality_error: f64,
    /// The file and field of the worst one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_at: Option<String>,
}

impl RotationRepairs {
    /// Adds the repairs of `other` (another file).
    pub fn merge(&mut self, other: &Self) {
        self.count += other.count;
        if other.worst_orthogonality_error > self.worst_orthogonality_error {
            self.worst_orthogonality_error = other.worst_orthogonality_error;
            self.worst_at.clone_from(&other.worst_at);
        }
    }

    /// Whether nothing was repaired.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// One line saying what was repaired, `None` when nothing was.
    pub fn note(&self) -> Option<String> {
        (!self.is_empty()).then(|| {
            format!(
                "{} ground-truth rotation(s) orthonormal only to |RᵀR − I| ≤ {:.1e} (worst: {}) \
                 read as their nearest rotations",
                self.count,
                self.worst_orthogonality_error,
                self.worst_at.as_deref().unwrap_or("?")
            )
        })
    }

    /// Counts a rotation whose |RᵀR − I| is `error` when it was repaired; `at` names it.
    fn add(&mut self, error: f64, at: impl FnOnce() -> String) {
        if error > so3_grid::ORTHONORMALITY_TOLERANCE {
            self.merge(&Self {
                count: 1,
                worst_orthogonality_error: error,
                worst_at: Some(at()),
            });
        }
    }
}

/// [`read_scene_gt`], and the rotations it read as their nearest rotations.
pub fn read_scene_gt_repaired(
    path: &Path,
) -> Result<(BTreeMap<u32, Vec<GtInstance>>, RotationRepairs), FileError> {
    let value = read_json(path)?;
    let mut repairs = RotationRepairs::default();
    let gt = instance_lists(&value, path)?
        .into_iter()
        .map(|(im_id, items)| {
            let instances = items
                .into_iter()
                .map(|(prefix, item)| {
                    let pose = pose_from_json(item, path, &prefix)?;
                    let matrix: [f64; 9] = numbers_at(item, "cam_R_m2c", path, &prefix)?;
                    let at = || format!("{}: {prefix}cam_R_m2c", path.display());
                    repairs.add(so3_grid::orthogonality_error(&matrix), at);
                    Ok(GtInstance {
                        obj_id: id_at(item, "obj_id", path, &prefix)?,
                        pose,
                    })
                })
                .collect::<Result<_, FileError>>()?;
            Ok((im_id, instances))
        })
        .collect::<Result<_, FileError>>()?;
    Ok((gt, repairs))
}

/// Reads only the `obj_id` of every instance of `scene_gt.json` (the labelling never reads
/// the poses).
pub fn read_object_ids(path: &Path) -> Result<BTreeMap<u32, Vec<u32>>, FileError> {
    let value = read_json(path)?;
    instance_lists(&value, path)?
        .into_iter()
        .map(|(im_id, items)| {
            let ids = items
                .into_iter()
                .map(|(prefix, item)| id_at(item, "obj_id", path, &prefix))
                .collect::<Result<_, FileError>>()?;
            Ok((im_id, ids))
        })
        .collect()
}

/// Writes `scene_gt.json` atomically.
pub fn write_scene_gt(path: &Path, gt: &BTreeMap<u32, Vec<GtInstance>>) -> Result<(), FileError> {
    let entries = gt
        .iter()
        .map(|(&id, instances)| {
            let list: Vec<Value> = instances
                .iter()
                .map(|instance| {
                    let mut entry = pose_to_json(&instance.pose);
                    entry["obj_id"] = json!(instance.obj_id);
                    entry
                })
                .collect();
            (id, Value::from(list))
        })
        .collect();
    write_json_by_id(path, &entries)
}

/// Reads `scene_gt_info.json`: image id → one entry per instance.
pub fn read_scene_gt_info(path: &Path) -> Result<BTreeMap<u32, Vec<GtInfo>>, FileError> {
    let value = read_json(path)?;
    instance_lists(&value, path)?
        .into_iter()
        .map(|(im_id, items)| {
            let infos = items
                .into_iter()
                .map(|(prefix, item)| {
                    let bbox = |key: &str| -> Result<[i64; 4], FileError> {
                        Ok(numbers_at::<4>(item, key, path, &prefix)?.map(|v| v as i64))
                    };
                    let count = |key: &str| -> Result<u64, FileError> {
                        Ok(id_at(item, key, path, &prefix)?.into())
                    };
                    Ok(GtInfo {
                        bbox_obj: bbox("bbox_obj")?,
                        bbox_visib: bbox("bbox_visib")?,
                        px_count_all: count("px_count_all")?,
                        px_count_valid: count("px_count_valid")?,
                        px_count_visib: count("px_count_visib")?,
                        visib_fract: number(item, "visib_fract", path, &prefix)?,
                    })
                })
                .collect::<Result<_, FileError>>()?;
            Ok((im_id, infos))
        })
        .collect()
}

/// Writes `scene_gt_info.json` atomically.
pub fn write_scene_gt_info(
    path: &Path,
    info: &BTreeMap<u32, Vec<GtInfo>>,
) -> Result<(), FileError> {
    let entries = info
        .iter()
        .map(|(&id, infos)| {
            let list: Vec<Value> = infos
                .iter()
                .map(|i| {
                    json!({
                        "bbox_obj": i.bbox_obj, "bbox_visib": i.bbox_visib,
                        "px_count_all": i.px_count_all, "px_count_valid": i.px_count_valid,
                        "px_count_visib": i.px_count_visib, "visib_fract": i.visib_fract,
                    })
                })
                .collect();
            (id, Value::from(list))
        })
        .collect();
    write_json_by_id(path, &entries)
}
