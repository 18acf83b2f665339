//! Everything about an object that the labelling of its instances reuses: its model cloud with
//! features, its renderer and its self-symmetries, computed once per object.
use depth_render::{Scene, TriangleMesh, sample_surface};
use nalgebra::Isometry3;
use registration::{NormalOrientation, PointCloud, PrepareOptions, PreparedCloud, prepare_cloud};

use crate::symmetries::{discover_symmetries, spread};
use crate::{LabelError, LabelOptions};

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

impl ObjectModel {
    /// Prepares `mesh` (metres) of object `obj_id`: `options.model_points` surface samples with
    /// face normals, downsampled at `options.voxel_fraction` of the diameter, FPFH, and the
    /// self-symmetries.
    pub fn new(
        obj_id: u32,
        mesh: &TriangleMesh,
        options: &LabelOptions,
    ) -> Result<Self, LabelError> {
        let diameter = mesh.diameter();
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
