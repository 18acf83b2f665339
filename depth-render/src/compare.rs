//! From depth maps back to points, and the render-and-compare score.
use nalgebra::Point3;

use crate::{PinholeCamera, Window};

/// Camera-frame points (metres) of the valid pixels (depth > 0 and finite, and `mask` true where
/// given) of a window-sized, row-major depth map; pixel `(u, v)` of the window is image pixel
/// `(window.u0 + u, window.v0 + v)`.
pub fn unproject(
    camera: &PinholeCamera,
    window: Window,
    depth: &[f32],
    mask: Option<&[bool]>,
) -> Vec<Point3<f32>> {
    let width = window.width() as usize;
    depth
        .iter()
        .enumerate()
        .filter(|&(i, &d)| {
            d > 0.0 && d.is_finite() && mask.is_none_or(|m| m.get(i).copied().unwrap_or(false))
        })
        .map(|(i, &d)| {
            let (u, v) = (
                window.u0 as usize + i % width.max(1),
                window.v0 as usize + i / width.max(1),
            );
            camera
                .unproject(u as f64, v as f64, f64::from(d))
                .cast::<f32>()
        })
        .collect()
}

/// The render-and-compare discrepancy (metres; 0 is a perfect match) of two depth maps of the
/// same window, robust to sensor noise and to occluders:
///
/// `S = (1/|V|) · Σ_{p ∈ V} e(p)`, with `V` the pixels valid (depth > 0) in *either* map,
/// `e(p) = min(|observed − rendered|, clamp)` where both are valid, and `e(p) = clamp` where only
/// one is (a silhouette mismatch costs as much as a gross depth error). `None` when no pixel is
/// valid in either map. A typical `clamp` is 1–2 cm: beyond the sensor noise, below the
/// object's size. Cost: one pass over the window, no allocation.
pub fn depth_discrepancy(observed: &[f32], rendered: &[f32], clamp: f32) -> Option<f32> {
    let (mut total, mut count) = (0.0f64, 0u64);
    for (&o, &r) in observed.iter().zip(rendered) {
        let (o_valid, r_valid) = (o > 0.0 && o.is_finite(), r > 0.0 && r.is_finite());
        let error = match (o_valid, r_valid) {
            (true, true) => (o - r).abs().min(clamp),
            (false, false) => continue,
            _ => clamp,
        };
        total += f64::from(error);
        count += 1;
    }
    (count > 0).then(|| (total / count as f64) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrepancy_follows_its_formula() {
        let clamp = 0.01;
        assert_eq!(depth_discrepancy(&[0.0, 0.0], &[0.0, 0.0], clamp), None);
        assert_eq!(
            depth_discrepancy(&[0.5, 0.6], &[0.5, 0.6], clamp),
            Some(0.0)
        );
        let shifted = depth_discrepancy(&[0.5, 0.6], &[0.501, 0.601], clamp).unwrap();
        assert!((shifted - 0.001).abs() < 1e-6);
        // A pixel valid in one map only costs the clamp; far errors are clamped.
        let mixed = depth_discrepancy(&[0.5, 0.0, 0.5], &[0.5, 0.7, 0.9], clamp).unwrap();
        assert!((mixed - 2.0 * clamp / 3.0).abs() < 1e-7);
    }
}
