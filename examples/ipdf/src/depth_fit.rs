//! A pose fitted to the depth the camera saw: its translation alone ([`fit_translation`]), or
//! the whole pose from a rotation model's hypotheses ([`pose_from_depth`]).
//!
//! A pose's translation fitted to the depth the camera saw. A translation model reads depth from
//! the crop's apparent size, which occlusion, the image border and the gap between renders and
//! real frames all bend (tens of millimetres at a metre), while where the object lies in the
//! image it reads well. Where the frame has a depth image and the instance a visible mask, the
//! pose is moved along its own line of sight, its rotation kept, until the mesh's surface
//! rendered at it lies on the masked depth. The rotation is the model's: a wrong one (a box's
//! depth-ambiguous half turn) still puts its surface where the camera saw one.
//!
//! ```
//! use depth_render::primitives::cuboid;
//! use depth_render::{Instance, PinholeCamera, Scene, Window};
//! use ipdf::depth_fit::fit_translation;
//! use nalgebra::{Isometry3, Translation3, UnitQuaternion};
//!
//! let mesh = cuboid([0.10, 0.06, 0.04])?;
//! let scene = Scene::new(std::slice::from_ref(&mesh));
//! let camera = PinholeCamera::new(300.0, 300.0, 80.0, 60.0, 160, 120)?;
//! let truth = Isometry3::from_parts(
//!     Translation3::new(0.01, -0.02, 0.6),
//!     UnitQuaternion::from_euler_angles(0.5, -0.4, 0.3),
//! );
//! let depth = scene.render(&camera, &[Instance::new(0, truth)], Window::full(&camera))?.depth;
//! let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
//! // A translation model's guess: the right place in the image, 8 cm too far.
//! let guess = Isometry3::from_parts((truth.translation.vector * 1.13).into(), truth.rotation);
//! let fitted = fit_translation(&scene, &camera, &depth, &mask, &guess).expect("enough depth");
//! assert!((fitted.translation.vector - truth.translation.vector).norm() < 0.001);
//! # Ok::<(), depth_render::RenderError>(())
//! ```
use depth_render::{Instance, PinholeCamera, Scene, Window, unproject};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use pseudo_label::{
    LabelOptions, ObjectModel, Observation, PixelLattice, SeededPose, pose_from_hypotheses,
};

use crate::median::median;

/// Fewest masked pixels with both a depth reading and the rendered surface a step needs.
pub const MIN_PIXELS: usize = 30;
/// Most steps along the line of sight.
const MAX_STEPS: usize = 8;
/// The first step goes along the guess's line of sight where its rendered surface covers at
/// least this share of the mask's readings.
const MIN_COVERAGE: f64 = 0.5;
/// A step shorter than this (metres) ends the fit.
const SETTLED_M: f64 = 1e-4;

/// `pose` (metres, object to camera) moved along its line of sight (its translation scaled,
/// which keeps where the object appears in the image) until the object's surface, rendered by
/// `scene` (the object as its mesh 0, metres) through `camera`, lies on the `depth` image's
/// readings (metres, 0: none; row-major, the camera's size) inside `mask`: each step is the
/// median difference of observed and rendered depth over the masked pixels where both read
/// one, the surface rendered again after it. A guess whose surface covers less than half of the
/// mask's readings (its line of sight misses the object) first moves, in all three directions,
/// by the difference of the per-axis medians of the masked readings' points and of the rendered
/// surface's, and is fitted along its new line of sight; one whose surface lies wholly outside
/// the image (fewer than [`MIN_PIXELS`] pixels of it in view) first puts its origin on the
/// readings' median point.
/// `None` where fewer than [`MIN_PIXELS`] pixels are compared, or for a pose not in front of the
/// camera.
pub fn fit_translation(
    scene: &Scene,
    camera: &PinholeCamera,
    depth: &[f32],
    mask: &[bool],
    pose: &Isometry3<f64>,
) -> Option<Isometry3<f64>> {
    let mut pose = *pose;
    let window = Window::full(camera);
    let readings = mask
        .iter()
        .zip(depth)
        .filter(|&(&m, &d)| m && d > 0.0 && d.is_finite())
        .count();
    // Until the first step along the line of sight, a guess may be moved onto the readings.
    let mut may_move = true;
    let mut stepped = false;
    for _ in 0..MAX_STEPS {
        let rendered = scene
            .render(camera, &[Instance::new(0, pose)], window)
            .ok()?
            .depth;
        let differences = differences(depth, &rendered, mask);
        if may_move && (differences.len() as f64) < MIN_COVERAGE * readings as f64 {
            // The guess shows the object beside most of its mask (a translation model far
            // off): its line of sight misses the object, so the surface's median point first
            // moves onto the masked readings' median point. A guess whose surface the image
            // does not show at all moves its origin there, and its surface the turn after.
            let observed = median_point(&unproject(camera, window, depth, Some(mask)))?;
            match median_point(&unproject(camera, window, &rendered, None)) {
                Some(surface) => {
                    pose.translation.vector += observed - surface;
                    may_move = false;
                }
                None if pose.translation.vector.z > 0.0 => pose.translation.vector = observed,
                None => return None,
            }
            continue;
        }
        may_move = false;
        stepped = true;
        let step = median_of_enough(differences)?;
        let z = pose.translation.vector.z;
        let next = z + step;
        if !next.is_finite() || z <= 0.0 || next <= 0.0 {
            return None;
        }
        pose.translation.vector *= next / z;
        if step.abs() < SETTLED_M {
            break;
        }
    }
    stepped.then_some(pose)
}

/// The pose of `model` (prepared for labelling with `options`) in a frame of `camera` with
/// `depth` (metres, 0: none) and the instance's `mask` (both row-major, the camera's size),
/// found from a rotation model's `hypotheses` (the most likely first): each placed on the
/// masked points and refined by ICP, the depth choosing among them where it tells them apart
/// and the order where it does not ([`pose_from_hypotheses`]), the depth and mask read at
/// every `options.pixel_stride`-th pixel as labelling reads them. `None` where the masked
/// depth cannot be registered (no reading, too few points, a mesh of another scale).
pub fn pose_from_depth(
    model: &ObjectModel,
    options: &LabelOptions,
    camera: &PinholeCamera,
    depth: &[f32],
    mask: &[bool],
    hypotheses: &[UnitQuaternion<f64>],
) -> Option<SeededPose> {
    let lattice = PixelLattice::new(camera, options.pixel_stride);
    let (depth, mask) = (lattice.sample(depth, 0.0), lattice.sample(mask, false));
    let observation = Observation::new(lattice.camera, &depth, &mask)?;
    pose_from_hypotheses(model, &observation, options, hypotheses).ok()
}

/// Observed minus rendered depth over the masked pixels where both read one.
fn differences(observed: &[f32], rendered: &[f32], mask: &[bool]) -> Vec<f64> {
    observed
        .iter()
        .zip(rendered)
        .zip(mask)
        .filter(|((o, r), m)| **m && **r > 0.0 && **o > 0.0 && o.is_finite())
        .map(|((o, r), _)| f64::from(o - r))
        .collect()
}

/// The median (upper middle) of `values`; `None` for fewer than [`MIN_PIXELS`].
fn median_of_enough(mut values: Vec<f64>) -> Option<f64> {
    (values.len() >= MIN_PIXELS).then(|| median(&mut values))
}

/// The per-axis medians of `points`; `None` for fewer than [`MIN_PIXELS`].
pub(crate) fn median_point(points: &[Point3<f32>]) -> Option<Vector3<f64>> {
    let [x, y, z] =
        [0, 1, 2].map(|axis| median_of_enough(points.iter().map(|p| f64::from(p[axis])).collect()));
    Some(Vector3::new(x?, y?, z?))
}

#[cfg(test)]
mod tests {
    use depth_render::primitives::cuboid;
    use depth_render::{DepthSensor, Instance, PinholeCamera, Scene, TriangleMesh, Window};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use proptest::prelude::*;

    use super::fit_translation;

    /// A 320 × 240 camera of a Kinect's focal length at half resolution.
    fn camera() -> PinholeCamera {
        PinholeCamera::new(262.5, 262.5, 160.0, 120.0, 320, 240).unwrap()
    }

    /// A 16 × 9 × 5 cm box (a cereal box's proportions, smaller).
    fn box_mesh() -> TriangleMesh {
        cuboid([0.16, 0.09, 0.05]).unwrap()
    }

    fn truth() -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(0.04, -0.03, 0.9),
            UnitQuaternion::from_euler_angles(0.6, -0.5, 0.4),
        )
    }

    fn render(scene: &Scene, pose: Isometry3<f64>) -> Vec<f32> {
        let camera = camera();
        scene
            .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
            .unwrap()
            .depth
    }

    #[test]
    fn a_translation_guessed_a_tenth_too_far_is_fitted_to_noisy_occluded_depth() {
        let mesh = box_mesh();
        let scene = Scene::new(std::slice::from_ref(&mesh));
        let truth = truth();
        let clean = render(&scene, truth);
        // Kinect v1 noise, and an occluder hiding the left half of the box: the mask keeps the
        // right half only, as a visible mask does.
        let noisy = DepthSensor::kinect().apply(&clean, &camera(), 7);
        let columns: Vec<usize> = (0..clean.len())
            .filter(|&i| clean[i] > 0.0)
            .map(|i| i % 320)
            .collect();
        let middle = (columns.iter().min().unwrap() + columns.iter().max().unwrap()) / 2;
        let mask: Vec<bool> = (0..clean.len())
            .map(|i| clean[i] > 0.0 && i % 320 > middle)
            .collect();
        // A translation model's guess: 9 cm too far, along the line of sight.
        let guess = Isometry3::from_parts(
            Translation3::from(truth.translation.vector * 1.1),
            truth.rotation,
        );
        let fitted = fit_translation(&scene, &camera(), &noisy, &mask, &guess).unwrap();
        let error = (fitted.translation.vector - truth.translation.vector).norm();
        assert!(error < 0.003, "{} mm", error * 1e3);
        assert_eq!(fitted.rotation, truth.rotation);
    }

    #[test]
    fn a_guess_beside_the_mask_or_outside_the_image_is_brought_onto_it_first() {
        let mesh = box_mesh();
        let scene = Scene::new(std::slice::from_ref(&mesh));
        let truth = truth();
        let depth = render(&scene, truth);
        let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
        // 15 cm aside and 10% too far: the box is drawn beside its mask. 80 cm aside: it would
        // be drawn well right of the image's edge, and the image shows none of it.
        let beside = (truth.translation.vector + Vector3::new(0.15, 0.0, 0.0)) * 1.1;
        let outside = truth.translation.vector + Vector3::new(0.8, 0.0, 0.0);
        for (off, shown) in [(beside, true), (outside, false)] {
            let guess = Isometry3::from_parts(Translation3::from(off), truth.rotation);
            assert_eq!(render(&scene, guess).iter().any(|&d| d > 0.0), shown);
            let fitted = fit_translation(&scene, &camera(), &depth, &mask, &guess).unwrap();
            let error = (fitted.translation.vector - truth.translation.vector).norm();
            assert!(error < 0.01, "{} mm", error * 1e3);
        }
    }

    #[test]
    fn a_mask_with_too_few_readings_fits_nothing() {
        let mesh = box_mesh();
        let scene = Scene::new(std::slice::from_ref(&mesh));
        let depth = render(&scene, truth());
        let first: Vec<usize> = (0..depth.len())
            .filter(|&i| depth[i] > 0.0)
            .take(20)
            .collect();
        let mask: Vec<bool> = (0..depth.len()).map(|i| first.contains(&i)).collect();
        assert!(fit_translation(&scene, &camera(), &depth, &mask, &truth()).is_none());
        // A pose that puts the object behind the camera shows no surface to compare.
        let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
        let behind = Isometry3::from_parts(Translation3::new(0.0, 0.0, -1.0), truth().rotation);
        assert!(fit_translation(&scene, &camera(), &depth, &mask, &behind).is_none());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        /// On noise-free depth, a guess on the truth's line of sight up to 15% off in depth
        /// lands within a millimetre of the truth, whatever the box's rotation and place; a
        /// guess off that line stays on its own where its surface covers at least half of the
        /// mask's readings, and is otherwise moved onto them.
        #[test]
        fn a_guess_off_in_depth_lands_on_the_truth_along_its_own_line_of_sight(
            angles in proptest::array::uniform3(-3.0..3.0f64),
            place in proptest::array::uniform3(-1.0..1.0f64),
            offset in proptest::array::uniform3(-1.0..1.0f64),
        ) {
            let mesh = box_mesh();
            let scene = Scene::new(std::slice::from_ref(&mesh));
            let truth = Isometry3::from_parts(
                Translation3::new(0.1 * place[0], 0.08 * place[1], 0.8 + 0.3 * place[2]),
                UnitQuaternion::from_euler_angles(angles[0], angles[1], angles[2]),
            );
            let depth = render(&scene, truth);
            let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
            let scale = 1.0 + 0.15 * offset[2];
            let on_line = Isometry3::from_parts(
                Translation3::from(truth.translation.vector * scale),
                truth.rotation,
            );
            let fitted = fit_translation(&scene, &camera(), &depth, &mask, &on_line).unwrap();
            let error = fitted.translation.vector - truth.translation.vector;
            prop_assert!(error.norm() < 0.001, "{:?} mm", error * 1e3);
            let across = Vector3::new(0.02 * offset[0], 0.02 * offset[1], 0.0);
            let off_line = Isometry3::from_parts(
                Translation3::from((truth.translation.vector + across) * scale),
                truth.rotation,
            );
            let fitted = fit_translation(&scene, &camera(), &depth, &mask, &off_line).unwrap();
            // The share of the mask's readings a pose's rendered surface covers.
            let readings = mask.iter().filter(|&&m| m).count() as f64;
            let coverage = |pose: Isometry3<f64>| {
                super::differences(&depth, &render(&scene, pose), &mask).len() as f64 / readings
            };
            if coverage(off_line) >= super::MIN_COVERAGE {
                let turn = fitted
                    .translation
                    .vector
                    .normalize()
                    .cross(&off_line.translation.vector.normalize())
                    .norm();
                prop_assert!(turn < 1e-12, "{turn}");
            } else {
                // A guess whose line of sight misses most of the object is first moved onto
                // the mask's readings: it ends covering them.
                let covered = coverage(fitted);
                prop_assert!(covered >= super::MIN_COVERAGE, "{covered}");
            }
        }
    }
}
