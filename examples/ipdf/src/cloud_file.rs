//! Point clouds from and to PLY files, through the one PLY reader and writer of the workspace
//! (`depth_render::load_vertices` / `write_ply`): a mesh file reads as points sampled on its
//! surface (a CAD mesh's vertices are its corners, far too few to register).
use std::path::Path;

use bop_dataset::write_atomically;
use registration::PointCloud;

use crate::Error;

/// Points sampled on a mesh's surface: at least this many, and at least its vertices.
pub const MESH_SAMPLES: usize = 20_000;

/// A PLY or OBJ file as a point cloud, coordinates multiplied by `scale` (0.001 for BOP's
/// millimetres): a file with faces as [`MESH_SAMPLES`] points sampled uniformly on its surface
/// with their faces' normals (seed 0), else its vertices (and normals, when every vertex has
/// one).
pub fn read_cloud(path: &Path, scale: f64) -> Result<PointCloud, Error> {
    match depth_render::load_mesh(path, scale) {
        Ok(loaded) => {
            let mesh = loaded.mesh;
            let count = MESH_SAMPLES.max(mesh.positions().len());
            let (points, normals) = depth_render::sample_surface(&mesh, count, 0);
            return Ok(PointCloud::new(points)?.with_normals(normals)?);
        }
        Err(depth_render::RenderError::MeshFile { field, .. }) if field == "face" => {}
        Err(error) => return Err(error.into()),
    }
    let vertices = depth_render::load_vertices(path, scale)?;
    let cloud = PointCloud::new(vertices.positions)?;
    Ok(match vertices.normals {
        Some(normals) => cloud.with_normals(normals)?,
        None => cloud,
    })
}

/// Writes `cloud` as a binary little-endian PLY (float `x y z`, and `nx ny nz` when it has
/// normals), atomically.
pub fn write_cloud(path: &Path, cloud: &PointCloud) -> Result<(), Error> {
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

    #[test]
    fn a_mesh_reads_as_points_on_its_surface() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("box.ply");
        let mesh = depth_render::Primitive::Cuboid {
            extents: [0.1, 0.2, 0.3],
        }
        .mesh()
        .unwrap();
        bop_dataset::write_mesh_ply(&path, &mesh).unwrap();
        let cloud = read_cloud(&path, 0.001).unwrap();
        assert_eq!(cloud.len(), MESH_SAMPLES);
        assert!(cloud.normals().is_some());
        // Every point on a face of the box (half-extents 0.05, 0.1, 0.15 m after the mm scale
        // of write_mesh_ply).
        let half = [0.05f32, 0.1, 0.15];
        for p in cloud.points() {
            let on_face = (0..3).any(|a| (p[a].abs() - half[a]).abs() < 1e-4);
            let inside = (0..3).all(|a| p[a].abs() <= half[a] + 1e-4);
            assert!(on_face && inside, "{p}");
        }
    }
}
