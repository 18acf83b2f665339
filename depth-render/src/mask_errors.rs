//! A detector's segmentation errors, applied to an exact instance mask.
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

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
            .map(|i| {
                let (u, v) = (i % width, i / width);
                [
                    (u.wrapping_sub(1), v),
                    (u + 1, v),
                    (u, v.wrapping_sub(1)),
                    (u, v + 1),
                ]
                .iter()
                .any(|&(x, y)| x < width && y < rows && out[y * width + x] != out[i])
            })
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

/// `mask` dilated (`grow`) or eroded by a (2r + 1)² square; pixels beyond the image count as
/// outside the mask.
fn morph(mask: &[bool], width: usize, radius: usize, grow: bool) -> Vec<bool> {
    if radius == 0 {
        return mask.to_vec();
    }
    let rows = mask.len() / width;
    let pass = |input: &[bool], horizontal: bool| -> Vec<bool> {
        (0..input.len())
            .map(|i| {
                let (u, v) = (i % width, i / width);
                let (position, length) = if horizontal { (u, width) } else { (v, rows) };
                let window = position as i64 - radius as i64..=(position + radius) as i64;
                let mut values = window.map(|p| {
                    (0..length as i64).contains(&p)
                        && if horizontal {
                            input[v * width + p as usize]
                        } else {
                            input[p as usize * width + u]
                        }
                });
                if grow {
                    values.any(|m| m)
                } else {
                    values.all(|m| m)
                }
            })
            .collect()
    };
    pass(&pass(&mask[..rows * width], true), false)
}
