//! `models/models_info.json` and the meshes beside it.
use std::collections::BTreeMap;
use std::path::Path;

use depth_render::{ImageTexture, LoadedMesh, Material, TriangleMesh};
use ipdf_metrics::SymmetryGroup;
use serde_json::{Value, json};

use crate::FileError;
use crate::atomic::write_atomically;
use crate::json::{entries_by_id, number, read_json, write_json_by_id};

/// One object's entry of `models_info.json` (millimetres, as in BOP).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelInfo {
    /// The largest distance between two vertices (mm).
    pub diameter: f64,
    /// The bounding box's smallest corner `min_x, min_y, min_z` (mm), when given.
    pub min: Option<[f64; 3]>,
    /// The bounding box's extents `size_x, size_y, size_z` (mm), when given.
    pub size: Option<[f64; 3]>,
    /// The proper symmetries (translations in mm); none when the entry lists none.
    pub symmetry: SymmetryGroup,
}

impl ModelInfo {
    /// The entry of `mesh` (in metres) with `symmetry` (translations in metres): its diameter
    /// and bounding box, all converted to millimetres.
    pub fn of_mesh(mesh: &TriangleMesh, symmetry: &SymmetryGroup) -> Self {
        let (low, high) = mesh.bounds();
        let diameter = mesh.diameter();
        let mm = |v: f32| f64::from(v) * 1e3;
        let mut symmetry = symmetry.clone();
        for s in &mut symmetry.discrete {
            s.translation.vector *= 1e3;
        }
        for c in &mut symmetry.continuous {
            c.offset *= 1e3;
        }
        Self {
            diameter: diameter * 1e3,
            min: Some([mm(low.x), mm(low.y), mm(low.z)]),
            size: Some([mm(high.x - low.x), mm(high.y - low.y), mm(high.z - low.z)]),
            symmetry,
        }
    }

    fn to_json(&self) -> Value {
        let mut entry = json!({"diameter": self.diameter});
        let fields = entry.as_object_mut().expect("an object");
        for (corner, prefix) in [(&self.min, "min_"), (&self.size, "size_")] {
            if let Some(values) = corner {
                for (axis, v) in ["x", "y", "z"].iter().zip(values) {
                    fields.insert(format!("{prefix}{axis}"), json!(v));
                }
            }
        }
        if let Value::Object(symmetries) = self.symmetry.to_bop_json() {
            fields.extend(symmetries);
        }
        entry
    }
}

/// Reads `models_info.json`: object id → entry. Errors name the key, e.g. `5.diameter` or
/// `5.symmetries_discrete[1]`.
pub fn read_models_info(path: &Path) -> Result<BTreeMap<u32, ModelInfo>, FileError> {
    let value = read_json(path)?;
    let mut out = BTreeMap::new();
    for (obj_id, entry) in entries_by_id(&value, path)? {
        let prefix = format!("{obj_id}.");
        let diameter = number(entry, "diameter", path, &prefix)?;
        if diameter <= 0.0 {
            return Err(FileError::new(
                path,
                format!("{prefix}diameter"),
                format!("{diameter} is not positive"),
            ));
        }
        let corner = |prefix_key: &str| -> Result<Option<[f64; 3]>, FileError> {
            if entry.get(format!("{prefix_key}x")).is_none() {
                return Ok(None);
            }
            let mut out = [0.0; 3];
            for (slot, axis) in out.iter_mut().zip(["x", "y", "z"]) {
                *slot = number(entry, &format!("{prefix_key}{axis}"), path, &prefix)?;
            }
            Ok(Some(out))
        };
        let symmetry = SymmetryGroup::from_bop_json(entry).map_err(|e| match e {
            ipdf_metrics::MetricsError::InvalidSymmetry { field, reason } => {
                FileError::new(path, format!("{prefix}{field}"), reason)
            }
            other => FileError::new(path, format!("{obj_id}"), other.to_string()),
        })?;
        out.insert(
            obj_id,
            ModelInfo {
                diameter,
                min: corner("min_")?,
                size: corner("size_")?,
                symmetry,
            },
        );
    }
    Ok(out)
}

/// Writes `models_info.json` atomically.
pub fn write_models_info(path: &Path, models: &BTreeMap<u32, ModelInfo>) -> Result<(), FileError> {
    let entries = models.iter().map(|(&id, m)| (id, m.to_json())).collect();
    write_json_by_id(path, &entries)
}

/// How the mesh file `path`, loaded as `loaded`, colours its surface: its texture image where
/// it names one ([`Material::Image`]), else its vertex colours where it has them, else `None`.
/// A texture image the file names but that cannot be read is refused, naming it.
pub fn mesh_appearance(path: &Path, loaded: &LoadedMesh) -> Result<Option<Material>, FileError> {
    Ok(match &loaded.texture {
        Some(texture) => Some(Material::Image(read_texture(path, texture)?)),
        None => loaded.mesh.colors().map(|_| Material::VertexColors),
    })
}

/// The texture image `texture` that the mesh file `mesh` names.
fn read_texture(mesh: &Path, texture: &Path) -> Result<ImageTexture, FileError> {
    let image = crate::read_rgb(texture)
        .map_err(|e| FileError::new(mesh, "TextureFile", format!("{}: {e}", texture.display())))?;
    let texels = image
        .pixels
        .iter()
        .map(|p| p.map(|c| f32::from(c) / 255.0))
        .collect();
    ImageTexture::new(image.width as usize, image.height as usize, texels)
        .map_err(|e| FileError::new(mesh, "TextureFile", e.to_string()))
}

/// Writes `mesh` (metres) as a binary little-endian PLY in millimetres (BOP's model format:
/// `x y z nx ny nz` per vertex when it has normals, its colours `red green blue` and texture
/// coordinates `texture_u texture_v` when it has them, `vertex_indices` per face), atomically.
pub fn write_mesh_ply(path: &Path, mesh: &TriangleMesh) -> Result<(), FileError> {
    write_atomically(path, |out| {
        depth_render::write_mesh_ply_to(out, mesh, 1e3, None)
    })
}

/// Writes `mesh` as [`write_mesh_ply`] does, coloured as `appearance` says where the file can
/// hold it: an image texture is written beside the mesh (`{stem}.png`, named by the PLY's
/// `comment TextureFile`, as BOP's textured models), vertex colours are in the PLY; what
/// [`mesh_appearance`] reads back. Other materials are not written.
pub fn write_coloured_mesh_ply(
    path: &Path,
    mesh: &TriangleMesh,
    appearance: Option<&Material>,
) -> Result<(), FileError> {
    let Some(Material::Image(texture)) = appearance.filter(|_| mesh.uvs().is_some()) else {
        return write_mesh_ply(path, mesh);
    };
    let image = path.with_extension("png");
    let (width, height) = texture.size();
    crate::write_rgb(&image, &texture.to_rgb8(), width as u32, height as u32)?;
    let name = image.file_name().map(|n| n.to_string_lossy().into_owned());
    write_atomically(path, |out| {
        depth_render::write_mesh_ply_to(out, mesh, 1e3, name.as_deref())
    })
}
