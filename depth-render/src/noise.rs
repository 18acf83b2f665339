//! A structured-light / time-of-flight depth sensor's errors, applied to clean depth maps.
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Depth noise: Gaussian with a standard deviation growing quadratically with depth (Nguyen,
/// Izadi, Lovell 2012, Kinect axial noise: `σ(z) = σ₀ + k·(z − z₀)²`), quantisation, and dropout
/// of pixels at depth discontinuities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthNoise {
    /// σ₀ (m).
    pub sigma_base: f32,
    /// k (1/m).
    pub sigma_growth: f32,
    /// z₀ (m).
    pub sigma_reference_depth: f32,
    /// Depths are rounded to multiples of this (m); 0 disables quantisation.
    pub quantisation: f32,
    /// A pixel whose depth differs from a 4-neighbour's by more than this (m) is on an edge.
    pub edge_threshold: f32,
    /// Probability that an edge pixel reads no depth.
    pub edge_dropout: f32,
}

impl Default for DepthNoise {
    /// Kinect-v1-like: σ = 1.2 mm + 1.9 mm/m²·(z − 0.4 m)², 1 mm steps, half of the pixels within
    /// a 1 cm step dropped.
    fn default() -> Self {
        Self {
            sigma_base: 0.0012,
            sigma_growth: 0.0019,
            sigma_reference_depth: 0.4,
            quantisation: 0.001,
            edge_threshold: 0.01,
            edge_dropout: 0.5,
        }
    }
}

impl DepthNoise {
    /// The standard deviation (m) at depth `z` (m).
    pub fn sigma(&self, z: f32) -> f32 {
        self.sigma_base + self.sigma_growth * (z - self.sigma_reference_depth).powi(2)
    }

    /// A noisy copy of the row-major `depth` map of `width` columns (0 = no reading stays 0).
    /// Deterministic for a seed at any thread count (row `r` draws from ChaCha8 stream `r`).
    pub fn apply(&self, depth: &[f32], width: usize, seed: u64) -> Vec<f32> {
        let width = width.max(1);
        let rows = depth.len() / width;
        let at = |u: usize, v: usize| depth[v * width + u];
        let mut out = depth.to_vec();
        out.par_chunks_mut(width).enumerate().for_each(|(v, row)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(v as u64);
            for (u, value) in row.iter_mut().enumerate() {
                let z = *value;
                // Draw the same numbers for every pixel so that results do not depend on content.
                let (u1, u2, drop): (f32, f32, f32) = (rng.random(), rng.random(), rng.random());
                if z <= 0.0 {
                    continue;
                }
                let neighbours = [
                    (u.wrapping_sub(1), v),
                    (u + 1, v),
                    (u, v.wrapping_sub(1)),
                    (u, v + 1),
                ];
                let on_edge = neighbours
                    .iter()
                    .filter(|&&(x, y)| x < width && y < rows)
                    .any(|&(x, y)| (at(x, y) - z).abs() > self.edge_threshold);
                if on_edge && drop < self.edge_dropout {
                    *value = 0.0;
                    continue;
                }
                // Box–Muller.
                let gaussian = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
                let mut noisy = z + self.sigma(z) * gaussian;
                if self.quantisation > 0.0 {
                    noisy = (noisy / self.quantisation).round() * self.quantisation;
                }
                *value = noisy.max(0.0);
            }
        });
        out
    }
}
