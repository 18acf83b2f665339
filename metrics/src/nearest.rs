//! The batched kernel behind MAAD and Recall MAAD: for every rotation of one set, the geodesic
//! distance to the nearest rotation of another.
//!
//! `|⟨p, q⟩|` of unit quaternions is monotone in the geodesic distance, so the nearest member
//! is the one with the largest absolute dot product. Rotations of the first set are processed
//! in lanes of [`LANES`] (structure of arrays, so the compiler vectorises the 4 multiply-adds
//! and the running maximum), in parallel over chunks with rayon. Only the winner's distance is
//! computed with the accurate formula.
use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use so3_grid::geodesic_distance;

const LANES: usize = 8;
const LANES_PER_TASK: usize = 256;

/// For each rotation of `from`, the geodesic distance (radians) to its nearest rotation in
/// `to` (`to` must not be empty).
pub fn nearest_distances(from: &[UnitQuaternion<f64>], to: &[UnitQuaternion<f64>]) -> Vec<f64> {
    debug_assert!(!to.is_empty());
    let targets: [Vec<f64>; 4] = std::array::from_fn(|c| to.iter().map(|q| q.coords[c]).collect());
    let mut out = vec![0.0; from.len()];
    out.par_chunks_mut(LANES * LANES_PER_TASK)
        .zip(from.par_chunks(LANES * LANES_PER_TASK))
        .for_each(|(out, from)| {
            for (out, from) in out.chunks_mut(LANES).zip(from.chunks(LANES)) {
                let best = nearest_in_lanes(from, &targets);
                for ((d, q), &b) in out.iter_mut().zip(from).zip(&best) {
                    *d = geodesic_distance(q, &to[b]);
                }
            }
        });
    out
}

/// Index in `targets` (components x, y, z, w as nalgebra stores them) of the nearest target of
/// each of up to `LANES` rotations.
fn nearest_in_lanes(from: &[UnitQuaternion<f64>], targets: &[Vec<f64>; 4]) -> [usize; LANES] {
    let lane = |c: usize| -> [f64; LANES] {
        std::array::from_fn(|k| from.get(k).map_or(0.0, |q| q.coords[c]))
    };
    let (x, y, z, w) = (lane(0), lane(1), lane(2), lane(3));
    let mut best_dot = [-1.0f64; LANES];
    let mut best = [0usize; LANES];
    let [tx, ty, tz, tw] = targets;
    for t in 0..tx.len() {
        let (a, b, c, d) = (tx[t], ty[t], tz[t], tw[t]);
        for k in 0..LANES {
            let dot = (x[k] * a + y[k] * b + z[k] * c + w[k] * d).abs();
            if dot > best_dot[k] {
                best_dot[k] = dot;
                best[k] = t;
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use so3_grid::random_rotations;

    #[test]
    fn agrees_with_brute_force() {
        let (from, to) = (random_rotations(1000, 1), random_rotations(37, 2));
        let fast = nearest_distances(&from, &to);
        for (q, d) in from.iter().zip(&fast) {
            let brute = to
                .iter()
                .map(|t| geodesic_distance(q, t))
                .fold(f64::INFINITY, f64::min);
            assert!((brute - d).abs() < 1e-12);
        }
    }
}
