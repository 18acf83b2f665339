//! Point clouds from and to PLY files (`vertex` elements with `x y z`, optionally `nx ny nz`;
//! faces, colours and other properties are ignored, so a mesh file reads as its vertices).

use std::io::Write;
use std::path::Path;

use nalgebra::{Point3, Vector3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use crate::{PointCloud, RegistrationError};

fn file_error(
    path: &Path,
    field: impl Into<String>,
    reason: impl Into<String>,
) -> RegistrationError {
    RegistrationError::CloudFile {
        path: path.to_path_buf(),
        field: field.into(),
        reason: reason.into(),
    }
}

/// Reads the vertices (and normals, when every vertex has `nx ny nz`) of a PLY file (ASCII or
/// binary), multiplying coordinates by `scale` (0.001 for BOP's millimetre models).
///
/// Errors name the file and the field: a missing file, a malformed header or body, a missing
/// `vertex` element, a vertex without `x`, a NaN coordinate, a zero normal.
pub fn read_ply(path: &Path, scale: f64) -> Result<PointCloud, RegistrationError> {
    let mut file =
        std::fs::File::open(path).map_err(|e| file_error(path, "file", e.to_string()))?;
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut std::io::BufReader::new(&mut file))
        .map_err(|e| file_error(path, "file", format!("not a readable PLY: {e}")))?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| file_error(path, "vertex", "missing"))?;
    let has_normals = vertices.first().is_some_and(|v| v.contains_key("nx"));
    let mut points = Vec::with_capacity(vertices.len());
    let mut normals = Vec::with_capacity(if has_normals { vertices.len() } else { 0 });
    for (i, vertex) in vertices.iter().enumerate() {
        let value = |key: &str| {
            vertex
                .get(key)
                .and_then(scalar)
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    file_error(
                        path,
                        format!("vertex[{i}].{key}"),
                        "missing or not a finite number",
                    )
                })
        };
        points.push(
            Point3::new(
                value("x")? * scale,
                value("y")? * scale,
                value("z")? * scale,
            )
            .cast::<f32>(),
        );
        if has_normals {
            let normal = Vector3::new(value("nx")?, value("ny")?, value("nz")?);
            if normal.norm() == 0.0 {
                return Err(file_error(
                    path,
                    format!("vertex[{i}].nx"),
                    "zero-length normal",
                ));
            }
            normals.push(normal.cast::<f32>());
        }
    }
    let cloud = PointCloud::new(points).map_err(|e| file_error(path, "vertex", e.to_string()))?;
    if has_normals {
        cloud
            .with_normals(normals)
            .map_err(|e| file_error(path, "vertex", e.to_string()))
    } else {
        Ok(cloud)
    }
}

/// Writes `cloud` as a binary little-endian PLY (float `x y z`, and `nx ny nz` when it has
/// normals), atomically: a temporary file beside `path`, renamed over it when complete.
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<(), RegistrationError> {
    let io = |e: std::io::Error| file_error(path, "file", e.to_string());
    let mut bytes = Vec::with_capacity(64 + cloud.len() * 24);
    let normals = cloud.normals();
    write!(bytes, "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n", cloud.len())
        .map_err(io)?;
    if normals.is_some() {
        bytes.extend_from_slice(b"property float nx\nproperty float ny\nproperty float nz\n");
    }
    bytes.extend_from_slice(b"end_header\n");
    for (i, p) in cloud.points().iter().enumerate() {
        let mut push = |v: f32| bytes.extend_from_slice(&v.to_le_bytes());
        p.coords.iter().for_each(|&v| push(v));
        if let Some(normals) = normals {
            normals[i].iter().for_each(|&v| push(v));
        }
    }
    let directory = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| file_error(path, "file", "not a file name"))?;
    let temporary = directory.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&temporary, &bytes).map_err(io)?;
    std::fs::rename(&temporary, path).map_err(|e| {
        let _ = std::fs::remove_file(&temporary);
        io(e)
    })
}

fn scalar(property: &Property) -> Option<f64> {
    Some(match *property {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_with_and_without_normals() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cloud.ply");
        let cloud = PointCloud::new(vec![
            Point3::new(0.1, -0.2, 0.3),
            Point3::new(1.0, 2.0, 3.0),
        ])
        .unwrap();
        write_ply(&path, &cloud).unwrap();
        assert_eq!(read_ply(&path, 1.0).unwrap(), cloud);
        let with = cloud
            .with_normals(vec![Vector3::x(), Vector3::new(0.0, 0.6, 0.8)])
            .unwrap();
        write_ply(&path, &with).unwrap();
        assert_eq!(read_ply(&path, 1.0).unwrap(), with);
        let millimetres = read_ply(&path, 1000.0).unwrap();
        assert!((millimetres.points()[1].z - 3000.0).abs() < 1e-3);
    }

    #[test]
    fn malformed_files_name_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.ply");
        let header = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
        let mut binary = header.replace("ascii", "binary_little_endian").into_bytes();
        for value in [0f32, 0.0, 0.0, 1.0, f32::NAN, 1.0] {
            binary.extend_from_slice(&value.to_le_bytes());
        }
        std::fs::write(&path, binary).unwrap();
        let message = read_ply(&path, 1.0).unwrap_err().to_string();
        assert!(message.contains("vertex[1].y"), "{message}");
        std::fs::write(&path, format!("{header}0 0 0\n")).unwrap();
        let message = read_ply(&path, 1.0).unwrap_err().to_string();
        assert!(
            message.contains("bad.ply") && message.contains("file"),
            "{message}"
        );
        let with_normals = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n";
        std::fs::write(&path, format!("{with_normals}0 0 0 0 0 0\n")).unwrap();
        let message = read_ply(&path, 1.0).unwrap_err().to_string();
        assert!(
            message.contains("vertex[0].nx") && message.contains("zero-length"),
            "{message}"
        );
        let missing = read_ply(&dir.path().join("none.ply"), 1.0)
            .unwrap_err()
            .to_string();
        assert!(missing.contains("none.ply"), "{missing}");
        std::fs::write(&path, "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n").unwrap();
        let message = read_ply(&path, 1.0).unwrap_err().to_string();
        assert!(message.contains("vertex: missing"), "{message}");
    }
}
