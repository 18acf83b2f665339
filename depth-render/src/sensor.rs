//! A depth camera's errors, applied to a clean rendering: the two kinds of sensor behind the
//! public RGB-D pose datasets, structured light (Kinect v1, PrimeSense Carmine: LINEMOD,
//! T-LESS, YCB-Video's Xtion) and active stereo (RealSense D4xx), each parameter with its
//! published source.
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::PinholeCamera;
use crate::pixel_grid::{four_neighbours, morph};

/// A depth sensor's errors. Lengths in metres; lengths in pixels are the sensor's own pixels
/// (`focal_px`), converted to a rendering camera's by the ratio of the focal lengths, so that one
/// sensor gives the same angular errors whatever the resolution it is simulated at.
///
/// [`DepthSensor::apply`] turns a clean depth image into what the sensor reads, in this order:
/// 1. *RGB–depth misregistration*: the whole depth image moves by `misregistration_px` in one
///    of the eight directions (drawn per image), against the colour image and its masks;
/// 2. *lateral noise*: each pixel reads the depth of a pixel displaced by a Gaussian of
///    `lateral_sigma_px` (nearest pixel), which makes edges ragged;
/// 3. *invalid pixels*: out of `range`; where the projector (structured light) or the second
///    imager (stereo) does not see the point, i.e. its shadow behind foreground objects, on
///    their left for a `baseline` along +x; the band at the image's left edge that the second
///    imager does not see (`stereo_band`); surfaces seen beyond `max_incidence_deg`; within
///    `edge_radius_px` of a depth discontinuity (a step larger than `edge_step` of the depth)
///    with probability `edge_dropout`; anywhere with probability `dropout`;
/// 4. *axial noise*: Gaussian of σ(z, θ) = `sigma_base` + `sigma_growth`·(z − `sigma_reference_depth`)²,
///    plus `grazing_sigma`/√z · θ²/(π/2 − θ)² beyond θ = 60° of incidence (Nguyen et al.);
/// 5. *quantisation*: the disparity `focal_px`·`baseline`/z is rounded to `disparity_step_px`,
///    and the depth to `depth_unit`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DepthSensor {
    /// σ₀ of the axial noise (m).
    pub sigma_base: f32,
    /// k of the axial noise (1/m).
    pub sigma_growth: f32,
    /// z₀ of the axial noise (m).
    pub sigma_reference_depth: f32,
    /// The axial noise's growth on oblique surfaces (m·√m), beyond 60° of incidence.
    pub grazing_sigma: f32,
    /// Surfaces seen at more than this incidence (degrees, between the normal and the ray)
    /// give no reading.
    pub max_incidence_deg: f32,
    /// The sensor's focal length (pixels of its own depth images).
    pub focal_px: f32,
    /// Distance (m) along the camera's +x axis to the projector or the second imager.
    pub baseline: f32,
    /// Disparity resolution (sensor pixels; 0: none).
    pub disparity_step_px: f32,
    /// Depth resolution (m; 0: none).
    pub depth_unit: f32,
    /// σ of the lateral noise (sensor pixels).
    pub lateral_sigma_px: f32,
    /// Whether the projector's or second imager's shadow gives no reading.
    pub shadows: bool,
    /// Whether the band at the image's left edge that the second imager does not see gives no
    /// reading (stereo).
    pub stereo_band: bool,
    /// Neighbouring depths that differ by more than this fraction of the depth are a
    /// discontinuity.
    pub edge_step: f32,
    /// Pixels this close to a discontinuity (sensor pixels)…
    pub edge_radius_px: f32,
    /// …give no reading with this probability.
    pub edge_dropout: f32,
    /// Any pixel gives no reading with this probability.
    pub dropout: f32,
    /// Nearest and farthest depth read (m).
    pub range: [f32; 2],
    /// Offset of the depth image from the colour image (sensor pixels).
    pub misregistration_px: f32,
}

/// The sensors [`DepthSensor`] has presets of, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorPreset {
    /// [`DepthSensor::kinect`].
    Kinect,
    /// [`DepthSensor::realsense`].
    Realsense,
}

impl SensorPreset {
    /// Every preset.
    pub const ALL: [Self; 2] = [Self::Kinect, Self::Realsense];

    /// `kinect` or `realsense`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Kinect => "kinect",
            Self::Realsense => "realsense",
        }
    }

    /// One line on the sensor.
    pub fn description(self) -> &'static str {
        match self {
            Self::Kinect => {
                "structured light (Kinect v1, PrimeSense Carmine, Xtion: LINEMOD, T-LESS, YCB-Video)"
            }
            Self::Realsense => "active stereo (Intel RealSense D435)",
        }
    }

    /// The sensor.
    pub fn sensor(self) -> DepthSensor {
        match self {
            Self::Kinect => DepthSensor::kinect(),
            Self::Realsense => DepthSensor::realsense(),
        }
    }
}

impl DepthSensor {
    /// Structured light: Kinect v1, PrimeSense Carmine 1.08/1.09, Asus Xtion.
    /// - axial noise σ = 1.2 mm + 1.9 mm/m²·(z − 0.4 m)², and its grazing term 0.1 mm·√m:
    ///   Nguyen, Izadi & Lovell, *Modeling Kinect sensor noise for improved 3D reconstruction
    ///   and tracking*, 3DIMPVT 2012 (the coefficients as in v4r, rotors_simulator and
    ///   elevation_mapping);
    /// - lateral σ 0.8 px: Nguyen et al. at normal incidence;
    /// - focal length 585 px (5.45 mm lens, 9.3 µm pixels), disparity in 1/8 px, i.e. depth in
    ///   steps of 2.85e-3·z² m: Khoshelham & Oude Elberink, *Accuracy and resolution of Kinect
    ///   depth data for indoor mapping applications*, Sensors 12(2) 2012;
    /// - projector 75 mm from the IR camera, casting shadows: render_kinect (Bohg et al., ICRA
    ///   2014) and simkinect (Handa et al., ICRA 2014);
    /// - range 0.5–5 m: Khoshelham & Oude Elberink;
    /// - engineering choices where no measurement is published: no reading beyond 80° of
    ///   incidence (Nguyen's σ reaches 8 mm there at 1 m), half of the pixels within 1 px of a
    ///   step of 2% of the depth lost (the 9×9 correlation window of render_kinect and
    ///   simkinect), 1% random dropout, and a 1 px RGB–depth misregistration.
    pub fn kinect() -> Self {
        Self {
            sigma_base: 0.0012,
            sigma_growth: 0.0019,
            sigma_reference_depth: 0.4,
            grazing_sigma: 0.0001,
            max_incidence_deg: 80.0,
            focal_px: 585.0,
            baseline: 0.075,
            disparity_step_px: 0.125,
            depth_unit: 0.0,
            lateral_sigma_px: 0.8,
            shadows: true,
            stereo_band: false,
            edge_step: 0.02,
            edge_radius_px: 1.0,
            edge_dropout: 0.5,
            dropout: 0.01,
            range: [0.5, 5.0],
            misregistration_px: 1.0,
        }
    }

    /// Active stereo: Intel RealSense D435 at its optimal 848 × 480.
    /// - axial RMS error z²·s/(f·B) with subpixel accuracy s = 0.08, focal length f = 424 px
    ///   (90° field of view) and baseline B = 50 mm, i.e. σ = 3.77 mm/m²·z²: Intel's
    ///   *Tuning depth cameras for best performance* white paper;
    /// - depth in 1 mm units (librealsense's default depth unit);
    /// - lateral σ 1 px: Halmetschlager-Funek et al., *An empirical evaluation of ten depth
    ///   cameras*, IEEE RAM 2019;
    /// - the band B·f/z px wide at the left edge that the right imager does not see: the D400
    ///   datasheet §4.5; the right imager's occlusion shadow on the left of foreground objects;
    /// - range 0.2–10 m (minimum depth at 848 × 480; SAPIEN's simulated D435);
    /// - engineering choices where no measurement is published: Nguyen's grazing term and an 80°
    ///   incidence limit, half of the pixels within 2 px of a step of 2% of the depth lost
    ///   (a 7×7 matching window, as SAPIEN's simulated D4xx), 1% random dropout, and a 1 px
    ///   RGB–depth misregistration.
    pub fn realsense() -> Self {
        Self {
            sigma_base: 0.0,
            sigma_growth: 0.08 / (424.0 * 0.05),
            sigma_reference_depth: 0.0,
            grazing_sigma: 0.0001,
            max_incidence_deg: 80.0,
            focal_px: 424.0,
            baseline: 0.05,
            disparity_step_px: 0.0,
            depth_unit: 0.001,
            lateral_sigma_px: 1.0,
            shadows: true,
            stereo_band: true,
            edge_step: 0.02,
            edge_radius_px: 2.0,
            edge_dropout: 0.5,
            dropout: 0.01,
            range: [0.2, 10.0],
            misregistration_px: 1.0,
        }
    }

    /// The axial noise's σ (m) at depth `z` (m) on a surface facing the camera, before
    /// quantisation.
    pub fn sigma(&self, z: f32) -> f32 {
        self.sigma_base + self.sigma_growth * (z - self.sigma_reference_depth).powi(2)
    }

    /// The axial noise's σ (m) at depth `z` on a surface seen at `incidence` radians.
    pub fn sigma_at_incidence(&self, z: f32, incidence: f32) -> f32 {
        let grazing = if incidence > std::f32::consts::FRAC_PI_3 {
            let ratio = incidence / (std::f32::consts::FRAC_PI_2 - incidence).max(1e-3);
            self.grazing_sigma / z.max(1e-3).sqrt() * ratio * ratio
        } else {
            0.0
        };
        self.sigma(z) + grazing
    }

    /// The spacing (m) of the depths the sensor can read near `z`.
    pub fn step(&self, z: f32) -> f32 {
        let disparity = if self.disparity_step_px > 0.0 {
            z * z * self.disparity_step_px / (self.focal_px * self.baseline)
        } else {
            0.0
        };
        disparity.max(self.depth_unit)
    }

    /// The standard deviation (m) of a reading at depth `z` on a surface facing the camera:
    /// the axial noise and the quantisation's `step²/12` (Sheppard's correction).
    pub fn reading_sigma(&self, z: f32) -> f32 {
        (self.sigma(z).powi(2) + self.step(z).powi(2) / 12.0).sqrt()
    }

    /// The standard deviation (m) of the difference between a reading and the true depth `z` of
    /// a surface whose depth changes by `slope` metres per pixel of a camera of focal length
    /// `focal` pixels: the axial noise at the incidence that the slope implies, the
    /// quantisation, and the lateral noise times the slope. The yardstick of
    /// [`crate::depth_discrepancy`].
    pub fn expected_error(&self, z: f32, slope: f32, focal: f32) -> f32 {
        let z = z.max(1e-3);
        let incidence = (slope * focal / z).atan();
        let lateral = self.lateral_sigma_px * focal / self.focal_px.max(1e-6) * slope;
        (self.sigma_at_incidence(z, incidence).powi(2)
            + self.step(z).powi(2) / 12.0
            + lateral * lateral)
            .sqrt()
    }

    /// [`DepthSensor::expected_error`] at each pixel of the clean, row-major depth map
    /// `rendered` (`width` columns) of a camera of focal length `focal` pixels, its slopes from
    /// central differences over neighbours on the same surface (within `edge_step`), one-sided
    /// where only one is; 0 where nothing is rendered.
    pub fn expected_errors(&self, rendered: &[f32], width: usize, focal: f32) -> Vec<f32> {
        let width = width.max(1);
        let rows = rendered.len() / width;
        let at = |u: usize, v: usize| rendered[v * width + u];
        let mut out = vec![0.0f32; rendered.len()];
        for v in 0..rows {
            for u in 0..width {
                let z = at(u, v);
                if z <= 0.0 {
                    continue;
                }
                let same = |d: f32| Image::continuous(z, d, self.edge_step);
                let derivative = |before: Option<f32>, after: Option<f32>| match (
                    before.filter(|&d| same(d)),
                    after.filter(|&d| same(d)),
                ) {
                    (Some(b), Some(a)) => 0.5 * (a - b),
                    (Some(b), None) => z - b,
                    (None, Some(a)) => a - z,
                    (None, None) => 0.0,
                };
                let du = derivative(
                    u.checked_sub(1).map(|x| at(x, v)),
                    (u + 1 < width).then(|| at(u + 1, v)),
                );
                let dv = derivative(
                    v.checked_sub(1).map(|y| at(u, y)),
                    (v + 1 < rows).then(|| at(u, v + 1)),
                );
                out[v * width + u] = self.expected_error(z, du.hypot(dv), focal);
            }
        }
        out
    }

    /// What the sensor reads of the clean, row-major z-depth image `depth` (m, 0: nothing) of
    /// `camera`, in the colour camera's pixels (see the type's docs). Deterministic for a seed
    /// at any thread count: row `r` draws from ChaCha8 stream `r`. A `depth` shorter than the
    /// camera's image is read as its whole rows.
    pub fn apply(&self, depth: &[f32], camera: &PinholeCamera, seed: u64) -> Vec<f32> {
        let width = camera.width.max(1) as usize;
        let rows = depth.len() / width;
        let scale = (camera.fx as f32 / self.focal_px.max(1e-6)).max(0.0);
        let shifted = shift(&depth[..rows * width], width, self.shift(scale, seed));
        let image = Image {
            depth: &shifted,
            width,
            rows,
        };
        let max_incidence = self.max_incidence_deg.to_radians();
        // Angles under both thresholds act alike, so they need no arccosine.
        let floor = std::f32::consts::FRAC_PI_3.min(max_incidence) - 0.01;
        let incidence = image.incidence(camera, self.edge_step, floor);
        let shadowed = if self.shadows || self.stereo_band {
            image.shadowed(
                camera.fx as f32 * self.baseline,
                self.shadows,
                self.stereo_band,
            )
        } else {
            vec![false; shifted.len()]
        };
        let near_edge = image.near_edge(self.edge_step, (self.edge_radius_px * scale).round());
        let lateral = self.lateral_sigma_px * scale;
        let mut out = vec![0.0f32; shifted.len()];
        out.par_chunks_mut(width).enumerate().for_each(|(v, row)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(v as u64);
            for (u, value) in row.iter_mut().enumerate() {
                // The same numbers for every pixel, so that they do not depend on content.
                let [g_u, g_v, g_z, _] = gaussians(&mut rng);
                let (edge_draw, dropout_draw): (f32, f32) = (rng.random(), rng.random());
                let source = image.displaced(u, v, lateral * g_u, lateral * g_v);
                let z = shifted[source];
                let lost = z <= 0.0
                    || z < self.range[0]
                    || z > self.range[1]
                    || shadowed[source]
                    || incidence[source] > max_incidence
                    || (near_edge[source] && edge_draw < self.edge_dropout)
                    || dropout_draw < self.dropout;
                if !lost {
                    let noisy = z + self.sigma_at_incidence(z, incidence[source]) * g_z;
                    *value = self.quantise(noisy);
                }
            }
        });
        out
    }

    /// The misregistration's offset (pixels of a camera `scale` times the sensor's focal
    /// length) of the image drawn from `seed`.
    fn shift(&self, scale: f32, seed: u64) -> (i64, i64) {
        let length = (self.misregistration_px * scale).round() as i64;
        if length == 0 {
            return (0, 0);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(u64::MAX);
        const DIRECTIONS: [(i64, i64); 8] = [
            (1, 0),
            (1, 1),
            (0, 1),
            (-1, 1),
            (-1, 0),
            (-1, -1),
            (0, -1),
            (1, -1),
        ];
        let (du, dv) = DIRECTIONS[rng.random_range(0..DIRECTIONS.len())];
        (du * length, dv * length)
    }

    /// A depth read: the disparity rounded to its step, then the depth to its unit.
    fn quantise(&self, z: f32) -> f32 {
        let mut z = z.max(0.0);
        let focal_baseline = self.focal_px * self.baseline;
        if self.disparity_step_px > 0.0 && z > 0.0 && focal_baseline > 0.0 {
            let disparity = focal_baseline / z;
            let steps = round(disparity / self.disparity_step_px).max(1.0);
            z = focal_baseline / (steps * self.disparity_step_px);
        }
        if self.depth_unit > 0.0 {
            z = round(z / self.depth_unit) * self.depth_unit;
        }
        z
    }
}

/// `x.round()` (halves away from zero) without a call to libm's `roundf`: x86-64 before
/// SSE4.1, Rust's default target, has no rounding instruction, and the call was 6% of
/// [`DepthSensor::apply`].
fn round(x: f32) -> f32 {
    if x.is_nan() || x.abs() >= 2e9 {
        return x.round();
    }
    let toward_zero = x as i32 as f32;
    // Exact: x and its truncation are within 1 of each other. Without branches: the
    // fraction of a noisy reading is as likely above a half as below.
    let fraction = x - toward_zero;
    toward_zero + f32::from(u8::from(fraction >= 0.5)) - f32::from(u8::from(fraction <= -0.5))
}

/// Four standard normal numbers from four uniform ones (Box–Muller).
pub(crate) fn gaussians(rng: &mut ChaCha8Rng) -> [f32; 4] {
    let mut pair = || {
        let (u1, u2): (f32, f32) = (rng.random(), rng.random());
        let radius = (-2.0 * (1.0 - u1).ln()).sqrt();
        let angle = std::f32::consts::TAU * u2;
        [radius * angle.cos(), radius * angle.sin()]
    };
    let ([a, b], [c, d]) = (pair(), pair());
    [a, b, c, d]
}

/// `depth` moved by `(du, dv)` pixels; what enters from outside reads nothing.
fn shift(depth: &[f32], width: usize, (du, dv): (i64, i64)) -> Vec<f32> {
    if (du, dv) == (0, 0) {
        return depth.to_vec();
    }
    let rows = depth.len() / width;
    let mut out = vec![0.0; depth.len()];
    for v in 0..rows as i64 {
        for u in 0..width as i64 {
            let (su, sv) = (u - du, v - dv);
            if (0..width as i64).contains(&su) && (0..rows as i64).contains(&sv) {
                out[v as usize * width + u as usize] = depth[sv as usize * width + su as usize];
            }
        }
    }
    out
}

/// A row-major depth image and what the sensor's errors need to know of its geometry.
struct Image<'a> {
    depth: &'a [f32],
    width: usize,
    rows: usize,
}

impl Image<'_> {
    /// The index of pixel `(u, v)` moved by `(du, dv)` (rounded), or of `(u, v)` itself when
    /// that leaves the image.
    fn displaced(&self, u: usize, v: usize, du: f32, dv: f32) -> usize {
        let (su, sv) = (u as i64 + round(du) as i64, v as i64 + round(dv) as i64);
        if (0..self.width as i64).contains(&su) && (0..self.rows as i64).contains(&sv) {
            sv as usize * self.width + su as usize
        } else {
            v * self.width + u
        }
    }

    /// Whether the depths `a` and `b` belong to one surface: both read, within `step` of
    /// their depth.
    fn continuous(a: f32, b: f32, step: f32) -> bool {
        a > 0.0 && b > 0.0 && (a - b).abs() <= step * a.min(b)
    }

    /// Each pixel's angle of incidence (radians, between the surface's normal, from its
    /// neighbours on the same surface, and the viewing ray); 0 where no normal can be formed or
    /// the angle is under `floor`.
    fn incidence(&self, camera: &PinholeCamera, edge_step: f32, floor: f32) -> Vec<f32> {
        let floor_cos = floor.cos();
        // Each pixel's camera-frame point, unprojected once (up to six neighbours use it).
        let mut points = vec![nalgebra::Vector3::zeros(); self.depth.len()];
        points
            .par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(v, row)| {
                for (u, point) in row.iter_mut().enumerate() {
                    let z = self.depth[v * self.width + u];
                    if z > 0.0 {
                        let p = camera.unproject(u as f64, v as f64, f64::from(z));
                        *point = nalgebra::Vector3::new(p.x as f32, p.y as f32, p.z as f32);
                    }
                }
            });
        let point = |u: usize, v: usize| points[v * self.width + u];
        let mut angles = vec![0.0f32; self.depth.len()];
        angles
            .par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(v, row)| {
                for (u, angle) in row.iter_mut().enumerate() {
                    let z = self.depth[v * self.width + u];
                    if z <= 0.0 {
                        continue;
                    }
                    let read = |nu: usize, nv: usize| {
                        (nu < self.width && nv < self.rows)
                            .then(|| self.depth[nv * self.width + nu])
                            .filter(|&d| d > 0.0)
                    };
                    // Central differences where both neighbours lie on one plane with the
                    // pixel (inverse depth is affine in the pixel coordinates on a plane, so its
                    // second difference vanishes, however oblique the plane), one-sided where
                    // one neighbour is on the same surface.
                    let tangent = |before: Option<(usize, usize)>, after: (usize, usize)| {
                        let depth_before = before.and_then(|(a, b)| read(a, b));
                        let depth_after = read(after.0, after.1);
                        if let (Some(b), Some(za), Some(zb)) = (before, depth_after, depth_before)
                            && (1.0 / za - 2.0 / z + 1.0 / zb).abs() <= edge_step / z
                        {
                            return Some(point(after.0, after.1) - point(b.0, b.1));
                        }
                        match (before, depth_before, depth_after) {
                            (Some(b), Some(zb), _) if Self::continuous(z, zb, edge_step) => {
                                Some(point(u, v) - point(b.0, b.1))
                            }
                            (_, _, Some(za)) if Self::continuous(z, za, edge_step) => {
                                Some(point(after.0, after.1) - point(u, v))
                            }
                            _ => None,
                        }
                    };
                    let along_u = tangent(u.checked_sub(1).map(|a| (a, v)), (u + 1, v));
                    let along_v = tangent(v.checked_sub(1).map(|b| (u, b)), (u, v + 1));
                    if let (Some(du), Some(dv)) = (along_u, along_v) {
                        let normal = du.cross(&dv);
                        let ray = point(u, v);
                        let cos = normal.dot(&ray).abs() / (normal.norm() * ray.norm()).max(1e-12);
                        if cos < floor_cos {
                            *angle = cos.clamp(0.0, 1.0).acos();
                        }
                    }
                }
            });
        angles
    }

    /// Pixels the projector or second imager, `focal_baseline` = f·B pixel·metres to the +x
    /// side, does not see: behind a nearer surface (`shadows`: some pixel to the right reaches
    /// further left in that view, by more than half a pixel), or beyond its left edge
    /// (`band`).
    fn shadowed(&self, focal_baseline: f32, shadows: bool, band: bool) -> Vec<bool> {
        let mut out = vec![false; self.depth.len()];
        out.par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(v, row)| {
                let depths = &self.depth[v * self.width..(v + 1) * self.width];
                let mut leftmost = f32::INFINITY;
                for u in (0..self.width).rev() {
                    let z = depths[u];
                    if z <= 0.0 {
                        continue;
                    }
                    let seen_at = u as f32 - focal_baseline / z;
                    row[u] = (shadows && seen_at > leftmost + 0.5) || (band && seen_at < 0.0);
                    leftmost = leftmost.min(seen_at);
                }
            });
        out
    }

    /// Pixels within `radius` (Chebyshev distance, pixels) of a depth discontinuity: a
    /// 4-neighbour pair not [`Image::continuous`], or a read pixel beside one that reads
    /// nothing.
    fn near_edge(&self, step: f32, radius: f32) -> Vec<bool> {
        let on_edge: Vec<bool> = (0..self.depth.len())
            .into_par_iter()
            .map(|i| {
                let z = self.depth[i];
                z > 0.0
                    && four_neighbours(i, self.width, self.rows)
                        .any(|j| !Self::continuous(z, self.depth[j], step))
            })
            .collect();
        morph(&on_edge, self.width, radius.max(0.0) as usize, true)
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    proptest! {
        /// The libm-free rounding is `f32::round`, halves and large values included.
        #[test]
        fn round_is_f32_round(x in prop_oneof![
            -1e4f32..1e4,
            (-20_000i32..20_000).prop_map(|k| k as f32 * 0.5),
            proptest::num::f32::ANY,
        ]) {
            let (ours, std) = (super::round(x), x.round());
            prop_assert!(ours == std || ours.is_nan() && std.is_nan(), "{x}: {ours} against {std}");
        }
    }
}
