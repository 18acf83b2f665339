//! Exact nearest grid rotation by branch and bound over the HEALPix hierarchy.
//!
//! Two facts make it exact (Hopf fibration, ψ about the rotated z-axis):
//! - every grid rotation of pixel `p` lies on the fibre `σ(c_p)·Rz(ψ)` over `p`'s centre `c_p`, and the geodesic
//!   distance from a rotation R to any rotation of that fibre is at least the angle between
//!   `R·ẑ` and `c_p` (a rotation by α moves a unit vector by at most α);
//! - along one fibre `|⟨q, base ⊗ q_z(ψ)⟩| = |w cos ψ/2 + z sin ψ/2|` with `(w, z)` from
//!   `base⁻¹ ⊗ q` (`base = σ(c_p)`): it peaks at `ψ* = 2·atan2(z, w)`, so the nearest ψ bin centre is the bin
//!   containing ψ*.
//!
//! Each coarser pixel stores a radius bounding the angle from its centre to every leaf centre
//! below it, so a subtree is skipped when `angle(R·ẑ, centre) − radius ≥ best distance`.
use std::f64::consts::TAU;

use rayon::prelude::*;

use crate::cell::{MAX_LEVEL, pixel_count};
use crate::hopf::{direction, fibre_components, rotated_z_axis};

/// Slack on the pruning bound, above the rounding of `acos` near 0.
const PRUNE_SLACK: f64 = 1e-9;

#[derive(Debug, Clone, Copy)]
struct Node {
    centre: [f64; 3],
    /// Upper bound on the angle from `centre` to every leaf centre in the subtree (radians).
    radius: f64,
}

#[derive(Debug)]
pub(crate) struct NearestIndex {
    /// Nodes of depth 0 ..= level, each depth in nested pixel order.
    depths: Vec<Vec<Node>>,
}

impl NearestIndex {
    pub(crate) fn new(level: u8) -> Self {
        let mut depths: Vec<Vec<Node>> = (0..=level)
            .map(|depth| {
                let layer = cdshealpix::nested::get(depth);
                (0..pixel_count(depth))
                    .into_par_iter()
                    .map(|pixel| {
                        let (lon, lat) = layer.center(pixel);
                        Node {
                            centre: direction(lon, lat),
                            radius: 0.0,
                        }
                    })
                    .collect()
            })
            .collect();
        for depth in (0..level as usize).rev() {
            let (upper, lower) = depths.split_at_mut(depth + 1);
            let (parents, kids) = (&mut upper[depth], &lower[0]);
            for (pixel, node) in parents.iter_mut().enumerate() {
                node.radius = kids[4 * pixel..4 * pixel + 4]
                    .iter()
                    .map(|kid| angle(&node.centre, &kid.centre) + kid.radius)
                    .fold(0.0, f64::max);
            }
        }
        Self { depths }
    }

    /// `(pixel, bin, distance)` of the grid rotation nearest to the unit quaternion `q`.
    pub(crate) fn nearest(
        &self,
        q: &[f64; 4],
        pixel_bases: &[[f64; 4]],
        half_psi: &[[f64; 2]],
    ) -> (u64, u64, f64) {
        let leaf_depth = self.depths.len() - 1;
        let bins = half_psi.len();
        let axis = rotated_z_axis(q);
        let mut best = (0u64, 0u64, f64::INFINITY);
        let mut stack = Stack::default();
        self.push_closest_last(&mut stack, 0, 0..12, &axis, best.2);
        while let Some((depth, pixel, alpha)) = stack.pop() {
            let node = &self.depths[depth][pixel as usize];
            if alpha - node.radius - PRUNE_SLACK >= best.2 {
                continue;
            }
            if depth < leaf_depth {
                self.push_closest_last(
                    &mut stack,
                    depth + 1,
                    4 * pixel..4 * pixel + 4,
                    &axis,
                    best.2,
                );
                continue;
            }
            let (w, z) = fibre_components(&pixel_bases[pixel as usize], q);
            let psi_star = (2.0 * z.atan2(w)).rem_euclid(TAU);
            let bin = ((psi_star / TAU * bins as f64) as usize).min(bins - 1);
            let [c, s] = half_psi[bin];
            let distance = 2.0 * (w * c + z * s).abs().min(1.0).acos();
            if distance < best.2 {
                best = (pixel, bin as u64, distance);
            }
        }
        best
    }

    /// Pushes the pixels of `range` at `depth` that may hold a nearer leaf, farthest first.
    fn push_closest_last(
        &self,
        stack: &mut Stack,
        depth: usize,
        range: std::ops::Range<u64>,
        axis: &[f64; 3],
        best_distance: f64,
    ) {
        let mut candidates = [(0u64, 0.0f64); 12];
        let mut count = 0;
        for pixel in range {
            let node = &self.depths[depth][pixel as usize];
            let alpha = angle(axis, &node.centre);
            if alpha - node.radius - PRUNE_SLACK < best_distance {
                candidates[count] = (pixel, alpha);
                count += 1;
            }
        }
        let candidates = &mut candidates[..count];
        candidates.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
        for &(pixel, alpha) in candidates.iter() {
            stack.push((depth, pixel, alpha));
        }
    }
}

/// A fixed-capacity DFS stack: each expansion pops one pixel and pushes at most 4, so it never
/// holds more than `12 + 3·MAX_LEVEL` entries.
struct Stack {
    items: [(usize, u64, f64); 12 + 3 * MAX_LEVEL as usize],
    len: usize,
}

impl Default for Stack {
    fn default() -> Self {
        Self {
            items: [(0, 0, 0.0); 12 + 3 * MAX_LEVEL as usize],
            len: 0,
        }
    }
}

impl Stack {
    fn push(&mut self, item: (usize, u64, f64)) {
        self.items[self.len] = item;
        self.len += 1;
    }

    fn pop(&mut self) -> Option<(usize, u64, f64)> {
        self.len = self.len.checked_sub(1)?;
        Some(self.items[self.len])
    }
}

fn angle(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .clamp(-1.0, 1.0)
        .acos()
}
