//! Primitive shapes: exact solids of revolution, analytic symmetry groups, resting poses.
use std::collections::HashMap;

use depth_render::primitives::MugShape;
use depth_render::{
    Instance, PinholeCamera, Primitive, RenderError, Scene, TriangleMesh, Window,
    group_by_symmetry, primitives, resting_poses,
};
use ipdf_metrics::SymmetryGroup;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

/// The symmetry rotations of `shape`, its axes of revolution sampled every degree.
fn every_degree(shape: Primitive) -> Vec<UnitQuaternion<f64>> {
    let symmetry = shape.symmetry().unwrap();
    SymmetryGroup::about_origin(&symmetry.discrete, &symmetry.continuous).rotations(360)
}

fn closed(mesh: &TriangleMesh) -> bool {
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for &[a, b, c] in mesh.triangles() {
        for (p, q) in [(a, b), (b, c), (c, a)] {
            *edges.entry((p, q)).or_default() += 1;
        }
    }
    edges
        .iter()
        .all(|(&(p, q), &n)| n == 1 && edges.get(&(q, p)) == Some(&1))
}

#[test]
fn solids_of_revolution_are_closed_with_exact_volume() {
    let n = 96u32;
    // A regular n-gon of circumradius r has area n/2 · r² · sin(2π/n).
    let polygon =
        |r: f64| f64::from(n) / 2.0 * r * r * (std::f64::consts::TAU / f64::from(n)).sin();
    let cone = primitives::cone(0.05, 0.12, n).unwrap();
    assert!(closed(&cone));
    let expected = polygon(0.05) * 0.12 / 3.0;
    assert!((cone.signed_volume() - expected).abs() / expected < 1e-6);
    let (lo, hi) = cone.bounds();
    assert!((lo.z + 0.06).abs() < 1e-7 && (hi.z - 0.06).abs() < 1e-7);

    let bowl = primitives::bowl(0.08, 0.055, 0.005, n, 12).unwrap();
    assert!(closed(&bowl));
    let (lo, hi) = bowl.bounds();
    assert!(
        (hi.x - 0.08).abs() < 1e-6 && (lo.z + 0.0275).abs() < 1e-7 && (hi.z - 0.0275).abs() < 1e-7
    );
    // The wall is thin: far less volume than the solid it encloses, but positive.
    let solid = polygon(0.08) * 0.055;
    assert!(bowl.signed_volume() > 0.0 && bowl.signed_volume() < 0.35 * solid);

    assert!(matches!(
        primitives::bowl(0.08, 0.05, 0.04, n, 12),
        Err(RenderError::InvalidDimension {
            name: "thickness",
            ..
        })
    ));
    assert!(primitives::cone(0.05, 0.1, 2).is_err());
}

#[test]
fn symmetry_groups_have_the_textbook_orders() {
    let order = |shape: Primitive| shape.symmetry().unwrap().discrete.len() + 1;
    assert_eq!(
        order(Primitive::Cuboid {
            extents: [0.1, 0.2, 0.3]
        }),
        4
    );
    assert_eq!(
        order(Primitive::Cuboid {
            extents: [0.1, 0.1, 0.3]
        }),
        8
    );
    assert_eq!(
        order(Primitive::Cuboid {
            extents: [0.1, 0.1, 0.1]
        }),
        24
    );
    assert_eq!(order(Primitive::Tetrahedron { circumradius: 0.1 }), 12);
    assert_eq!(order(Primitive::Octahedron { circumradius: 0.1 }), 24);
    assert_eq!(order(Primitive::Icosahedron { circumradius: 0.1 }), 60);
    assert_eq!(
        order(Primitive::Plane {
            width: 1.0,
            depth: 2.0
        }),
        2
    );
    let can = Primitive::Cylinder {
        radius: 0.05,
        height: 0.1,
        segments: 64,
    }
    .symmetry()
    .unwrap();
    assert_eq!((can.discrete.len(), can.continuous.len()), (1, 1));
    let cone = Primitive::Cone {
        radius: 0.05,
        height: 0.1,
        segments: 64,
    }
    .symmetry()
    .unwrap();
    assert_eq!((cone.discrete.len(), cone.continuous.len()), (0, 1));
    assert!(matches!(
        Primitive::Sphere {
            radius: 0.1,
            subdivisions: 2
        }
        .symmetry(),
        Err(RenderError::SymmetryNotRepresentable { .. })
    ));
}

fn depth_at(scene: &Scene, pose: Isometry3<f64>) -> Vec<f32> {
    let camera = PinholeCamera::new(300.0, 300.0, 40.0, 40.0, 80, 80).unwrap();
    scene
        .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
        .unwrap()
        .depth
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// Seen at `R` or at `R·S` for any symmetry `S`, a shape renders the same depth image
    /// (exactly up to rounding for polyhedra; within the tessellation error for a can turned by
    /// an arbitrary angle about its axis).
    #[test]
    fn symmetric_poses_render_identical_depth(
        axis in prop::array::uniform3(-1.0..1.0f64),
        angle in 0.0..3.1f64,
        which in 0usize..5,
        pick in 0usize..100,
        turn in 0.0..std::f64::consts::TAU,
    ) {
        let shapes = [
            Primitive::Cuboid { extents: [0.06, 0.06, 0.12] },
            Primitive::Tetrahedron { circumradius: 0.06 },
            Primitive::Octahedron { circumradius: 0.06 },
            Primitive::Icosahedron { circumradius: 0.06 },
            Primitive::Cylinder { radius: 0.04, height: 0.1, segments: 256 },
        ];
        let shape = shapes[which];
        let symmetry = shape.symmetry().unwrap();
        let scene = Scene::new(&[shape.mesh().unwrap()]);
        let axis = Vector3::from(axis);
        prop_assume!(axis.norm() > 0.1);
        let rotation = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
        let mut s = UnitQuaternion::identity();
        if !symmetry.discrete.is_empty() {
            s = symmetry.discrete[pick % symmetry.discrete.len()];
        }
        if let Some(axis) = symmetry.continuous.first() {
            s = UnitQuaternion::from_axis_angle(axis, turn) * s;
        }
        let place = |r: UnitQuaternion<f64>| Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), r);
        let (a, b) = (depth_at(&scene, place(rotation)), depth_at(&scene, place(rotation * s)));
        let tolerance = if symmetry.continuous.is_empty() { 1e-5 } else { 2e-4 };
        let mismatched = a.iter().zip(&b).filter(|(x, y)| (*x - *y).abs() > tolerance).count();
        // Silhouette pixels of a tessellated can may flip; polyhedra match everywhere.
        let allowed = if symmetry.continuous.is_empty() { 0 } else { 12 };
        prop_assert!(mismatched <= allowed, "{mismatched} pixels differ");
    }
}

#[test]
fn a_box_rests_on_six_faces_three_up_to_symmetry() {
    let shape = Primitive::Cuboid {
        extents: [0.1, 0.2, 0.3],
    };
    let poses = resting_poses(&shape.mesh().unwrap()).unwrap();
    assert_eq!(poses.len(), 6);
    let total: f64 = poses.iter().map(|p| p.probability).sum();
    assert!((total - 1.0).abs() < 1e-9);
    // The largest faces (0.2 × 0.3, normal ±x) are the likeliest.
    assert!(poses[0].normal.x.abs() > 0.999 && (poses[0].offset - 0.05).abs() < 1e-6);
    let groups = group_by_symmetry(&poses, &every_degree(shape));
    assert_eq!(groups.len(), 3);
    // Resting on a face puts the box on the table, face down.
    let placed = poses[0].on_table(0.7, 0.1, -0.2);
    let lowest = shape
        .mesh()
        .unwrap()
        .positions()
        .iter()
        .map(|p| (placed * p.cast::<f64>()).z)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest.abs() < 1e-7);
    assert!((placed * poses[0].normal.into_inner() + Vector3::z()).norm() < 1e-9);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A box of half-extents `e` standing on the face whose normal is axis `i` tips over the
    /// nearer of that face's edges: at `atan(min(e_j, e_k) / e_i)`.
    #[test]
    fn a_box_tips_over_its_nearer_edge(
        extents in prop::array::uniform3(0.02f64..0.4),
    ) {
        let shape = Primitive::Cuboid { extents };
        let poses = resting_poses(&shape.mesh().unwrap()).unwrap();
        prop_assert_eq!(poses.len(), 6);
        for pose in &poses {
            let i = pose.normal.iamax();
            let half: Vec<f64> = extents.iter().map(|e| e / 2.0).collect();
            let across = (0..3).filter(|&j| j != i).map(|j| half[j]).fold(f64::INFINITY, f64::min);
            let expected = (across / half[i]).atan();
            prop_assert!((pose.tipping_angle - expected).abs() < 1e-6, "{pose:?}: {expected}");
        }
    }
}

#[test]
fn a_can_rests_on_its_caps_and_side() {
    let shape = Primitive::Cylinder {
        radius: 0.04,
        height: 0.12,
        segments: 48,
    };
    let poses = resting_poses(&shape.mesh().unwrap()).unwrap();
    assert_eq!(poses.len(), 2 + 48);
    let axis_only = SymmetryGroup::about_origin(&[], &[Vector3::z_axis()]).rotations(360);
    assert_eq!(
        group_by_symmetry(&poses, &axis_only).len(),
        3,
        "top, bottom, side"
    );
    assert_eq!(
        group_by_symmetry(&poses, &every_degree(shape)).len(),
        2,
        "caps, side"
    );
    // A tall can falls on its side more often than it lands on a cap.
    let side: f64 = poses
        .iter()
        .filter(|p| p.normal.z.abs() < 0.5)
        .map(|p| p.probability)
        .sum();
    assert!(side > 0.5, "{side}");
    // On a facet of its side it tips at half the angle between facets (3.75°); on a cap, at
    // atan(apothem / half the height), to the f32 vertices' rounding.
    let apothem = 0.04 * (std::f64::consts::PI / 48.0).cos();
    for pose in &poses {
        let expected = if pose.normal.z.abs() > 0.999 {
            (apothem / 0.06).atan()
        } else {
            std::f64::consts::PI / 48.0
        };
        assert!(
            (pose.tipping_angle - expected).abs() < 1e-6,
            "{pose:?}: {expected}"
        );
    }
}

/// The YCB-Video scans of the cracker box and the sugar box (real scans, in the fixture of
/// `examples/pseudo-label`) rest on all six sides of their bounding box, each found as one face
/// though a scan's flat side is a patchwork of hull triangles: each tips at no more than a flat
/// box of the scan's bounding box does (`atan` of half the nearer edge over half the height,
/// plus a degree: the scan's centre of mass is not its box's centre), and at 5° or more
/// (their rounded edges make the faces smaller than the box's).
#[test]
fn scanned_boxes_rest_on_all_six_sides() {
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples/pseudo-label/tests/data/ycbv_real/models");
    for id in [2, 3] {
        let path = fixture.join(format!("obj_{id:06}.ply"));
        let mesh = depth_render::load_mesh(&path, 0.001).unwrap().mesh;
        let (low, high) = mesh.bounds();
        let half = ((high - low) / 2.0).cast::<f64>();
        let poses = resting_poses(&mesh).unwrap();
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut direction = Vector3::zeros();
                direction[axis] = sign;
                let tipping = poses
                    .iter()
                    .filter(|p| p.normal.dot(&direction) > 10f64.to_radians().cos())
                    .map(|p| p.tipping_angle.to_degrees())
                    .fold(f64::NEG_INFINITY, f64::max);
                let across = (0..3)
                    .filter(|&j| j != axis)
                    .map(|j| half[j])
                    .fold(f64::INFINITY, f64::min);
                let flat_box = (across / half[axis]).atan().to_degrees();
                assert!(
                    (5.0..=flat_box + 1.0).contains(&tipping),
                    "obj {id}, axis {axis} {sign}: tips at {tipping:.1}°, a flat box at {flat_box:.1}°"
                );
            }
        }
    }
}

#[test]
fn regular_solids_and_a_bowl_rest_as_expected() {
    let count = |shape: Primitive| resting_poses(&shape.mesh().unwrap()).unwrap().len();
    assert_eq!(count(Primitive::Tetrahedron { circumradius: 0.05 }), 4);
    assert_eq!(count(Primitive::Octahedron { circumradius: 0.05 }), 8);
    assert_eq!(count(Primitive::Icosahedron { circumradius: 0.05 }), 20);
    // A bowl stands on its foot or upside down on its rim, never on its curved wall.
    let bowl = Primitive::Bowl {
        radius: 0.08,
        height: 0.055,
        thickness: 0.005,
        segments: 64,
        rings: 8,
    };
    let poses = resting_poses(&bowl.mesh().unwrap()).unwrap();
    assert_eq!(poses.len(), 2, "{poses:?}");
    assert!(poses.iter().all(|p| p.normal.z.abs() > 0.999));
    // A flat plane has no resting pose.
    assert!(matches!(
        resting_poses(&primitives::plane(1.0, 1.0).unwrap()),
        Err(RenderError::NoRestingPose { .. })
    ));
}

/// The mug is closed and outward-wound, with the volume of its cup (outer solid less the
/// inside) plus its handle (Pappus: the tube's cross-section times the half circle its centre
/// follows), the handle where its dimensions put it, and refused dimensions named.
#[test]
fn a_mug_is_a_closed_cup_with_a_handle() {
    let (radius, height, wall, reach, thickness, n) = (0.04, 0.095, 0.004, 0.03, 0.008, 96u32);
    let dimensions = MugShape {
        radius,
        height,
        wall,
        handle_reach: reach,
        handle_thickness: thickness,
        segments: n,
    };
    let mug = primitives::mug(&dimensions).unwrap();
    assert!(closed(&mug));
    let (lo, hi) = mug.bounds();
    assert!(
        (f64::from(hi.x) - (radius + reach + 0.5 * thickness)).abs() < 1e-5,
        "{hi}"
    );
    assert!((f64::from(lo.x) + radius).abs() < 1e-6);
    assert!((f64::from(hi.z) - 0.5 * height).abs() < 1e-6);
    let polygon =
        |r: f64, k: u32| f64::from(k) / 2.0 * r * r * (std::f64::consts::TAU / f64::from(k)).sin();
    let cup = polygon(radius, n) * height - polygon(radius - wall, n) * (height - wall);
    let handle = polygon(0.5 * thickness, n / 4) * reach * std::f64::consts::PI;
    let volume = mug.signed_volume();
    // Cup and handle are each closed, so their signed volumes add.
    assert!(
        (volume - (cup + handle)).abs() / (cup + handle) < 1e-3,
        "{volume} against {}",
        cup + handle
    );
    let symmetry = Primitive::Mug(dimensions).symmetry().unwrap();
    assert!(symmetry.discrete.is_empty() && symmetry.continuous.is_empty());
    for (bad, name) in [
        (
            primitives::mug(&MugShape {
                handle_reach: 0.046,
                ..dimensions
            }),
            "handle_reach",
        ),
        (
            primitives::mug(&MugShape {
                wall: 0.03,
                ..dimensions
            }),
            "wall",
        ),
    ] {
        assert!(
            matches!(bad, Err(RenderError::InvalidDimension { name: found, .. }) if found == name)
        );
    }
}

/// The mug's ambiguity depends on the view: seen from the side with the handle turned away from
/// the camera, a turn of 20° about its axis renders the same depth (but for silhouette pixels
/// of the tessellated cup), with the handle towards the camera it moves the handle's pixels.
#[test]
fn a_mug_turned_about_its_axis_looks_the_same_only_with_its_handle_hidden() {
    let shape = Primitive::Mug(MugShape {
        radius: 0.04,
        height: 0.095,
        wall: 0.004,
        handle_reach: 0.03,
        handle_thickness: 0.008,
        segments: 256,
    });
    let scene = Scene::new(&[shape.mesh().unwrap()]);
    // Model z up the image (camera −y); the handle (+x) away from the camera (+z) or towards it.
    let upright = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    let place = |facing: f64, turn: f64| {
        let rotation = upright
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), facing + turn.to_radians());
        Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), rotation)
    };
    let changed = |facing: f64| {
        let (a, b) = (
            depth_at(&scene, place(facing, 0.0)),
            depth_at(&scene, place(facing, 20.0)),
        );
        a.iter()
            .zip(&b)
            .filter(|(x, y)| (*x - *y).abs() > 2e-4)
            .count()
    };
    // Which way the handle faces: model +x turned by `upright` then by `facing` about z.
    let hidden = std::f64::consts::FRAC_PI_2;
    assert!(
        (upright * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), hidden) * Vector3::x()).z
            > 0.99
    );
    let (away, towards) = (changed(hidden), changed(hidden + std::f64::consts::PI));
    assert!(away <= 12, "{away} pixels differ with the handle hidden");
    assert!(
        towards >= 40,
        "only {towards} pixels differ with the handle in view"
    );
}
