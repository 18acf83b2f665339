//! Render-and-compare: how well a pose of the model explains the observed depth inside the
//! instance's mask, with occluders in front of the object forgiven.
use depth_render::{Instance, PinholeCamera, Scene, Window, depth_discrepancy};
use nalgebra::Isometry3;

use crate::images::mask_box;

/// An observed instance: the image's depth and the instance's visible mask.
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
        })
    }
}

/// The render-and-compare score (metres, lower is better) of the model (mesh 0 of `scene`) at
/// model→camera `pose`: [`depth_discrepancy`] over the observation's window between the masked
/// observed depth and the rendered depth, except that rendered pixels outside the mask behind
/// an observed surface (nearer by more than `clamp`) are occluded and not compared. `None` when
/// nothing is observed or rendered in the window.
pub fn render_and_compare(
    scene: &Scene,
    observation: &Observation,
    pose: &Isometry3<f64>,
    clamp: f32,
) -> Option<f32> {
    let rendering = scene
        .render(
            &observation.camera,
            &[Instance::new(0, *pose)],
            observation.window,
        )
        .ok()?;
    let window = rendering.window;
    let (window_width, image_width) = (window.width() as usize, observation.camera.width as usize);
    let mut observed = Vec::with_capacity(rendering.depth.len());
    let mut rendered = Vec::with_capacity(rendering.depth.len());
    for (i, &r) in rendering.depth.iter().enumerate() {
        let (u, v) = (
            window.u0 as usize + i % window_width,
            window.v0 as usize + i / window_width,
        );
        let pixel = v * image_width + u;
        let depth = observation.depth[pixel];
        if observation.mask[pixel] {
            observed.push(depth);
            rendered.push(r);
        } else if r > 0.0 && depth > 0.0 && depth < r - clamp {
            continue; // an occluder in front of the model: no evidence either way
        } else {
            observed.push(0.0);
            rendered.push(r);
        }
    }
    depth_discrepancy(&observed, &rendered, clamp)
}
