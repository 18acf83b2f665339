//! Loading meshes from PLY (ASCII or binary, any polygon size; BOP's `models/obj_*.ply`) and
//! OBJ files, with a scale to metres (BOP meshes are in millimetres: `scale = 0.001`).
//! Per-vertex normals (`nx ny nz`, OBJ `vn`), colours (`red green blue`, OBJ `v x y z r g b`) and
//! texture coordinates (`s t`, `u v`, `texture_u texture_v`, OBJ `vt`) are kept when present,
//! and so is the name of the texture image they index (PLY's `comment TextureFile NAME`, as
//! MeshLab and BOP's textured models write it; the OBJ material's `map_Kd`).
//! The same reader gives the vertices alone ([`load_vertices`]: point clouds, a mesh's vertices),
//! and [`write_ply`] writes binary little-endian PLY of vertices, normals and faces.
use std::io::Write;
use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use crate::mesh_repair::{MeshParts, MeshRepairs, repair};
use crate::{RenderError, TriangleMesh};

/// A mesh read from a file, and what loading repaired in it.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedMesh {
    /// The mesh, repaired.
    pub mesh: TriangleMesh,
    /// What was repaired (see [`MeshRepairs`]).
    pub repairs: MeshRepairs,
    /// The texture image the file names, beside the mesh file (not opened here); named only
    /// where the mesh has texture coordinates.
    pub texture: Option<PathBuf>,
}

/// Loads a `.ply` or `.obj` mesh and multiplies its coordinates by `scale`.
///
/// Polygons are triangulated as fans. What scanned and exported meshes commonly get slightly
/// wrong is repaired and counted in [`LoadedMesh::repairs`]: zero-area triangles and vertices
/// no triangle uses are dropped, normals of zero length (or not finite) are recomputed. What
/// cannot be used is refused, naming the file and the element or field: unreadable or truncated
/// files, missing `x`/`y`/`z` or faces, non-finite coordinates or colours, indices out of range,
/// no triangle left after the repairs.
pub fn load_mesh(path: &Path, scale: f64) -> Result<LoadedMesh, RenderError> {
    check_scale(path, scale)?;
    let raw = read_raw(path)?;
    let Some(polygons) = &raw.polygons else {
        return Err(file_error(path, "face", "missing".into()));
    };
    let positions = scaled_positions(path, &raw.positions, scale)?;
    let triangles = triangulate(path, polygons, positions.len())?;
    let (parts, repairs, original_vertex) = repair(MeshParts {
        positions,
        triangles,
        normals: raw.normals,
        colors: raw.colors,
        uvs: raw.uvs,
    });
    if parts.triangles.is_empty() {
        return Err(file_error(
            path,
            "face",
            format!("no triangle of non-zero area ({repairs})"),
        ));
    }
    let mesh = mesh_from_parts(path, parts, &original_vertex)?;
    let texture = match (mesh.uvs(), raw.texture) {
        (Some(_), Some(name)) => Some(path.with_file_name(name)),
        _ => None,
    };
    Ok(LoadedMesh {
        mesh,
        repairs,
        texture,
    })
}

/// The file's vertex `positions` times `scale`, in f32; an error naming the first that is not
/// finite.
fn scaled_positions(
    path: &Path,
    positions: &[Point3<f64>],
    scale: f64,
) -> Result<Vec<Point3<f32>>, RenderError> {
    let positions: Vec<Point3<f32>> = positions
        .iter()
        .map(|p| (p * scale).cast::<f32>())
        .collect();
    if let Some(vertex) = positions
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        let error = RenderError::NonFiniteVertex { vertex };
        return Err(file_error(
            path,
            &format!("vertex[{vertex}]"),
            error.to_string(),
        ));
    }
    Ok(positions)
}

/// The `polygons` of a file with `vertices` vertices as fans of triangles; an error naming the
/// first face with fewer than 3 vertices or an index out of range.
fn triangulate(
    path: &Path,
    polygons: &[Vec<u32>],
    vertices: usize,
) -> Result<Vec<[u32; 3]>, RenderError> {
    let mut triangles = Vec::new();
    for (face, polygon) in polygons.iter().enumerate() {
        if polygon.len() < 3 {
            return Err(file_error(
                path,
                &format!("face[{face}]"),
                format!("has {} vertices", polygon.len()),
            ));
        }
        if let Some(&index) = polygon.iter().find(|&&i| i as usize >= vertices) {
            return Err(file_error(
                path,
                &format!("face[{face}]"),
                format!("refers to vertex {index}, but there are {vertices} vertices"),
            ));
        }
        for k in 1..polygon.len() - 1 {
            triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
        }
    }
    Ok(triangles)
}

/// The mesh of repaired `parts`, with their attributes. Indices, coordinates and areas were
/// checked or repaired before: what is left to refuse is an attribute (a colour outside
/// [0, 1], a non-finite texture coordinate), named by the file's vertex index
/// (`original_vertex` maps a repaired vertex to it).
fn mesh_from_parts(
    path: &Path,
    parts: MeshParts,
    original_vertex: &[usize],
) -> Result<TriangleMesh, RenderError> {
    let with_attributes = |mesh: TriangleMesh| -> Result<TriangleMesh, RenderError> {
        let mut mesh = mesh;
        if let Some(normals) = parts.normals {
            mesh = mesh.with_normals(normals)?;
        }
        if let Some(colors) = parts.colors {
            mesh = mesh.with_colors(colors)?;
        }
        if let Some(uvs) = parts.uvs {
            mesh = mesh.with_uvs(uvs)?;
        }
        Ok(mesh)
    };
    TriangleMesh::new(parts.positions, parts.triangles)
        .and_then(with_attributes)
        .map_err(|error| {
            let field = match &error {
                RenderError::InvalidAttribute {
                    attribute, vertex, ..
                } => {
                    let vertex = original_vertex.get(*vertex).copied().unwrap_or(*vertex);
                    format!("vertex[{vertex}].{attribute}")
                }
                _ => "mesh".into(),
            };
            file_error(path, &field, error.to_string())
        })
}

/// The vertices of a PLY or OBJ file (a point cloud, or a mesh's vertices), in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Vertices {
    /// Positions (metres).
    pub positions: Vec<Point3<f32>>,
    /// Unit normals, when every vertex has one.
    pub normals: Option<Vec<Vector3<f32>>>,
}

/// Loads the vertices (and normals, when every vertex has `nx ny nz`) of a `.ply` or `.obj` file,
/// multiplying coordinates by `scale`; faces, colours and other properties are ignored, so a mesh
/// file reads as its vertices. Errors name the file and the field: a missing file, a malformed
/// header or body, a missing `vertex` element, a vertex without `x`, a non-finite coordinate, a
/// zero-length normal.
pub fn load_vertices(path: &Path, scale: f64) -> Result<Vertices, RenderError> {
    check_scale(path, scale)?;
    let raw = read_raw(path)?;
    let mut positions = Vec::with_capacity(raw.positions.len());
    for (i, p) in raw.positions.iter().enumerate() {
        if let Some(axis) = (0..3).find(|&k| !p[k].is_finite()) {
            let field = format!("vertex[{i}].{}", ["x", "y", "z"][axis]);
            return Err(file_error(path, &field, "not a finite number".into()));
        }
        positions.push((p * scale).cast::<f32>());
    }
    let normals = match raw.normals {
        None => None,
        Some(normals) => Some(
            normals
                .into_iter()
                .enumerate()
                .map(|(i, n)| {
                    let length = n.norm();
                    if length.is_finite() && length > 0.0 {
                        Ok(n / length)
                    } else {
                        let field = format!("vertex[{i}].nx");
                        Err(file_error(path, &field, "zero-length normal".into()))
                    }
                })
                .collect::<Result<_, _>>()?,
        ),
    };
    Ok(Vertices { positions, normals })
}

/// Writes binary little-endian PLY to `out`: float `x y z` (multiplied by `scale`), `nx ny nz`
/// when `normals` are given (one per position), and `vertex_indices` per triangle (an element
/// `face` only when there are triangles). BOP's model format with `scale = 1000` for a mesh in
/// metres.
pub fn write_ply(
    out: &mut impl Write,
    positions: &[Point3<f32>],
    normals: Option<&[Vector3<f32>]>,
    triangles: &[[u32; 3]],
    scale: f32,
) -> std::io::Result<()> {
    let columns = PlyColumns {
        positions,
        normals,
        colors: None,
        uvs: None,
    };
    write_ply_columns(out, &columns, triangles, scale, None)
}

/// Writes `mesh` as [`write_ply`] does, with its vertex colours (`uchar red green blue`) and
/// texture coordinates (`float texture_u texture_v`) where it has them, and `comment
/// TextureFile {texture}` where a texture image is named (BOP's textured models; what
/// [`load_mesh`] reads back).
pub fn write_mesh_ply_to(
    out: &mut impl Write,
    mesh: &TriangleMesh,
    scale: f32,
    texture: Option<&str>,
) -> std::io::Result<()> {
    let columns = PlyColumns {
        positions: mesh.positions(),
        normals: mesh.normals(),
        colors: mesh.colors(),
        uvs: mesh.uvs(),
    };
    write_ply_columns(out, &columns, mesh.triangles(), scale, texture)
}

/// The per-vertex columns [`write_ply_columns`] writes.
struct PlyColumns<'a> {
    positions: &'a [Point3<f32>],
    normals: Option<&'a [Vector3<f32>]>,
    colors: Option<&'a [[f32; 3]]>,
    uvs: Option<&'a [[f32; 2]]>,
}

fn write_ply_columns(
    out: &mut impl Write,
    columns: &PlyColumns,
    triangles: &[[u32; 3]],
    scale: f32,
    texture: Option<&str>,
) -> std::io::Result<()> {
    let count = columns.positions.len();
    let lengths = [
        columns.normals.map(<[_]>::len),
        columns.colors.map(<[_]>::len),
        columns.uvs.map(<[_]>::len),
    ];
    if lengths.into_iter().flatten().any(|n| n != count) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "one normal, colour and texture coordinate per vertex expected",
        ));
    }
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment ipdf-rs\n");
    if let Some(texture) = texture {
        header += &format!("comment TextureFile {texture}\n");
    }
    header +=
        &format!("element vertex {count}\nproperty float x\nproperty float y\nproperty float z\n");
    if columns.normals.is_some() {
        header += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if columns.colors.is_some() {
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if columns.uvs.is_some() {
        header += "property float texture_u\nproperty float texture_v\n";
    }
    if !triangles.is_empty() {
        header += &format!(
            "element face {}\nproperty list uchar int vertex_indices\n",
            triangles.len()
        );
    }
    header += "end_header\n";
    out.write_all(header.as_bytes())?;
    for (i, p) in columns.positions.iter().enumerate() {
        for v in (p.coords * scale).iter() {
            out.write_all(&v.to_le_bytes())?;
        }
        if let Some(normals) = columns.normals {
            for v in normals[i].iter() {
                out.write_all(&v.to_le_bytes())?;
            }
        }
        if let Some(colors) = columns.colors {
            out.write_all(&colors[i].map(|c| (c * 255.0).round().clamp(0.0, 255.0) as u8))?;
        }
        if let Some(uvs) = columns.uvs {
            for v in uvs[i] {
                out.write_all(&v.to_le_bytes())?;
            }
        }
    }
    for triangle in triangles {
        out.write_all(&[3])?;
        for &index in triangle {
            let index = i32::try_from(index).map_err(std::io::Error::other)?;
            out.write_all(&index.to_le_bytes())?;
        }
    }
    Ok(())
}

/// Refuses a `scale` that is not a positive number, naming the file.
fn check_scale(path: &Path, scale: f64) -> Result<(), RenderError> {
    if scale.is_finite() && scale > 0.0 {
        Ok(())
    } else {
        let reason = format!("must be positive, got {scale}");
        Err(file_error(path, "scale", reason))
    }
}

/// Reads a `.ply` or `.obj` file, by its extension.
fn read_raw(path: &Path) -> Result<RawMesh, RenderError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("ply") => read_ply(path),
        Some("obj") => read_obj(path),
        _ => Err(file_error(
            path,
            "extension",
            "expected .ply or .obj".into(),
        )),
    }
}

/// A mesh as read from a file, before validation.
#[derive(Default)]
struct RawMesh {
    positions: Vec<Point3<f64>>,
    /// The faces, `None` for a file without a face element (a point cloud).
    polygons: Option<Vec<Vec<u32>>>,
    normals: Option<Vec<Vector3<f32>>>,
    colors: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    /// The texture image's name as the file gives it.
    texture: Option<String>,
}

/// Names of texture-coordinate pairs used by PLY writers.
const UV_NAMES: [[&str; 2]; 4] = [
    ["s", "t"],
    ["u", "v"],
    ["texture_u", "texture_v"],
    ["texture_s", "texture_t"],
];

fn read_ply(path: &Path) -> Result<RawMesh, RenderError> {
    let mut file =
        std::fs::File::open(path).map_err(|e| file_error(path, "file", e.to_string()))?;
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut std::io::BufReader::new(&mut file))
        .map_err(|e| file_error(path, "file", format!("not a readable PLY: {e}")))?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| file_error(path, "vertex", "missing".into()))?;
    let first = vertices.first();
    let has = |key: &str| first.is_some_and(|v| v.contains_key(key));
    let uv_names = UV_NAMES.into_iter().find(|[u, v]| has(u) && has(v));
    // Integer colours are 0–255; floating-point ones already 0–1.
    let color_scale = match first.and_then(|v| v.get("red")) {
        Some(Property::Float(_) | Property::Double(_)) => 1.0,
        _ => 1.0 / 255.0,
    };
    let mut raw = RawMesh {
        positions: Vec::with_capacity(vertices.len()),
        normals: has("nx").then(Vec::new),
        colors: (has("red") && has("green") && has("blue")).then(Vec::new),
        uvs: uv_names.map(|_| Vec::new()),
        texture: ply.header.comments.iter().find_map(|c| {
            let name = c.trim().strip_prefix("TextureFile")?.trim();
            (!name.is_empty()).then(|| name.to_string())
        }),
        ..RawMesh::default()
    };
    for (i, vertex) in vertices.iter().enumerate() {
        let value = |key: &str| {
            vertex.get(key).and_then(scalar).ok_or_else(|| {
                file_error(
                    path,
                    &format!("vertex[{i}].{key}"),
                    "missing or not a number".into(),
                )
            })
        };
        raw.positions
            .push(Point3::new(value("x")?, value("y")?, value("z")?));
        if let Some(normals) = &mut raw.normals {
            normals.push(Vector3::new(value("nx")?, value("ny")?, value("nz")?).cast());
        }
        if let Some(colors) = &mut raw.colors {
            let channel = |key| value(key).map(|c| (c * color_scale) as f32);
            colors.push([channel("red")?, channel("green")?, channel("blue")?]);
        }
        if let (Some(uvs), Some([u, v])) = (&mut raw.uvs, uv_names) {
            uvs.push([value(u)? as f32, value(v)? as f32]);
        }
    }
    let Some(faces) = ply.payload.get("face") else {
        return Ok(raw);
    };
    let polygons = raw.polygons.insert(Vec::with_capacity(faces.len()));
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
    Ok(raw)
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

fn read_obj(path: &Path) -> Result<RawMesh, RenderError> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: false,
        ..Default::default()
    };
    let (models, materials) = tobj::load_obj(path, &options)
        .map_err(|e| file_error(path, "file", format!("not a readable OBJ: {e}")))?;
    // A material library that is missing or unreadable leaves the mesh untextured.
    let mut raw = RawMesh {
        texture: models
            .iter()
            .find_map(|m| m.mesh.material_id)
            .and_then(|id| materials.ok()?.into_iter().nth(id)?.diffuse_texture),
        ..RawMesh::default()
    };
    let mut polygons = Vec::new();
    let all =
        |has: fn(&tobj::Mesh) -> bool| !models.is_empty() && models.iter().all(|m| has(&m.mesh));
    if all(|m| !m.normals.is_empty()) {
        raw.normals = Some(Vec::new());
    }
    if all(|m| !m.vertex_color.is_empty()) {
        raw.colors = Some(Vec::new());
    }
    if all(|m| !m.texcoords.is_empty()) {
        raw.uvs = Some(Vec::new());
    }
    for model in &models {
        let mesh = &model.mesh;
        let offset = raw.positions.len() as u32;
        if let Some(normals) = &mut raw.normals {
            normals.extend(
                mesh.normals
                    .chunks_exact(3)
                    .map(|n| Vector3::new(n[0], n[1], n[2])),
            );
        }
        if let Some(colors) = &mut raw.colors {
            colors.extend(
                mesh.vertex_color
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]]),
            );
        }
        if let Some(uvs) = &mut raw.uvs {
            uvs.extend(mesh.texcoords.chunks_exact(2).map(|t| [t[0], t[1]]));
        }
        raw.positions.extend(
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
    raw.polygons = Some(polygons);
    Ok(raw)
}

fn file_error(path: &Path, field: &str, reason: String) -> RenderError {
    RenderError::MeshFile {
        path: PathBuf::from(path),
        field: field.to_string(),
        reason,
    }
}
