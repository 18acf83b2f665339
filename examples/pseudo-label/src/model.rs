//! Everything about an object that the labelling of its instances reuses: its model cloud with
//! features, its renderer and its self-symmetries, computed once per object.
use depth_render::{Scene, TriangleMesh, sample_surface};
use nalgebra::Isometry3;
use registration::{NormalOrientation, PointCloud, PrepareOptions, PreparedCloud, prepare_cloud};

use crate::symmetries::{
    SymmetryAxis, discover_symmetries, principal_turns, spread, symmetry_axes,
};
use crate::{LabelError, LabelOptions};

/// One object, prepared for labelling.
pub struct ObjectModel {
    /// Its id in the dataset.
    pub obj_id: u32,
    /// Largest distance between two vertices (metres).
    pub diameter: f64,
    /// Voxel size of the clouds (metres).
    pub voxel: f32,
    /// The model's surface samples, downsampled, with outward normals and FPFH features, indexed
    /// for ICP's nearest-point queries.
    pub cloud: PreparedCloud,
    /// Its self-symmetries (model frame, metres), identity first: at most
    /// `LabelOptions::max_symmetries`, spread evenly over those found.
    pub symmetries: Vec<Isometry3<f64>>,
    /// The turns about its principal axes that are not symmetries: the poses the first label
    /// is checked against ([`principal_turns`]).
    pub principal_turns: Vec<Isometry3<f64>>,
    /// The axes about which every turn is a symmetry ([`symmetry_axes`]): a can's, a bowl's.
    pub symmetry_axes: Vec<SymmetryAxis>,
    /// The mesh, ready to render.
    pub scene: Scene,
}

impl ObjectModel {
    /// Prepares `mesh` (metres) of object `obj_id`: `options.model_points` surface samples with
    /// face normals, downsampled at `options.voxel_fraction` of the diameter, FPFH, the
    /// self-symmetries, its axes of continuous symmetry and the principal turns that are not
    /// symmetries.
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
        let cloud = prepare_cloud(&cloud, &prepare)?.with_nearest_grid();
        let found = discover_symmetries(&cloud, voxel);
        let rotations: Vec<_> = found.iter().map(|s| s.rotation).collect();
        let mut kept = spread(&rotations, options.max_symmetries);
        kept.sort_unstable();
        let symmetries: Vec<_> = kept.into_iter().map(|i| found[i]).collect();
        let principal_turns = principal_turns(&cloud, voxel, &found);
        let symmetry_axes = symmetry_axes(&cloud, voxel, &found);
        Ok(Self {
            obj_id,
            diameter,
            voxel,
            cloud,
            symmetries,
            principal_turns,
            symmetry_axes,
            scene: Scene::new(std::slice::from_ref(mesh)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use synth_data::{ObjectKind, SynthObject};

    fn model(kind: ObjectKind) -> ObjectModel {
        let object = SynthObject::built_in(kind).unwrap();
        ObjectModel::new(1, &object.mesh, &LabelOptions::default()).unwrap()
    }

    /// A can and a bowl turn onto themselves about their axis (the mesh's z axis, through
    /// the origin); a box has no such axis, and neither has a mug, whose handle is a
    /// twentieth of its surface.
    #[test]
    fn cans_and_bowls_have_an_axis_of_symmetry_boxes_and_mugs_none() {
        for kind in [ObjectKind::Can, ObjectKind::Bowl] {
            let axes = model(kind).symmetry_axes;
            assert_eq!(axes.len(), 1, "{kind:?}: {axes:?}");
            let axis = axes[0];
            // Through the origin along z: within a degree and a millimetre.
            assert!(
                axis.holds(&Vector3::z(), &nalgebra::Point3::origin(), 1e-3),
                "{kind:?}: {axis:?}"
            );
            assert!(
                axis.axis.dot(&Vector3::z()).abs() > 1f64.to_radians().cos(),
                "{kind:?}: {axis:?}"
            );
        }
        for kind in [ObjectKind::Box, ObjectKind::Mug] {
            let axes = model(kind).symmetry_axes;
            assert!(axes.is_empty(), "{kind:?}: {axes:?}");
        }
    }

    /// A box with three different edges has 4 symmetries (the half turns about its axes) and
    /// is checked against the other 20 turns; a can, symmetric about its axis and upside
    /// down, only against the 16 that tip its axis over.
    #[test]
    fn principal_turns_leave_out_the_symmetries() {
        let cuboid = model(ObjectKind::Box);
        assert_eq!(cuboid.symmetries.len(), 4);
        assert_eq!(cuboid.principal_turns.len(), 20);
        let can = model(ObjectKind::Can);
        assert_eq!(can.principal_turns.len(), 16);
        let axis = Vector3::z();
        for turn in &can.principal_turns {
            let tilt = (turn.rotation * axis).dot(&axis).abs();
            // The principal axes of 20,000 surface samples, within a degree.
            assert!(tilt < 0.02, "{turn}");
        }
    }
}
