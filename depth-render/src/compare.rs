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
    for error in pixel_discrepancies(observed, rendered, sigma, cap).flatten() {
        total += f64::from(error);
        count += 1;
    }
    (count > 0).then(|| (total / count as f64) as f32)
}

/// Each pixel's term `e(p)` of [`depth_discrepancy`] (in expected errors, at most `cap`), or
/// `None` where it is no evidence (no observed depth).
pub fn pixel_discrepancies<'a>(
    observed: &'a [f32],
    rendered: &'a [f32],
    sigma: &'a [f32],
    cap: f32,
) -> impl Iterator<Item = Option<f32>> + 'a {
    observed
        .iter()
        .zip(rendered)
        .zip(sigma)
        .map(move |((&o, &r), &s)| {
            let (o_valid, r_valid) = (o > 0.0 && o.is_finite(), r > 0.0 && r.is_finite());
            match (o_valid, r_valid) {
                (true, true) => Some(((o - r).abs() / s.max(f32::MIN_POSITIVE)).min(cap)),
                (true, false) => Some(cap),
                (false, _) => None,
            }
        })
}

/// The Visible Surface Discrepancy of BOP (Hodaň et al., "On evaluation of 6D object pose
/// estimation", ECCVW 2016): how differently two poses of an object explain what the camera
/// sees, judged only where the object is visible, so that poses the image cannot tell apart
/// (a mug whose handle is hidden, turned about its axis) are equivalent.
///
/// `estimate` and `truth` are the object's depth rendered at the two poses, `observed` the
/// image's depth, all of the same pixels (metres, 0: none). A rendered pixel is visible where
/// the observed depth lies no nearer than `delta` in front of it (or is missing); the error is
/// the fraction of pixels visible under either pose that are not visible under both within
/// `tau` of each other. 0: the same visible surface; 1: nothing in common. BOP 2018 counts a
/// pose as correct below 0.3 with `delta` 15 mm and `tau` 20 mm. `None` when neither pose is
/// visible.
pub fn visible_surface_discrepancy(
    observed: &[f32],
    estimate: &[f32],
    truth: &[f32],
    delta: f32,
    tau: f32,
) -> Option<f32> {
    let visible = |rendered: f32, observed: f32| {
        rendered > 0.0 && (observed <= 0.0 || rendered - observed <= delta)
    };
    let (mut union, mut differing) = (0u64, 0u64);
    for ((&o, &e), &t) in observed.iter().zip(estimate).zip(truth) {
        let (seen_e, seen_t) = (visible(e, o), visible(t, o));
        if seen_e || seen_t {
            union += 1;
            if !(seen_e && seen_t && (e - t).abs() < tau) {
                differing += 1;
            }
        }
    }
    (union > 0).then(|| differing as f32 / union as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visible_surface_discrepancy_counts_the_visible_pixels_that_differ() {
        let (delta, tau) = (0.015, 0.02);
        // Four pixels: the same surface, a surface 3 cm off, one hidden behind an occluder
        // under both poses, one seen under the estimate only.
        let observed = [0.5, 0.5, 0.3, 0.0];
        let estimate = [0.5, 0.53, 0.5, 0.6];
        let truth = [0.505, 0.5, 0.5, 0.0];
        let error = visible_surface_discrepancy(&observed, &estimate, &truth, delta, tau);
        assert_eq!(error, Some(2.0 / 3.0));
        assert_eq!(
            visible_surface_discrepancy(&observed, &truth, &truth, delta, tau),
            Some(0.0)
        );
        assert_eq!(
            visible_surface_discrepancy(&[0.3], &[0.5], &[0.5], delta, tau),
            None
        );
    }

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
