//! A real scanned mesh as users bring it (see `tests/data/SOURCES.md`): YCB's mustard bottle,
//! google_16k, with the two zero-area triangles the scan left.
use std::path::Path;

use depth_render::{Instance, PinholeCamera, Scene, Window, check_mesh_size, load_mesh};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

#[test]
fn the_ycb_mustard_bottle_scan_is_repaired_and_renders() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ycb_006_mustard_bottle.ply");
    let loaded = load_mesh(&path, 1.0).unwrap();
    assert_eq!(loaded.repairs.degenerate_triangles, 2, "{}", loaded.repairs);
    assert_eq!(loaded.repairs.unreferenced_vertices, 0);
    assert_eq!(loaded.mesh.triangles().len(), 16_384 - 2);
    check_mesh_size(&loaded.mesh, &path, 1.0, "scale").unwrap();
    // YCB's bottle is about 96 × 58 × 191 mm.
    let (low, high) = loaded.mesh.bounds();
    let size = high - low;
    let mut sides = [size.x, size.y, size.z];
    sides.sort_by(f32::total_cmp);
    assert!((sides[2] - 0.19).abs() < 0.01, "{size}");
    let camera = PinholeCamera::new(1066.8, 1067.5, 312.99, 241.31, 640, 480).unwrap();
    let pose = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.7),
        UnitQuaternion::from_euler_angles(1.2, 0.3, -0.4),
    );
    let scene = Scene::new(std::slice::from_ref(&loaded.mesh));
    let rendering = scene
        .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
        .unwrap();
    let hits: Vec<f32> = rendering
        .depth
        .iter()
        .copied()
        .filter(|d| *d > 0.0)
        .collect();
    assert!(hits.len() > 5_000, "{} pixels", hits.len());
    // Every hit lies within the bottle's reach of its centre.
    assert!(hits.iter().all(|d| (d - 0.7).abs() < 0.12));
}
