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
    // Every eighth pixel of every eighth row against a brute-force ray cast: the nearest hit
    // of the pixel's ray (OpenCV's pixel centres) with every triangle of the posed scan,
    // Möller–Trumbore in f64. Rays that graze an edge may hit in one and miss in the other.
    let triangles: Vec<[nalgebra::Point3<f64>; 3]> = loaded
        .mesh
        .triangles()
        .iter()
        .map(|t| t.map(|i| pose * loaded.mesh.positions()[i as usize].cast::<f64>()))
        .collect();
    let (mut compared, mut disagree) = (0, 0);
    for v in (0..480).step_by(8) {
        for u in (0..640).step_by(8) {
            let ray = nalgebra::Vector3::new(
                (f64::from(u) - 312.99) / 1066.8,
                (f64::from(v) - 241.31) / 1067.5,
                1.0,
            );
            let nearest = triangles
                .iter()
                .filter_map(|t| ray_hit(&ray, t))
                .min_by(f64::total_cmp);
            let rendered = f64::from(rendering.depth[(v * 640 + u) as usize]);
            compared += 1;
            match nearest {
                Some(depth) if rendered > 0.0 => {
                    assert!(
                        (depth - rendered).abs() < 1e-4,
                        "({u}, {v}): {rendered} against {depth}"
                    )
                }
                None if rendered == 0.0 => {}
                _ => disagree += 1,
            }
        }
    }
    assert!(
        disagree * 200 <= compared,
        "{disagree} of {compared} pixels hit in one only"
    );
}

/// The ray parameter (here the z-depth, the ray's z being 1) of the hit of the ray from the
/// origin along `ray` with `triangle`, either side facing (Möller and Trumbore 1997).
fn ray_hit(ray: &nalgebra::Vector3<f64>, triangle: &[nalgebra::Point3<f64>; 3]) -> Option<f64> {
    let [a, b, c] = triangle;
    let (ab, ac) = (b - a, c - a);
    let p = ray.cross(&ac);
    let determinant = ab.dot(&p);
    if determinant.abs() < 1e-15 {
        return None;
    }
    let to_a = -a.coords;
    let s = to_a.dot(&p) / determinant;
    let q = to_a.cross(&ab);
    let t = ray.dot(&q) / determinant;
    let depth = ac.dot(&q) / determinant;
    (s >= 0.0 && t >= 0.0 && s + t <= 1.0 && depth > 0.0).then_some(depth)
}
