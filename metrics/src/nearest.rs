//! The batched kernel behind MAAD and Recall MAAD: for every rotation of one set, the geodesic
//! distance to the nearest rotation of another.
//!
//! `|⟨p, q⟩|` of unit quaternions is monotone in the geodesic distance (`d = 2·acos|⟨p, q⟩|`),
//! so the nearest member is the one with the largest absolute dot product. The search runs in
//! f32 over blocks of [`BLOCK`] rotations (structure of arrays and a branch-free running
//! maximum, so the compiler vectorises it), in parallel over blocks with rayon. f32 packs twice
//! the lanes of f64; faer GEMM (`benches/benches/metrics.rs`) measured slower.
//! f32 resolves `acos` poorly near 1, so rotations within [`REFINE_BELOW`] of their nearest
//! are re-measured in f64 against the whole set; elsewhere the error is below 1e-4 rad.
use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use so3_grid::geodesic_distance;

/// Rotations of `from` handled together: their components sit in four arrays of this length,
/// so the inner loop over them is a plain vectorisable loop.
const BLOCK: usize = 256;

/// Distances (radians) below which the f32 estimate is replaced by an exact f64 search.
pub const REFINE_BELOW: f64 = 0.03;

/// For each rotation of `from`, the geodesic distance (radians) to its nearest rotation in
/// `to` (infinite when `to` is empty).
pub fn nearest_distances(from: &[UnitQuaternion<f64>], to: &[UnitQuaternion<f64>]) -> Vec<f64> {
    if to.is_empty() {
        return vec![f64::INFINITY; from.len()];
    }
    let targets: Vec<[f32; 4]> = to
        .iter()
        .map(|q| q.coords.map(|c| c as f32).into())
        .collect();
    let refine_dot = (0.5 * REFINE_BELOW).cos() as f32;
    let mut out = vec![0.0; from.len()];
    out.par_chunks_mut(BLOCK)
        .zip(from.par_chunks(BLOCK))
        .for_each(|(out, from)| {
            let best = largest_dots(from, &targets);
            for ((d, q), &dot) in out.iter_mut().zip(from).zip(&best) {
                *d = if dot > refine_dot {
                    to.iter()
                        .map(|t| geodesic_distance(q, t))
                        .fold(f64::INFINITY, f64::min)
                } else {
                    2.0 * f64::from(dot.min(1.0)).acos()
                };
            }
        });
    out
}

/// The largest `|⟨q, t⟩|` over `targets` (components x, y, z, w as nalgebra stores them) of
/// each rotation `q` of a block.
fn largest_dots(block: &[UnitQuaternion<f64>], targets: &[[f32; 4]]) -> [f32; BLOCK] {
    let mut lanes = [[0.0f32; BLOCK]; 4];
    for (k, q) in block.iter().enumerate() {
        for (c, lane) in lanes.iter_mut().enumerate() {
            lane[k] = q.coords[c] as f32;
        }
    }
    let [x, y, z, w] = &lanes;
    let mut best = [0.0f32; BLOCK];
    for &[a, b, c, d] in targets {
        for k in 0..BLOCK {
            let dot = (x[k] * a + y[k] * b + z[k] * c + w[k] * d).abs();
            best[k] = if dot > best[k] { dot } else { best[k] };
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use so3_grid::random_rotations;

    #[test]
    fn near_rotations_are_measured_exactly() {
        let to = random_rotations(50, 3);
        let tiny = UnitQuaternion::from_euler_angles(1e-6, 0.0, 0.0);
        let from: Vec<_> = to.iter().map(|t| t * tiny).collect();
        for d in nearest_distances(&from, &to) {
            assert!((d - 1e-6).abs() < 1e-12, "{d}");
        }
    }

    #[test]
    fn agrees_with_brute_force() {
        let (from, to) = (random_rotations(1000, 1), random_rotations(37, 2));
        let fast = nearest_distances(&from, &to);
        for (q, d) in from.iter().zip(&fast) {
            let brute = to
                .iter()
                .map(|t| geodesic_distance(q, t))
                .fold(f64::INFINITY, f64::min);
            assert!((brute - d).abs() < 1e-4);
        }
    }
}
