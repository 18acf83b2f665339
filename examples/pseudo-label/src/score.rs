//! Render-and-compare: how well a pose of the model explains the observed depth inside the
//! instance's mask, with occluders in front of the object forgiven.
use depth_render::{
    DepthSensor, Instance, PinholeCamera, Scene, Window, depth_discrepancy, pixel_discrepancies,
};
use nalgebra::Isometry3;

use bop_dataset::mask_box;

/// An observed instance: the image's depth and the instance's visible mask, and its colour
/// image where there is one.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// The camera of the image.
    pub camera: PinholeCamera,
    /// z-depth of the whole image (metres, 0: no reading), row-major.
    pub depth: &'a [f32],
    /// The instance's visible pixels, row-major, the image's size.
    pub mask: &'a [bool],
    /// The pixels compared: the mask's bounding box with a margin.
    pub window: Window,
    /// The image's 8-bit RGB, row-major, the image's size: what tells apart by colour the
    /// poses that depth cannot ([`crate::appearance_match`]); `None` without one.
    pub colour: Option<&'a [[u8; 3]]>,
}

impl<'a> Observation<'a> {
    /// The observation of `mask` in `depth` (both the camera's size); `None` for an empty
    /// mask. The compared window is the mask's box grown by a fifth of its size (at least 4
    /// pixels) on each side.
    pub fn new(camera: PinholeCamera, depth: &'a [f32], mask: &'a [bool]) -> Option<Self> {
        let [u0, v0, u1, v1] = mask_box(mask, camera.width as usize)?;
        let (margin_u, margin_v) = (((u1 - u0) / 5).max(4), ((v1 - v0) / 5).max(4));
        let window = Window {
            u0: u0.saturating_sub(margin_u),
            v0: v0.saturating_sub(margin_v),
            u1: (u1 + margin_u).min(camera.width),
            v1: (v1 + margin_v).min(camera.height),
        };
        Some(Self {
            camera,
            depth,
            mask,
            window,
            colour: None,
        })
    }

    /// This observation with the image's colours (`None` when their number is not the
    /// image's: a colour image of another size cannot be read pixel by pixel with the depth).
    pub fn with_colour(self, colour: &'a [[u8; 3]]) -> Self {
        let pixels = self.camera.width as usize * self.camera.height as usize;
        Self {
            colour: (colour.len() == pixels).then_some(colour),
            ..self
        }
    }
}

/// The pixels `(n·u, n·v)` of an image, for a stride n ≥ 1: the camera that sees them, and
/// their values read from any per-pixel image of the full camera's size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelLattice {
    /// The camera of the sampled pixels: its pixel `(u, v)` is pixel `(n·u, n·v)` of the image.
    pub camera: PinholeCamera,
    stride: u32,
    image_width: u32,
}

impl PixelLattice {
    /// Every `stride`-th pixel of every `stride`-th row of `camera`'s image (0 reads as 1).
    /// Rays go through integer pixel coordinates, so the focal lengths and the principal point
    /// divide by the stride.
    pub fn new(camera: &PinholeCamera, stride: u32) -> Self {
        let n = stride.max(1);
        let camera_of_lattice = PinholeCamera {
            fx: camera.fx / f64::from(n),
            fy: camera.fy / f64::from(n),
            cx: camera.cx / f64::from(n),
            cy: camera.cy / f64::from(n),
            width: camera.width.div_ceil(n),
            height: camera.height.div_ceil(n),
        };
        Self {
            camera: camera_of_lattice,
            stride: n,
            image_width: camera.width,
        }
    }

    /// The lattice's values of a row-major image of the full camera's size (depth, mask…);
    /// pixels beyond a short slice read as `missing`.
    pub fn sample<T: Copy>(&self, image: &[T], missing: T) -> Vec<T> {
        let (n, width) = (self.stride as usize, self.image_width as usize);
        (0..self.camera.height as usize)
            .flat_map(|v| (0..self.camera.width as usize).map(move |u| v * n * width + u * n))
            .map(|i| image.get(i).copied().unwrap_or(missing))
            .collect()
    }
}

/// The render-and-compare score (in units of the sensor's expected error, lower is better;
/// about 0.8 for the true pose) of the model (mesh 0 of `scene`) at model→camera `pose`:
/// [`depth_discrepancy`] over the observation's window, each pixel's residual divided by
/// `sensor`'s [`DepthSensor::expected_error`] for the rendered surface there and capped at
/// `cap`. Compared are the mask's pixels and the rendered pixels outside the mask: there the
/// observed depth still counts (the object beyond a tight mask agrees with the pose, the
/// background behind a pose that overhangs the object does not), except behind an observed
/// surface nearer by more than `cap` σ (an occluder: no evidence either way). Pixels without a
/// reading are holes, not evidence. `None` when nothing is compared.
pub fn render_and_compare(
    scene: &Scene,
    observation: &Observation,
    pose: &Isometry3<f64>,
    sensor: &DepthSensor,
    cap: f32,
) -> Option<f32> {
    compare_pose(scene, observation, pose, sensor, cap).map(|c| c.score)
}

/// How a pose explains an observation: its [`render_and_compare`] score, which pixels of the
/// observation's window it leaves unexplained (residual at the cap), and the depth it renders
/// there.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The render-and-compare score.
    pub score: f32,
    /// Per pixel of the observation's window (row-major): the pose does not explain it.
    unexplained: Vec<bool>,
    /// Per pixel of the window: the depth the pose renders (0 where it misses the object).
    rendered: Vec<f32>,
    /// Per pixel of the window: the residual at which a depth reads as unexplained (the cap
    /// times the sensor's expected error at the rendered depth).
    tolerance: Vec<f32>,
    /// The window's width.
    width: usize,
}

/// A pose explains fewer pixels than another by more than this many standard deviations of the
/// count (a sign test on the pixels where one pose explains the depth and the other does not)…
const TELL_APART_SIGMAS: f64 = 3.0;

/// …and by more than this many pixels: what tells two poses apart is a part of the object,
/// not a few pixels of noise.
const TELL_APART_PIXELS: f64 = 6.0;

impl Comparison {
    /// Whether the observation tells this pose apart from `other` (a comparison of the same
    /// observation). Only where the two poses place a part of the object differently is there
    /// evidence: the pixels where their renders differ by more than the tolerance (or one
    /// renders the object and the other does not), in patches (each with its four neighbours,
    /// so that a silhouette shifted by a fraction of a millimetre, a line one pixel wide,
    /// counts nothing). Of those pixels, the ones one pose explains and the other does not are
    /// counted, and this pose is told apart when it loses significantly more than chance allows
    /// (a sign test: more than 3 σ and 6 pixels beyond an even split). Poses the view cannot
    /// tell apart place every part alike up to a symmetry, or split such pixels evenly; a pose
    /// that misplaces a small part of the object (a mug's handle) loses the part's pixels,
    /// which a mean over the window hardly notices, even where the sensor leaves holes in a
    /// thin part (the place the poses disagree on is a patch of the renders, not of the
    /// readings).
    pub fn told_apart_from(&self, other: &Comparison) -> bool {
        let differ: Vec<bool> = (0..self.rendered.len().min(other.rendered.len()))
            .map(|i| {
                let (mine, theirs) = (self.rendered[i], other.rendered[i]);
                match (mine > 0.0, theirs > 0.0) {
                    (true, true) => {
                        (mine - theirs).abs() > self.tolerance[i].min(other.tolerance[i])
                    }
                    (false, false) => false,
                    _ => true,
                }
            })
            .collect();
        let part = eroded(&differ, self.width);
        let (mut lost, mut won) = (0usize, 0usize);
        for ((&at, &mine), &theirs) in part.iter().zip(&self.unexplained).zip(&other.unexplained) {
            lost += usize::from(at && mine && !theirs);
            won += usize::from(at && theirs && !mine);
        }
        let excess = lost as f64 - won as f64;
        excess > TELL_APART_SIGMAS * ((lost + won) as f64).sqrt() + TELL_APART_PIXELS
    }
}

/// The pixels of a row-major `mask` `width` pixels wide that are set with their four
/// neighbours: a line one or two pixels wide (a silhouette edge shifted by a fraction of a
/// millimetre) drops out, a patch (a part of the object) keeps its inside.
fn eroded(mask: &[bool], width: usize) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    (0..mask.len())
        .map(|i| {
            let (u, v) = (i % width, i / width);
            u > 0
                && v > 0
                && u + 1 < width
                && v + 1 < height
                && mask[i]
                && mask[i - 1]
                && mask[i + 1]
                && mask[i - width]
                && mask[i + width]
        })
        .collect()
}

/// The acceptance rule of an instance's labels: a pose is accepted when it scores at most
/// `score` and the observation does not tell it apart from the best pose found, `best` (where
/// that could be compared).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Acceptance {
    /// The highest score accepted.
    pub score: f64,
    /// The best pose's comparison.
    pub best: Option<Comparison>,
}

impl Acceptance {
    /// Whether a pose that compares as `comparison` is accepted.
    pub fn accepts(&self, comparison: &Comparison) -> bool {
        f64::from(comparison.score) <= self.score
            && self
                .best
                .as_ref()
                .is_none_or(|best| !comparison.told_apart_from(best))
    }
}

/// [`render_and_compare`] with the pixels the pose leaves unexplained ([`Comparison`]).
pub fn compare_pose(
    scene: &Scene,
    observation: &Observation,
    pose: &Isometry3<f64>,
    sensor: &DepthSensor,
    cap: f32,
) -> Option<Comparison> {
    let rendering = scene
        .render(
            &observation.camera,
            &[Instance::new(0, *pose)],
            observation.window,
        )
        .ok()?;
    let window = rendering.window;
    let (window_width, image_width) = (window.width() as usize, observation.camera.width as usize);
    let sigma =
        sensor.expected_errors(&rendering.depth, window_width, observation.camera.fx as f32);
    let mut observed = Vec::with_capacity(rendering.depth.len());
    let mut rendered = Vec::with_capacity(rendering.depth.len());
    let mut errors = Vec::with_capacity(rendering.depth.len());
    let mut compared = Vec::with_capacity(rendering.depth.len());
    for (i, (&r, &s)) in rendering.depth.iter().zip(&sigma).enumerate() {
        let (u, v) = (
            window.u0 as usize + i % window_width,
            window.v0 as usize + i / window_width,
        );
        let pixel = v * image_width + u;
        let depth = observation.depth[pixel];
        if !observation.mask[pixel] && (r <= 0.0 || (depth > 0.0 && depth < r - cap * s)) {
            continue; // the background beside the object, or an occluder in front of the model
        }
        observed.push(depth);
        rendered.push(r);
        errors.push(s);
        compared.push(i);
    }
    let score = depth_discrepancy(&observed, &rendered, &errors, cap)?;
    let mut unexplained = vec![false; rendering.depth.len()];
    for (&i, error) in compared
        .iter()
        .zip(pixel_discrepancies(&observed, &rendered, &errors, cap))
    {
        unexplained[i] = error.is_some_and(|e| e >= cap);
    }
    let tolerance = sigma.iter().map(|&s| cap * s).collect();
    Some(Comparison {
        score,
        unexplained,
        rendered: rendering.depth,
        tolerance,
        width: window_width,
    })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// Pixel `(u, v)` of the sampled image is pixel `(n·u, n·v)` of the image: the same
        /// depth, the same mask value and the same camera ray; no pixel is left out at the
        /// right or bottom edge.
        #[test]
        fn sampled_pixels_are_the_images_pixels(
            width in 1u32..40,
            height in 1u32..40,
            stride in 1u32..6,
            fx in 100.0..2000.0f64,
            cx in -50.0..50.0f64,
        ) {
            let camera = PinholeCamera::new(fx, 1.1 * fx, cx, cx + 3.0, width, height).unwrap();
            let count = (width * height) as usize;
            let depth: Vec<f32> = (0..count).map(|i| i as f32).collect();
            let mask: Vec<bool> = (0..count).map(|i| i % 3 == 0).collect();
            let lattice = PixelLattice::new(&camera, stride);
            let (sampled_depth, sampled_mask) = (lattice.sample(&depth, 0.0), lattice.sample(&mask, false));
            prop_assert_eq!(lattice.camera.width, (width - 1) / stride + 1);
            prop_assert_eq!(lattice.camera.height, (height - 1) / stride + 1);
            prop_assert_eq!(sampled_depth.len(), (lattice.camera.width * lattice.camera.height) as usize);
            prop_assert_eq!(sampled_depth.len(), sampled_mask.len());
            for (i, (&d, &m)) in sampled_depth.iter().zip(&sampled_mask).enumerate() {
                let (u, v) = (i as u32 % lattice.camera.width, i as u32 / lattice.camera.width);
                let (full_u, full_v) = (u * stride, v * stride);
                let full = (full_v * width + full_u) as usize;
                prop_assert_eq!(d, depth[full]);
                prop_assert_eq!(m, mask[full]);
                let ray = lattice.camera.ray_direction(f64::from(u), f64::from(v));
                let full_ray = camera.ray_direction(f64::from(full_u), f64::from(full_v));
                for k in 0..3 {
                    prop_assert!((ray[k] - full_ray[k]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn short_slices_read_as_empty_pixels() {
        let camera = PinholeCamera::new(500.0, 500.0, 4.0, 4.0, 8, 8).unwrap();
        let lattice = PixelLattice::new(&camera, 2);
        let (depth, mask) = (
            lattice.sample(&[1.0; 10], 0.0),
            lattice.sample(&[true; 10], false),
        );
        assert_eq!(depth.len(), 16);
        assert_eq!(&depth[..5], &[1.0, 1.0, 1.0, 1.0, 0.0]);
        assert!(mask[4..].iter().all(|&m| !m));
    }
}
