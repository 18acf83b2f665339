//! Catching a mesh read at the wrong scale before it renders as a speck or a wall: objects that
//! a depth camera images for pose estimation are between a few millimetres and a few metres
//! across, and a mesh in metres read as millimetres (or the reverse) lands a factor of 1,000
//! outside that range.
use std::path::Path;

use crate::{RenderError, TriangleMesh};

/// Sizes (bounding-box diagonal, metres) accepted as an object's: 2 mm to 20 m, a factor of ten
/// beyond a screw and a car on either side.
pub const PLAUSIBLE_SIZE_M: (f64, f64) = (0.002, 20.0);

/// The units meshes commonly come in, as factors to metres: metres, centimetres, millimetres.
const UNITS: [f64; 3] = [1.0, 0.01, 0.001];

/// Refuses `mesh`, loaded from `path` with `scale` (metres per file unit), when its size is
/// not an object's ([`PLAUSIBLE_SIZE_M`]), suggesting the common unit that makes it one.
/// `setting` names the option that sets the scale (`--mesh-scale` on the command line).
pub fn check_mesh_size(
    mesh: &TriangleMesh,
    path: &Path,
    scale: f64,
    setting: &str,
) -> Result<(), RenderError> {
    let (low, high) = mesh.bounds();
    let size = f64::from((high - low).norm());
    let (min, max) = PLAUSIBLE_SIZE_M;
    if (min..=max).contains(&size) {
        return Ok(());
    }
    let file_size = size / scale;
    // The unit that brings the object closest to 20 cm (in ratio).
    let suggestion = UNITS
        .into_iter()
        .filter(|unit| (min..=max).contains(&(file_size * unit)))
        .min_by(|a, b| {
            let distance = |unit: f64| (file_size * unit / 0.2).ln().abs();
            distance(*a).total_cmp(&distance(*b))
        });
    Err(RenderError::MeshScale {
        path: path.to_path_buf(),
        size_m: size,
        scale,
        setting: setting.to_string(),
        suggestion,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Primitive;

    fn can(scale: f32) -> TriangleMesh {
        let mesh = Primitive::Cylinder {
            radius: 0.05,
            height: 0.1,
            segments: 32,
        }
        .mesh()
        .unwrap();
        let positions = mesh.positions().iter().map(|p| p * scale).collect();
        TriangleMesh::new(positions, mesh.triangles().to_vec()).unwrap()
    }

    #[test]
    fn a_mesh_in_metres_read_as_millimetres_is_refused_with_the_scale_that_fits() {
        let path = Path::new("can.ply");
        assert!(check_mesh_size(&can(1.0), path, 0.001, "--mesh-scale").is_ok());
        let error = check_mesh_size(&can(0.001), path, 0.001, "--mesh-scale").unwrap_err();
        let RenderError::MeshScale { suggestion, .. } = &error else {
            panic!("{error}");
        };
        assert_eq!(*suggestion, Some(1.0));
        let text = error.to_string();
        assert!(
            text.contains("can.ply") && text.contains("--mesh-scale 1"),
            "{text}"
        );
        // Millimetres read as metres.
        let error = check_mesh_size(&can(1000.0), path, 1.0, "--mesh-scale").unwrap_err();
        assert!(error.to_string().contains("--mesh-scale 0.001"), "{error}");
    }
}
