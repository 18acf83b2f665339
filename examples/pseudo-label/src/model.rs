//! Everything about an object that the labelling of its instances reuses: its model cloud with
//! features, its renderer and its self-symmetries, computed once per object.
use depth_render::{Material, Scene, TriangleMesh, sample_surface};
use nalgebra::Isometry3;
use registration::{NormalOrientation, PointCloud, PrepareOptions, PreparedCloud, prepare_cloud};

use crate::symmetries::{
    SymmetryAxis, discover_symmetries, near_axis_turns, principal_turns, spread, turn_axes,
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
    /// The poses the first label is checked against: the turns about its principal axes that
    /// are not symmetries ([`principal_turns`]), and the turns about its nearly symmetric axes
    /// ([`near_axis_turns`]).
    pub principal_turns: Vec<Isometry3<f64>>,
    /// The axes about which every turn is a symmetry ([`turn_axes`]): a can's, a bowl's.
    pub symmetry_axes: Vec<SymmetryAxis>,
    /// The mesh, ready to render.
    pub scene: Scene,
    /// How its surface is coloured (its texture or vertex colours), where the mesh file
    /// says: what labels are told apart by in a colour image ([`crate::appearance_match`]).
    pub appearance: Option<Material>,
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
        let axes = turn_axes(&cloud, voxel, &found, SymmetryAxis::of_revolution(mesh));
        let mut principal_turns = principal_turns(&cloud, voxel, &found);
        principal_turns.extend(near_axis_turns(&axes.nearly));
        Ok(Self {
            obj_id,
            diameter,
            voxel,
            cloud,
            symmetries,
            principal_turns,
            symmetry_axes: axes.symmetric,
            scene: Scene::new(std::slice::from_ref(mesh)),
            appearance: None,
        })
    }

    /// This model coloured as `appearance` (a material its mesh cannot show, a texture
    /// without texture coordinates, matches nothing: [`crate::appearance_match`] is `None`).
    pub fn with_appearance(self, appearance: Option<Material>) -> Self {
        Self { appearance, ..self }
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

    /// The axes of the built-in shapes' turns, from the mesh's construction: a can and a bowl
    /// turn onto themselves about their axis (the mesh's z axis, through the origin); a mug
    /// does so but for its handle, a twentieth of its surface, about its cup's axis (the same
    /// line); a box has no such axis.
    #[test]
    fn cans_and_bowls_turn_about_their_axis_mugs_nearly_boxes_not() {
        let on_z = |axis: &SymmetryAxis, tolerance: f64| {
            axis.holds(&Vector3::z(), &nalgebra::Point3::origin(), tolerance)
                && axis.axis.dot(&Vector3::z()).abs() > 1f64.to_radians().cos()
        };
        for kind in [
            ObjectKind::Can,
            ObjectKind::Bowl,
            ObjectKind::Mug,
            ObjectKind::Box,
        ] {
            let model = model(kind);
            let found = discover_symmetries(&model.cloud, model.voxel);
            let revolution =
                SymmetryAxis::of_revolution(&SynthObject::built_in(kind).unwrap().mesh);
            let axes = turn_axes(&model.cloud, model.voxel, &found, revolution);
            assert_eq!(model.symmetry_axes, axes.symmetric, "{kind:?}");
            let (symmetric, nearly) = match kind {
                ObjectKind::Can | ObjectKind::Bowl => (1, 0),
                ObjectKind::Mug => (0, 1),
                _ => (0, 0),
            };
            assert_eq!(axes.symmetric.len(), symmetric, "{kind:?}: {axes:?}");
            assert_eq!(axes.nearly.len(), nearly, "{kind:?}: {axes:?}");
            // A symmetric axis fitted to the surface's normals within a hundredth of a degree
            // and a tenth of a millimetre; the mug's nearly symmetric one, a screw axis,
            // within a degree and two millimetres (its handle pulls it).
            for axis in &axes.symmetric {
                assert!(on_z(axis, 1e-4), "{kind:?}: {axis:?}");
                assert!(
                    axis.axis.dot(&Vector3::z()).abs() > 0.01f64.to_radians().cos(),
                    "{kind:?}: {axis:?}"
                );
            }
            for axis in &axes.nearly {
                assert!(on_z(axis, 2e-3), "{kind:?}: {axis:?}");
            }
        }
    }

    /// Modulo the turns about its axis, a can's symmetry group has two members, upright and
    /// upside down; a box's half turns, with no axis to reduce them, stay four.
    #[test]
    fn a_cans_symmetries_apart_from_its_axis_are_upright_and_upside_down() {
        let can = model(ObjectKind::Can);
        let apart = crate::symmetries::apart_from_axes(
            &can.symmetries,
            &can.symmetry_axes,
            0.05 * can.diameter,
        );
        assert_eq!(apart.len(), 2, "{apart:?}");
        assert_eq!(apart[0], Isometry3::identity());
        assert!(
            (apart[1].rotation * Vector3::z()).z < -0.999,
            "{}",
            apart[1]
        );
        let cuboid = model(ObjectKind::Box);
        let apart = crate::symmetries::apart_from_axes(
            &cuboid.symmetries,
            &cuboid.symmetry_axes,
            0.05 * cuboid.diameter,
        );
        assert_eq!(apart.len(), 4);
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
