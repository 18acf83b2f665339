//! Meshes as scanners and exporters leave them: zero-area triangles, unused vertices and
//! zero-length normals are repaired on loading, counted, and the repaired mesh renders the
//! same depth as the clean one.
use depth_render::{
    Instance, PinholeCamera, Primitive, Scene, TriangleMesh, Window, load_mesh, write_ply,
};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use proptest::prelude::*;

fn can() -> TriangleMesh {
    Primitive::Cylinder {
        radius: 0.04,
        height: 0.1,
        segments: 24,
    }
    .mesh()
    .unwrap()
}

/// `mesh` with `extra` unused vertices put in front of its own, a zero-area triangle (a
/// repeated corner) after every `every`-th triangle, and the normals of the vertices in
/// `zeroed` set to zero; written as PLY (in mm) at `path`.
fn messy_ply(
    mesh: &TriangleMesh,
    extra: usize,
    every: usize,
    zeroed: &[usize],
    path: &std::path::Path,
) -> usize {
    let offset = extra as u32;
    let mut positions: Vec<Point3<f32>> = (0..extra)
        .map(|k| Point3::new(1.0 + k as f32, -2.0, 3.0))
        .collect();
    positions.extend_from_slice(mesh.positions());
    let mut normals: Vec<Vector3<f32>> = vec![Vector3::x(); extra];
    // Normals pointing away from the can's centre, as a scanner's would.
    normals.extend(mesh.positions().iter().map(|p| p.coords.normalize()));
    for &k in zeroed {
        normals[extra + k] = Vector3::zeros();
    }
    let mut triangles = Vec::new();
    let mut degenerate = 0;
    for (k, triangle) in mesh.triangles().iter().enumerate() {
        let [a, b, c] = triangle.map(|i| i + offset);
        triangles.push([a, b, c]);
        if every > 0 && k % every == 0 {
            triangles.push([a, b, a]);
            degenerate += 1;
        }
    }
    let mut bytes = Vec::new();
    write_ply(&mut bytes, &positions, Some(&normals), &triangles, 1e3).unwrap();
    std::fs::write(path, bytes).unwrap();
    degenerate
}

fn depth(mesh: &TriangleMesh) -> Vec<f32> {
    let camera = PinholeCamera::new(572.4, 573.6, 80.0, 60.0, 160, 120).unwrap();
    let pose = Isometry3::from_parts(
        nalgebra::Translation3::new(0.0, 0.0, 0.5),
        UnitQuaternion::from_euler_angles(0.7, -0.3, 0.2),
    );
    let scene = Scene::new(std::slice::from_ref(mesh));
    scene
        .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
        .unwrap()
        .depth
}

#[test]
fn a_messy_can_loads_as_the_clean_can_and_renders_the_same_depth() {
    let dir = tempfile::tempdir().unwrap();
    let clean = can();
    let clean_path = dir.path().join("clean.ply");
    messy_ply(&clean, 0, 0, &[], &clean_path);
    let messy_path = dir.path().join("messy.ply");
    let degenerate = messy_ply(&clean, 7, 5, &[0, 3, 10], &messy_path);
    let tidy = load_mesh(&clean_path, 1e-3).unwrap();
    let repaired = load_mesh(&messy_path, 1e-3).unwrap();
    assert!(tidy.repairs.is_empty());
    assert_eq!(repaired.repairs.degenerate_triangles, degenerate);
    assert_eq!(repaired.repairs.unreferenced_vertices, 7);
    assert_eq!(repaired.repairs.normals, 3);
    assert_eq!(
        repaired.repairs.to_string(),
        format!(
            "dropped {degenerate} zero-area triangles, dropped 7 unreferenced vertices, \
             recomputed 3 normals"
        )
    );
    assert_eq!(repaired.mesh.positions(), tidy.mesh.positions());
    assert_eq!(repaired.mesh.triangles(), tidy.mesh.triangles());
    let rendered = depth(&repaired.mesh);
    assert!(rendered.iter().filter(|d| **d > 0.0).count() > 500);
    assert_eq!(rendered, depth(&tidy.mesh));
    // A recomputed normal points out of the can, as the file's did.
    for k in [0, 3, 10] {
        let fixed = repaired.mesh.normals().unwrap()[k];
        let original = clean.positions()[k].coords.normalize();
        assert!(
            fixed.dot(&original) > 0.5,
            "vertex {k}: {fixed} vs {original}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Whatever junk is added, repair gives back the clean mesh's geometry and counts the junk.
    #[test]
    fn repair_recovers_the_clean_geometry(
        extra in 0usize..12,
        every in 0usize..9,
        zeroed in proptest::collection::btree_set(0usize..50, 0..6),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let clean = can();
        let path = dir.path().join("messy.ply");
        let zeroed: Vec<usize> = zeroed.into_iter().collect();
        let degenerate = messy_ply(&clean, extra, every, &zeroed, &path);
        let loaded = load_mesh(&path, 1e-3).unwrap();
        prop_assert_eq!(loaded.repairs.degenerate_triangles, degenerate);
        prop_assert_eq!(loaded.repairs.unreferenced_vertices, extra);
        prop_assert_eq!(loaded.repairs.normals, zeroed.len());
        prop_assert_eq!(loaded.mesh.triangles(), clean.triangles());
        for (a, b) in loaded.mesh.positions().iter().zip(clean.positions()) {
            prop_assert!((a - b).norm() < 1e-6);
        }
    }
}

#[test]
fn what_cannot_be_repaired_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "nan.obj",
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
            "vertex[1]",
        ),
        (
            "flat.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n3 0 0 1\n",
            "face",
        ),
        (
            "index.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
            "face[0]",
        ),
    ];
    // A colour outside [0, 1] is named by the file's vertex, also after an unused vertex
    // before it was dropped.
    let colour = (
        "colour.ply",
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nproperty float red\nproperty float green\nproperty float blue\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n\
         5 5 5 0 0 0\n0 0 0 0 0 0\n1 0 0 2 0 0\n0 1 0 0 0 0\n3 1 2 3\n",
        "vertex[2].colors",
    );
    for (name, text, field) in cases.into_iter().chain([colour]) {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        match load_mesh(&path, 1.0) {
            Err(depth_render::RenderError::MeshFile {
                field: f, path: p, ..
            }) => {
                assert_eq!(p, path);
                assert!(f.starts_with(field), "{name}: {f}");
            }
            other => panic!("{name}: {other:?}"),
        }
    }
}
