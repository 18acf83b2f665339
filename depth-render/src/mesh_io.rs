//! Loading meshes from PLY (ASCII or binary, any polygon size; BOP's `models/obj_*.ply`) and
//! OBJ files, with a scale to metres (BOP meshes are in millimetres: `scale = 0.001`).
use std::path::{Path, PathBuf};

use nalgebra::Point3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use crate::{RenderError, TriangleMesh};

/// Loads a `.ply` or `.obj` mesh and multiplies its coordinates by `scale`.
///
/// Polygons are triangulated as fans. Every failure names the file and the element or field:
/// unreadable or truncated files, missing `x`/`y`/`z` or face indices, non-finite coordinates,
/// indices out of range, zero-area faces.
pub fn load_mesh(path: &Path, scale: f64) -> Result<TriangleMesh, RenderError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(file_error(
            path,
            "scale",
            format!("must be positive, got {scale}"),
        ));
    }
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let (positions, polygons) = match extension.as_deref() {
        Some("ply") => read_ply(path)?,
        Some("obj") => read_obj(path)?,
        _ => {
            return Err(file_error(
                path,
                "extension",
                "expected .ply or .obj".into(),
            ));
        }
    };
    let positions = positions
        .iter()
        .map(|p| (p * scale).cast::<f32>())
        .collect();
    let mut triangles = Vec::new();
    let mut face_of_triangle = Vec::new();
    for (face, polygon) in polygons.iter().enumerate() {
        if polygon.len() < 3 {
            return Err(file_error(
                path,
                &format!("face[{face}]"),
                format!("has {} vertices", polygon.len()),
            ));
        }
        for k in 1..polygon.len() - 1 {
            triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
            face_of_triangle.push(face);
        }
    }
    TriangleMesh::new(positions, triangles).map_err(|error| {
        let field = match &error {
            RenderError::NonFiniteVertex { vertex } => format!("vertex[{vertex}]"),
            RenderError::IndexOutOfRange { triangle, .. }
            | RenderError::DegenerateTriangle { triangle } => {
                format!("face[{}]", face_of_triangle[*triangle])
            }
            _ => "mesh".into(),
        };
        file_error(path, &field, error.to_string())
    })
}

type Polygons = Vec<Vec<u32>>;

fn read_ply(path: &Path) -> Result<(Vec<Point3<f64>>, Polygons), RenderError> {
    let mut file =
        std::fs::File::open(path).map_err(|e| file_error(path, "file", e.to_string()))?;
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut file)
        .map_err(|e| file_error(path, "file", format!("not a readable PLY: {e}")))?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| file_error(path, "vertex", "missing".into()))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, vertex) in vertices.iter().enumerate() {
        let coordinate = |key: &str| {
            vertex.get(key).and_then(scalar).ok_or_else(|| {
                file_error(
                    path,
                    &format!("vertex[{i}].{key}"),
                    "missing or not a number".into(),
                )
            })
        };
        positions.push(Point3::new(
            coordinate("x")?,
            coordinate("y")?,
            coordinate("z")?,
        ));
    }
    let faces = ply
        .payload
        .get("face")
        .ok_or_else(|| file_error(path, "face", "missing".into()))?;
    let mut polygons = Vec::with_capacity(faces.len());
    for (i, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"));
        let indices = list.and_then(index_list).ok_or_else(|| {
            file_error(
                path,
                &format!("face[{i}].vertex_indices"),
                "missing or not a list of indices".into(),
            )
        })?;
        polygons.push(indices);
    }
    Ok((positions, polygons))
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

fn index_list(property: &Property) -> Option<Vec<u32>> {
    fn non_negative<T: TryInto<u32> + Copy>(values: &[T]) -> Option<Vec<u32>> {
        values.iter().map(|&v| v.try_into().ok()).collect()
    }
    match property {
        Property::ListChar(v) => non_negative(v),
        Property::ListUChar(v) => non_negative(v),
        Property::ListShort(v) => non_negative(v),
        Property::ListUShort(v) => non_negative(v),
        Property::ListInt(v) => non_negative(v),
        Property::ListUInt(v) => Some(v.clone()),
        _ => None,
    }
}

fn read_obj(path: &Path) -> Result<(Vec<Point3<f64>>, Polygons), RenderError> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: false,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj(path, &options)
        .map_err(|e| file_error(path, "file", format!("not a readable OBJ: {e}")))?;
    let mut positions = Vec::new();
    let mut polygons = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let offset = positions.len() as u32;
        positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Point3::new(p[0], p[1], p[2]).cast::<f64>()),
        );
        let mut start = 0usize;
        let arities: Vec<usize> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.iter().map(|&a| a as usize).collect()
        };
        for arity in arities {
            let face = mesh.indices.get(start..start + arity).ok_or_else(|| {
                file_error(
                    path,
                    &format!("{}.f", model.name),
                    "face indices are truncated".into(),
                )
            })?;
            polygons.push(face.iter().map(|&i| i + offset).collect());
            start += arity;
        }
    }
    Ok((positions, polygons))
}

fn file_error(path: &Path, field: &str, reason: String) -> RenderError {
    RenderError::MeshFile {
        path: PathBuf::from(path),
        field: field.to_string(),
        reason,
    }
}
