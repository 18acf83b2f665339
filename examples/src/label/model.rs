//! Everything about an object that the labelling of its instances reuses: its model cloud with
//! features, its renderer and its self-symmetries, computed once per object.
use depth_render::{Scene, TriangleMesh, sample_surface};
use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;
use registration::{NormalOrientation, PointCloud, PrepareOptions, PreparedCloud, prepare_cloud};

use super::LabelOptions;
use super::symmetries::{discover_symmetries, spread};
use crate::PipelineError;

/// One object, prepared for labelling.
pub struct ObjectModel {
    /// Its id in the dataset.
    pub obj_id: u32,
    /// Largest distance between two vertices (metres).
    pub diameter: f64,
    /// Voxel size of the clouds (metres).
    pub voxel: f32,
    /// The model's surface samples, downsampled, with outward normals and FPFH features.
    pub cloud: PreparedCloud,
    /// Its self-symmetries (model frame, metres), identity first: at most
    /// `LabelOptions::max_symmetries`, spread evenly over those found.
    pub symmetries: Vec<Isometry3<f64>>,
    /// The mesh, ready to render.
    pub scene: Scene,
}

/// The largest distance between two of `points` (0 for fewer than two), in parallel.
pub fn max_distance(points: &[Point3<f32>]) -> f32 {
    points
        .par_iter()
        .enumerate()
        .map(|(i, a)| {
            points[i + 1..]
                .iter()
                .map(|b| (a - b).norm())
                .fold(0.0f32, f32::max)
        })
        .reduce(|| 0.0, f32::max)
}

/// The largest distance between two vertices of `mesh` (metres), as BOP's `diameter`.
pub fn mesh_diameter(mesh: &TriangleMesh) -> f64 {
    max_distance(mesh.positions()).into()
}

impl ObjectModel {
    /// Prepares `mesh` (metres) of object `obj_id`: `options.model_points` surface samples with
    /// face normals, downsampled at `options.voxel_fraction` of the diameter, FPFH, and the
    /// self-symmetries.
    pub fn new(
        obj_id: u32,
        mesh: &TriangleMesh,
        options: &LabelOptions,
    ) -> Result<Self, PipelineError> {
        let diameter = mesh_diameter(mesh);
        let voxel = (diameter * options.voxel_fraction) as f32;
        let (points, normals) = sample_surface(mesh, options.model_points, options.seed);
        let cloud = PointCloud::new(points)?.with_normals(normals)?;
        let prepare = PrepareOptions::for_voxel(voxel)
            .oriented(NormalOrientation::Consistent { neighbours: 10 });
        let cloud = prepare_cloud(&cloud, &prepare)?;
        let found = discover_symmetries(&cloud, voxel);
        let rotations: Vec<_> = found.iter().map(|s| s.rotation).collect();
        let mut kept = spread(&rotations, options.max_symmetries);
        kept.sort_unstable();
        let symmetries = kept.into_iter().map(|i| found[i]).collect();
        Ok(Self {
            obj_id,
            diameter,
            voxel,
            cloud,
            symmetries,
            scene: Scene::new(std::slice::from_ref(mesh)),
        })
    }
}
