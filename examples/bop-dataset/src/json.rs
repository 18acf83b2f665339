//! BOP's JSON conventions: intrinsics (`cam_K`, row-major 3×3, with `width`/`height` or BOP's
//! dataset-level `camera.json` keys `fx fy cx cy width height`), `depth_scale` (mm per depth
//! unit) and model→camera poses (`cam_R_m2c` row-major 3×3, `cam_t_m2c` in mm). Poses are
//! returned in metres.
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use depth_render::PinholeCamera;
use nalgebra::{Isometry3, Translation3};
use serde_json::Value;

use crate::FileError;
use crate::atomic::write_atomically;

/// Reads and parses a JSON file.
pub fn read_json(path: &Path) -> Result<Value, FileError> {
    let text =
        std::fs::read_to_string(path).map_err(|e| FileError::new(path, "file", e.to_string()))?;
    serde_json::from_str(&text)
        .map_err(|e| FileError::new(path, "file", format!("not valid JSON: {e}")))
}

/// Reads a JSON file into `T`; a mismatch names the file and, in serde's words, the field.
pub fn read_json_as<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, FileError> {
    let text =
        std::fs::read_to_string(path).map_err(|e| FileError::new(path, "file", e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| FileError::new(path, "file", e.to_string()))
}

/// A camera and the scale of its depth images.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BopCamera {
    /// Intrinsics and image size.
    pub camera: PinholeCamera,
    /// Millimetres per unit of the depth PNGs (1.0 when absent).
    pub depth_scale: f64,
}

impl BopCamera {
    /// Writes the camera as BOP's dataset-level `camera.json` (`fx fy cx cy width height
    /// depth_scale`), atomically; [`camera_from_json`] reads it back.
    pub fn write(&self, path: &Path) -> Result<(), FileError> {
        let c = &self.camera;
        let entry = serde_json::json!({
            "cx": c.cx, "cy": c.cy, "depth_scale": self.depth_scale, "fx": c.fx, "fy": c.fy,
            "height": c.height, "width": c.width,
        });
        crate::write_json(path, &entry)
    }
}

/// Intrinsics without an image size, as BOP's per-image `scene_camera.json` entries give them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal lengths and principal point (pixels).
    pub fx: f64,
    /// See `fx`.
    pub fy: f64,
    /// See `fx`.
    pub cx: f64,
    /// See `fx`.
    pub cy: f64,
    /// Millimetres per unit of the depth PNGs (1.0 when absent).
    pub depth_scale: f64,
}

impl Intrinsics {
    /// The camera of an image of `width × height` pixels.
    pub fn camera(&self, width: u32, height: u32) -> Result<BopCamera, depth_render::RenderError> {
        Ok(BopCamera {
            camera: PinholeCamera::new(self.fx, self.fy, self.cx, self.cy, width, height)?,
            depth_scale: self.depth_scale,
        })
    }

    /// The BOP JSON of these intrinsics (`cam_K`, `depth_scale`).
    pub fn to_json(&self) -> Value {
        serde_json::json!({
            "cam_K": [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0],
            "depth_scale": self.depth_scale,
        })
    }
}

/// Parses intrinsics from `value` (an object of `path`; `prefix` names where it sits in the
/// file, e.g. `"12."` for an entry of `scene_camera.json`): `cam_K` or BOP's dataset-level
/// `fx fy cx cy`, and `depth_scale`.
pub fn intrinsics_from_json(
    value: &Value,
    path: &Path,
    prefix: &str,
) -> Result<Intrinsics, FileError> {
    let (fx, fy, cx, cy) = match value.get("cam_K") {
        Some(k) => {
            let k: [f64; 9] = numbers(k, path, &format!("{prefix}cam_K"))?;
            (k[0], k[4], k[2], k[5])
        }
        None => (
            number(value, "fx", path, prefix)?,
            number(value, "fy", path, prefix)?,
            number(value, "cx", path, prefix)?,
            number(value, "cy", path, prefix)?,
        ),
    };
    let depth_scale = match value.get("depth_scale") {
        None => 1.0,
        Some(_) => number(value, "depth_scale", path, prefix)?,
    };
    if depth_scale <= 0.0 {
        return Err(FileError::new(
            path,
            format!("{prefix}depth_scale"),
            format!("{depth_scale} is not positive"),
        ));
    }
    Ok(Intrinsics {
        fx,
        fy,
        cx,
        cy,
        depth_scale,
    })
}

/// Parses a camera from `value` (`cam_K` or `fx fy cx cy`, and `depth_scale`). `size` supplies width and
/// height when the object has none (BOP's per-image entries).
pub fn camera_from_json(
    value: &Value,
    path: &Path,
    prefix: &str,
    size: Option<(u32, u32)>,
) -> Result<BopCamera, FileError> {
    let intrinsics = intrinsics_from_json(value, path, prefix)?;
    let dimension = |key: &str| -> Result<u32, FileError> {
        let v = number(value, key, path, prefix)?;
        if v.fract() != 0.0 || !(1.0..=65_535.0).contains(&v) {
            return Err(FileError::new(
                path,
                format!("{prefix}{key}"),
                format!("{v} is not an image size"),
            ));
        }
        Ok(v as u32)
    };
    let (width, height) = match (value.get("width"), value.get("height"), size) {
        (None, None, Some(size)) => size,
        _ => (dimension("width")?, dimension("height")?),
    };
    intrinsics
        .camera(width, height)
        .map_err(|e| FileError::new(path, format!("{prefix}cam_K"), e.to_string()))
}

/// Parses a model→camera pose (metres) from `cam_R_m2c` and `cam_t_m2c` (mm) of `value`.
pub fn pose_from_json(
    value: &Value,
    path: &Path,
    prefix: &str,
) -> Result<Isometry3<f64>, FileError> {
    let r: [f64; 9] = numbers_at(value, "cam_R_m2c", path, prefix)?;
    let rotation = so3_grid::rotation_from_matrix(&r)
        .map_err(|e| FileError::new(path, format!("{prefix}cam_R_m2c"), e.to_string()))?;
    let t: [f64; 3] = numbers_at(value, "cam_t_m2c", path, prefix)?;
    Ok(Isometry3::from_parts(
        Translation3::new(t[0] * 1e-3, t[1] * 1e-3, t[2] * 1e-3),
        rotation,
    ))
}

/// The BOP JSON of a model→camera pose given in metres.
pub fn pose_to_json(pose: &Isometry3<f64>) -> Value {
    let r = so3_grid::rotation_to_matrix(&pose.rotation);
    let t = pose.translation.vector * 1e3;
    serde_json::json!({"cam_R_m2c": r, "cam_t_m2c": [t.x, t.y, t.z]})
}

/// Writes a BOP per-image file (`scene_gt.json`, `scene_camera.json`, …) atomically: one line
/// per image id, in numeric order, as the BOP toolkit does.
pub fn write_json_by_id(path: &Path, entries: &BTreeMap<u32, Value>) -> Result<(), FileError> {
    write_atomically(path, |out| {
        out.write_all(b"{")?;
        for (i, (id, value)) in entries.iter().enumerate() {
            let separator = if i == 0 { "\n" } else { ",\n" };
            write!(out, "{separator}  \"{id}\": {value}")?;
        }
        out.write_all(b"\n}\n")
    })
}

/// The entries of a JSON object keyed by non-negative integer ids (image or object ids), in
/// numeric order; a key that is not an id is an error naming it.
pub fn entries_by_id<'a>(
    value: &'a Value,
    path: &Path,
) -> Result<BTreeMap<u32, &'a Value>, FileError> {
    let object = value
        .as_object()
        .ok_or_else(|| FileError::new(path, "file", "expected a JSON object keyed by id"))?;
    object
        .iter()
        .map(|(key, entry)| {
            let id = key
                .parse::<u32>()
                .map_err(|_| FileError::new(path, key.as_str(), "key is not an integer id"))?;
            Ok((id, entry))
        })
        .collect()
}

/// The non-negative integer under `key` of `value`.
pub fn id_at(value: &Value, key: &str, path: &Path, prefix: &str) -> Result<u32, FileError> {
    let v = number(value, key, path, prefix)?;
    if v.fract() != 0.0 || !(0.0..=f64::from(u32::MAX)).contains(&v) {
        return Err(FileError::new(
            path,
            format!("{prefix}{key}"),
            format!("{v} is not an integer id"),
        ));
    }
    Ok(v as u32)
}

/// The finite number under `key` of `value`.
pub fn number(value: &Value, key: &str, path: &Path, prefix: &str) -> Result<f64, FileError> {
    let field = format!("{prefix}{key}");
    let v = value
        .get(key)
        .ok_or_else(|| FileError::new(path, &field, "missing"))?;
    v.as_f64()
        .filter(|v| v.is_finite())
        .ok_or_else(|| FileError::new(path, &field, format!("{v} is not a finite number")))
}

/// The list of `N` finite numbers under `key` of `value`.
pub fn numbers_at<const N: usize>(
    value: &Value,
    key: &str,
    path: &Path,
    prefix: &str,
) -> Result<[f64; N], FileError> {
    let field = format!("{prefix}{key}");
    let list = value
        .get(key)
        .ok_or_else(|| FileError::new(path, &field, "missing"))?;
    numbers(list, path, &field)
}

fn numbers<const N: usize>(value: &Value, path: &Path, field: &str) -> Result<[f64; N], FileError> {
    let list = value
        .as_array()
        .filter(|a| a.len() == N)
        .ok_or_else(|| FileError::new(path, field, format!("expected a list of {N} numbers")))?;
    let mut out = [0.0; N];
    for (i, (slot, v)) in out.iter_mut().zip(list).enumerate() {
        *slot = v.as_f64().filter(|v| v.is_finite()).ok_or_else(|| {
            FileError::new(
                path,
                format!("{field}[{i}]"),
                format!("{v} is not a finite number"),
            )
        })?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    #[test]
    fn poses_round_trip_through_bop_json_in_millimetres() {
        let pose = Isometry3::from_parts(
            Translation3::new(0.01, -0.2, 0.75),
            UnitQuaternion::from_euler_angles(0.3, -1.2, 2.5),
        );
        let value = pose_to_json(&pose);
        assert!((value["cam_t_m2c"][2].as_f64().unwrap() - 750.0).abs() < 1e-9);
        let back = pose_from_json(&value, Path::new("p.json"), "").unwrap();
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-9);
    }

    #[test]
    fn cameras_read_cam_k_or_bop_camera_json_keys() {
        let path = Path::new("c.json");
        let k =
            serde_json::json!({"cam_K": [600, 0, 320, 0, 610, 240, 0, 0, 1], "depth_scale": 0.1});
        let bop = camera_from_json(&k, path, "3.", Some((640, 480))).unwrap();
        assert_eq!(
            (bop.camera.fy, bop.camera.width, bop.depth_scale),
            (610.0, 640, 0.1)
        );
        let keys = serde_json::json!({"fx": 1075.65, "fy": 1073.9, "cx": 320, "cy": 240, "width": 640, "height": 480});
        assert_eq!(
            camera_from_json(&keys, path, "", None).unwrap().camera.fx,
            1075.65
        );
        let error = camera_from_json(&k, path, "3.", None).unwrap_err();
        assert_eq!(error.field, "3.width");
    }

    #[test]
    fn a_written_dataset_camera_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("camera.json");
        let intrinsics = Intrinsics {
            fx: 1075.65,
            fy: 1073.9,
            cx: 321.5,
            cy: 239.25,
            depth_scale: 0.1,
        };
        let camera = intrinsics.camera(640, 480).unwrap();
        camera.write(&path).unwrap();
        let back = camera_from_json(&read_json(&path).unwrap(), &path, "", None).unwrap();
        assert_eq!(back, camera);
    }
}
