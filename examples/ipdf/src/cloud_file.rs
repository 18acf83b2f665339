//! Point clouds from and to PLY files, through the one PLY reader and writer of the workspace
//! (`depth_render::load_vertices` / `write_ply`): a mesh file reads as its vertices.
use std::path::Path;

use bop_dataset::write_atomically;
use registration::PointCloud;

use crate::PipelineError;

/// The vertices (and normals, when every vertex has one) of a PLY or OBJ file as a point cloud,
/// coordinates multiplied by `scale` (0.001 for BOP's millimetres).
pub fn read_cloud(path: &Path, scale: f64) -> Result<PointCloud, PipelineError> {
    let vertices = depth_render::load_vertices(path, scale)?;
    let cloud = PointCloud::new(vertices.positions)?;
    Ok(match vertices.normals {
        Some(normals) => cloud.with_normals(normals)?,
        None => cloud,
    })
}

/// Writes `cloud` as a binary little-endian PLY (float `x y z`, and `nx ny nz` when it has
/// normals), atomically.
pub fn write_cloud(path: &Path, cloud: &PointCloud) -> Result<(), PipelineError> {
    write_atomically(path, |out| {
        depth_render::write_ply(out, cloud.points(), cloud.normals(), &[], 1.0)
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::*;

    #[test]
    fn clouds_round_trip_with_and_without_normals() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cloud.ply");
        let cloud = PointCloud::new(vec![
            Point3::new(0.1, -0.2, 0.3),
            Point3::new(1.0, 2.0, 3.0),
        ])
        .unwrap();
        write_cloud(&path, &cloud).unwrap();
        assert_eq!(read_cloud(&path, 1.0).unwrap(), cloud);
        let with = cloud
            .with_normals(vec![Vector3::x(), Vector3::new(0.0, 0.6, 0.8)])
            .unwrap();
        write_cloud(&path, &with).unwrap();
        assert_eq!(read_cloud(&path, 1.0).unwrap(), with);
    }
}
