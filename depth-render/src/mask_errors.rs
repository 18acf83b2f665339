//! A detector's segmentation errors, applied to an exact instance mask.
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::pixel_grid::{four_neighbours, morph};

/// How far a detector's mask strays from the object's true silhouette: the whole mask grown or
/// shrunk by a whole number of pixels, then its boundary made ragged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MaskErrors {
    /// Each mask is dilated (positive) or eroded (negative) by a number of pixels drawn
    /// uniformly from −`max_shift_px` to `max_shift_px` (a square structuring element).
    pub max_shift_px: u32,
    /// Then each pixel on its boundary (one whose 4-neighbour differs) is flipped with this
    /// probability.
    pub ragged: f32,
}

impl Default for MaskErrors {
    /// Up to one pixel grown or shrunk, a fifth of the boundary pixels flipped (an engineering
    /// choice: no published figure of detector masks' errors in pixels was found).
    fn default() -> Self {
        Self {
            max_shift_px: 1,
            ragged: 0.2,
        }
    }
}

impl MaskErrors {
    /// The mask a detector might give for the exact row-major `mask` of `width` columns;
    /// deterministic for a seed. A mask that erosion would empty is kept as it is before
    /// raggedness (a detector that found the object gives it some pixels).
    pub fn apply(&self, mask: &[bool], width: usize, seed: u64) -> Vec<bool> {
        let width = width.max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let limit = self.max_shift_px as i64;
        let shift = rng.random_range(-limit..=limit);
        let mut out = morph(mask, width, shift.unsigned_abs() as usize, shift > 0);
        if !out.iter().any(|&m| m) {
            out = mask.to_vec();
        }
        let rows = out.len() / width;
        let boundary: Vec<bool> = (0..out.len())
            .map(|i| four_neighbours(i, width, rows).any(|j| out[j] != out[i]))
            .collect();
        for (pixel, on_boundary) in out.iter_mut().zip(boundary) {
            let draw: f32 = rng.random();
            if on_boundary && draw < self.ragged {
                *pixel = !*pixel;
            }
        }
        out
    }
}
