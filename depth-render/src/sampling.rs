//! Area-weighted uniform sampling of mesh surfaces.
use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::TriangleMesh;

/// `count` points distributed uniformly over the surface of `mesh` (each triangle chosen with
/// probability proportional to its area, then a uniform point inside it), with the unit
/// outward normal of the triangle each lies on. Deterministic for a seed.
pub fn sample_surface(
    mesh: &TriangleMesh,
    count: usize,
    seed: u64,
) -> (Vec<Point3<f32>>, Vec<Vector3<f32>>) {
    let mut cumulative = Vec::with_capacity(mesh.triangles().len());
    let mut total = 0.0f64;
    for t in 0..mesh.triangles().len() {
        let [a, b, c] = mesh.corners(t).map(|p| p.cast::<f64>());
        total += 0.5 * (b - a).cross(&(c - a)).norm();
        cumulative.push(total);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut points = Vec::with_capacity(count);
    let mut normals = Vec::with_capacity(count);
    for _ in 0..count {
        let target = rng.random::<f64>() * total;
        let t = cumulative
            .partition_point(|&c| c < target)
            .min(cumulative.len() - 1);
        let [a, b, c] = mesh.corners(t).map(|p| p.cast::<f64>());
        // Uniform in the triangle: (1 − √r₁, √r₁(1 − r₂), √r₁ r₂) (Osada et al. 2002).
        let (r1, r2): (f64, f64) = (rng.random(), rng.random());
        let s = r1.sqrt();
        let p = a.coords * (1.0 - s) + b.coords * (s * (1.0 - r2)) + c.coords * (s * r2);
        points.push(Point3::from(p).cast::<f32>());
        normals.push((b - a).cross(&(c - a)).normalize().cast::<f32>());
    }
    (points, normals)
}
