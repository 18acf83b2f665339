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

/// The render-and-compare discrepancy of two depth maps of the same window, in units of the
/// sensor's expected error, robust to sensor noise, holes and occluders:
///
/// `S = (1/|V|) · Σ_{p ∈ V} e(p)`, with `e(p) = min(|observed − rendered| / sigma, cap)` where
/// both maps read a depth (> 0), `e(p) = cap` where only the observed one does (depth that the
/// pose does not explain), and `V` those pixels: where only the rendered map reads, the sensor
/// left a hole (a shadow, an edge, a surface too oblique, dropout), which is no evidence either
/// way. `sigma` is each pixel's expected error (for example
/// [`crate::DepthSensor::expected_errors`]); a typical `cap` is 3. `None` when no pixel is
/// compared. On Gaussian noise the true depth scores E[min(|N(0, 1)|, cap)] ≈ 0.80 at cap 3.
pub fn depth_discrepancy(
    observed: &[f32],
    rendered: &[f32],
    sigma: &[f32],
    cap: f32,
) -> Option<f32> {
    let (mut total, mut count) = (0.0f64, 0u64);
    for ((&o, &r), &s) in observed.iter().zip(rendered).zip(sigma) {
        let (o_valid, r_valid) = (o > 0.0 && o.is_finite(), r > 0.0 && r.is_finite());
        let error = match (o_valid, r_valid) {
            (true, true) => ((o - r).abs() / s.max(f32::MIN_POSITIVE)).min(cap),
            (true, false) => cap,
            (false, _) => continue,
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
        let (sigma, cap) = ([0.001; 3], 3.0);
        let shifted = depth_discrepancy(&[0.5, 0.6], &[0.501, 0.6015], &sigma, cap).unwrap();
        assert!((shifted - 1.25).abs() < 1e-3, "{shifted}");
        // Far errors are capped, a depth not explained costs the cap, a hole nothing.
        let mixed = depth_discrepancy(&[0.5, 0.5, 0.0], &[0.6, 0.0, 0.5], &sigma, cap).unwrap();
        assert!((mixed - cap).abs() < 1e-6);
        // Each pixel in its own σ.
        let scaled = depth_discrepancy(&[0.5, 0.5], &[0.502, 0.502], &[0.001, 0.004], cap);
        assert!((scaled.unwrap() - 1.25).abs() < 1e-3);
    }
}
