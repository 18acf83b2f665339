//! Registration trials on a synthetic non-symmetric object: its model cloud, and rendered,
//! noisy partial views with their true poses. The data of `benches/benches/registration.rs`,
//! the `registration_trials` example and `benches/python/open3d_registration.py`.
use depth_render::{
    DepthSensor, Instance, PinholeCamera, Scene, TriangleMesh, Window, sample_surface, unproject,
};
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use registration::PointCloud;

use crate::SynthError;

/// A lumpy egg about 24 × 15 × 10 cm: a subdivided sphere whose radius varies with direction
/// (one end fatter, bumps, a twist), so that no rotation maps it onto itself.
pub fn egg_mesh() -> Result<TriangleMesh, SynthError> {
    let sphere = depth_render::primitives::sphere(1.0, 5)?;
    let positions = sphere
        .positions()
        .iter()
        .map(|p| {
            let u = p.coords.cast::<f64>().normalize();
            let taper = 1.0 + 0.35 * u.x + 0.2 * u.y * u.z;
            let bumps = 1.0
                + 0.2 * (3.0 * u.x + 1.0).sin() * (4.0 * u.y).cos()
                + 0.15 * (5.0 * u.z + 2.0 * u.x).sin();
            let radius = Vector3::new(0.12, 0.077, 0.05).component_mul(&u) * taper * bumps;
            Point3::from(radius.cast::<f32>())
        })
        .collect();
    Ok(TriangleMesh::new(positions, sphere.triangles().to_vec())?)
}

/// `count` points sampled uniformly on `mesh`, with its face normals.
pub fn model_cloud(mesh: &TriangleMesh, count: usize, seed: u64) -> Result<PointCloud, SynthError> {
    let (points, normals) = sample_surface(mesh, count, seed);
    Ok(PointCloud::new(points)?.with_normals(normals)?)
}

/// A partial view and the pose that maps the model into it.
#[derive(Debug, Clone)]
pub struct RegistrationTrial {
    /// The unprojected, noisy depth view (camera frame, metres).
    pub view: PointCloud,
    /// Model → camera.
    pub truth: Isometry3<f64>,
}

/// `count` views of `mesh` by a 640 × 480 camera (f = 600 px): uniformly random rotations,
/// the object 0.6–0.8 m away and up to 5 cm off the optical axis, read by
/// [`DepthSensor::kinect`].
pub fn registration_trials(
    mesh: &TriangleMesh,
    count: usize,
    seed: u64,
) -> Result<Vec<RegistrationTrial>, SynthError> {
    let camera = PinholeCamera::new(600.0, 600.0, 320.0, 240.0, 640, 480)?;
    let scene = Scene::new(std::slice::from_ref(mesh));
    let rotations = so3_grid::random_rotations(count, seed);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rotations
        .into_iter()
        .enumerate()
        .map(|(i, rotation)| {
            let mut offset = |half: f64| (rng.random::<f64>() * 2.0 - 1.0) * half;
            let translation = Translation3::new(offset(0.05), offset(0.05), 0.7 + offset(0.1));
            let truth = Isometry3::from_parts(translation, rotation);
            let window = Window::full(&camera);
            let rendering = scene.render(&camera, &[Instance::new(0, truth)], window)?;
            let noisy = DepthSensor::kinect().apply(&rendering.depth, &camera, seed ^ i as u64);
            let view = PointCloud::new(unproject(&camera, window, &noisy, None))?;
            Ok(RegistrationTrial { view, truth })
        })
        .collect()
}
