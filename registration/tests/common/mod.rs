//! A seeded, non-symmetric test object and its partial views.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr_free::gaussian;
use registration::PointCloud;

/// Semi-axes of the ellipsoid the object is a bumpy version of (metres).
const AXES: [f64; 3] = [0.12, 0.077, 0.05];

/// The surface point in direction `u` (unit vector from the object's centre): a radial bump
/// field without any rotational symmetry.
fn surface(u: &Vector3<f64>) -> Vector3<f64> {
    // An egg (one end fatter) with bumps and a twist: no rotation maps it onto itself.
    let taper = 1.0 + 0.35 * u.x + 0.2 * u.y * u.z;
    let bumps = 1.0
        + 0.2 * (3.0 * u.x + 1.0).sin() * (4.0 * u.y).cos()
        + 0.15 * (5.0 * u.z + 2.0 * u.x).sin();
    let bumps = bumps * taper;
    Vector3::new(AXES[0] * u.x, AXES[1] * u.y, AXES[2] * u.z) * bumps
}

/// Surface samples and their outward normals.
pub type Samples = (Vec<Point3<f32>>, Vec<Vector3<f32>>);

/// About `count` surface samples with outward normals, in the model frame.
pub fn model(count: usize) -> Samples {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let (r, a) = ((1.0 - z * z).sqrt(), golden * i as f64);
            let u = Vector3::new(r * a.cos(), r * a.sin(), z);
            let t1 = u
                .cross(&if u.x.abs() < 0.9 {
                    Vector3::x()
                } else {
                    Vector3::y()
                })
                .normalize();
            let t2 = u.cross(&t1);
            let h = 1e-5;
            let p = surface(&u);
            let du = surface(&(u + t1 * h).normalize()) - p;
            let dv = surface(&(u + t2 * h).normalize()) - p;
            let mut n = du.cross(&dv).normalize();
            if n.dot(&p) < 0.0 {
                n = -n;
            }
            (Point3::from(p.cast::<f32>()), n.cast::<f32>())
        })
        .unzip()
}

/// The model moved by `pose` into a camera frame, seen from the origin: points whose normals
/// face the camera, with isotropic Gaussian noise of `sigma` metres.
pub fn view(model: &Samples, pose: &Isometry3<f64>, sigma: f64, seed: u64) -> PointCloud {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pose32 = pose.cast::<f32>();
    let points = model
        .0
        .iter()
        .zip(&model.1)
        .map(|(p, n)| (pose32 * p, pose32.rotation * n))
        .filter(|(p, n)| n.dot(&p.coords) < -0.05 * p.coords.norm())
        .map(|(p, _)| p + Vector3::from_fn(|_, _| (sigma * gaussian(&mut rng)) as f32))
        .collect();
    PointCloud::new(points).unwrap()
}

/// A pose from a unit quaternion's components and a translation.
pub fn pose(quaternion: [f64; 4], translation: [f64; 3]) -> Isometry3<f64> {
    let q = nalgebra::Quaternion::new(quaternion[0], quaternion[1], quaternion[2], quaternion[3]);
    Isometry3::from_parts(
        Translation3::from(Vector3::from(translation)),
        UnitQuaternion::from_quaternion(q),
    )
}

/// Rotation error (degrees) and translation error (metres) of `estimate` against `truth`.
pub fn errors(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    let rotation = (estimate.rotation.inverse() * truth.rotation)
        .angle()
        .to_degrees();
    (
        rotation,
        (estimate.translation.vector - truth.translation.vector).norm(),
    )
}

/// Box–Muller standard normal samples.
mod rand_distr_free {
    use rand::RngExt;
    pub fn gaussian(rng: &mut impl RngExt) -> f64 {
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}
