//! A pose from an image model's rotation hypotheses and the frame's depth: what an RGB-D
//! camera gets from a rotation model, as PoseCNN's "+ICP" rows score on YCB-Video. Each
//! hypothesis (a rotation the image makes likely, the most likely first) is placed on the
//! observed points and registered to them by ICP ([`align_from`]: a hypothesis tens of degrees
//! off lands on the pose the depth shows), then scored by render-and-compare. The depth settles
//! what it can see (a rotation roughly right, the place); the image settles what the depth
//! cannot tell apart (a printed box's half turns): of the refined poses that the observation
//! does not tell apart from the best ([`crate::Comparison::told_apart_from`]) and that score
//! under the labeller's acceptance bar (`max_score`, or within `score_margin` of the best where
//! even the best is above it), the one from the most likely hypothesis is chosen.
use nalgebra::{Isometry3, UnitQuaternion};
use rayon::prelude::*;

use crate::instance::{Candidate, LabelFailure, align_from, prepare_view};
use crate::placement::placed;
use crate::{LabelOptions, ObjectModel, Observation};

/// The pose chosen from the hypotheses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeededPose {
    /// The pose (model→camera, metres).
    pub pose: Isometry3<f64>,
    /// Which hypothesis it was refined from (0: the most likely).
    pub hypothesis: usize,
    /// Its render-and-compare score (in the sensor's expected errors).
    pub score: f64,
}

/// The pose of `model` in `observation` seeded by `hypotheses` (rotations, model→camera, the
/// most likely first), as the module describes: each turned about the model's centroid onto
/// the observed points' centroid, registered by ICP, and scored with `options` (moved to the
/// depth's noise as labelling moves them). An error where the observation cannot be
/// registered (no depth in the mask, too few points, a mesh of another scale) or nothing
/// could be compared.
pub fn pose_from_hypotheses(
    model: &ObjectModel,
    observation: &Observation,
    options: &LabelOptions,
    hypotheses: &[UnitQuaternion<f64>],
) -> Result<SeededPose, LabelFailure> {
    let (view, options) = prepare_view(model, observation, options)?;
    let refined: Vec<Candidate> = hypotheses
        .par_iter()
        .map(|rotation| {
            let start = placed(model, &view, *rotation);
            let pose = align_from(model, &view, &start).unwrap_or(start);
            Candidate::compared(model, observation, pose, &options)
        })
        .collect();
    let best = refined
        .iter()
        .filter(|c| c.score().is_finite())
        .min_by(|a, b| a.score().total_cmp(&b.score()))
        .ok_or_else(|| LabelFailure::Registration("no hypothesis could be compared".into()))?;
    // A pose that explains the depth as well as the sensor's noise allows, or nearly as well as
    // the best: real frames and real scans leave a true pose's score a little above its
    // look-alike's (the fixture's cracker box: 0.86 against 0.74), which only the parts where
    // the two differ can decide.
    let limit = options.max_score.max(best.score() + options.score_margin);
    let chosen = refined
        .iter()
        .position(|c| {
            c.score() <= limit
                && match (&c.comparison, &best.comparison) {
                    (Some(mine), Some(theirs)) => !mine.told_apart_from(theirs),
                    _ => false,
                }
        })
        .unwrap_or(0);
    Ok(SeededPose {
        pose: refined[chosen].pose,
        hypothesis: chosen,
        score: refined[chosen].score(),
    })
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_PI_2, PI};

    use depth_render::{DepthSensor, Instance, PinholeCamera, Window};
    use nalgebra::{Translation3, Vector3};
    use so3_grid::geodesic_distance;
    use synth_data::{ObjectKind, SynthObject};

    use super::*;

    /// The built-in cracker box (three different edges: its half turns about its axes show the
    /// same surface) as a Kinect sees it at 0.7 m, tilted so that three faces show.
    struct Seen {
        model: ObjectModel,
        camera: PinholeCamera,
        depth: Vec<f32>,
        mask: Vec<bool>,
        truth: Isometry3<f64>,
    }

    fn seen() -> Seen {
        let object = SynthObject::built_in(ObjectKind::Box).unwrap();
        let model = ObjectModel::new(1, &object.mesh, &LabelOptions::default()).unwrap();
        let camera = PinholeCamera::new(262.5, 262.5, 160.0, 120.0, 320, 240).unwrap();
        let truth = Isometry3::from_parts(
            Translation3::new(0.03, -0.02, 0.7),
            UnitQuaternion::from_euler_angles(0.7, -0.5, 0.4),
        );
        let clean = model
            .scene
            .render(&camera, &[Instance::new(0, truth)], Window::full(&camera))
            .unwrap()
            .depth;
        let mask = clean.iter().map(|&d| d > 0.0).collect();
        let depth = DepthSensor::kinect().apply(&clean, &camera, 3);
        Seen {
            model,
            camera,
            depth,
            mask,
            truth,
        }
    }

    /// The angle (degrees) from `rotation` to the nearest of the truth's four half turns, the
    /// box's symmetries by construction.
    fn to_symmetries(truth: &UnitQuaternion<f64>, rotation: &UnitQuaternion<f64>) -> f64 {
        [Vector3::x(), Vector3::y(), Vector3::z()]
            .iter()
            .map(|axis| *truth * UnitQuaternion::from_scaled_axis(axis * PI))
            .chain([*truth])
            .map(|symmetric| geodesic_distance(&symmetric, rotation).to_degrees())
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn a_wrong_first_hypothesis_gives_way_to_a_rough_one_the_depth_confirms() {
        let seen = seen();
        let observation = Observation::new(seen.camera, &seen.depth, &seen.mask).unwrap();
        let truth = seen.truth.rotation;
        // The first hypothesis a quarter turn off (its long and middle edges swapped), the
        // second 25° off the truth about an oblique axis.
        let wrong = truth * UnitQuaternion::from_scaled_axis(Vector3::z() * FRAC_PI_2);
        let rough = truth
            * UnitQuaternion::from_scaled_axis(
                Vector3::new(1.0, 1.0, 0.0).normalize() * 25f64.to_radians(),
            );
        let found = pose_from_hypotheses(
            &seen.model,
            &observation,
            &LabelOptions::default(),
            &[wrong, rough],
        )
        .unwrap();
        assert_eq!(found.hypothesis, 1);
        let error = to_symmetries(&truth, &found.pose.rotation);
        assert!(error < 2.0, "{error}°");
        let shift = (found.pose.translation.vector - seen.truth.translation.vector).norm();
        assert!(shift < 0.005, "{} mm", shift * 1e3);
    }

    #[test]
    fn the_image_chooses_between_poses_the_depth_cannot_tell_apart() {
        let seen = seen();
        let observation = Observation::new(seen.camera, &seen.depth, &seen.mask).unwrap();
        let truth = seen.truth.rotation;
        // A half turn about the box's thinnest axis shows the camera the same surface: whichever
        // the image makes more likely is kept, refined.
        let half_turn = truth * UnitQuaternion::from_scaled_axis(Vector3::x() * PI);
        let off = |r: UnitQuaternion<f64>| {
            r * UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 1.0, 1.0).normalize() * 0.2)
        };
        for (first, second) in [(truth, half_turn), (half_turn, truth)] {
            let found = pose_from_hypotheses(
                &seen.model,
                &observation,
                &LabelOptions::default(),
                &[off(first), off(second)],
            )
            .unwrap();
            assert_eq!(found.hypothesis, 0);
            let error = geodesic_distance(&first, &found.pose.rotation).to_degrees();
            assert!(error < 2.0, "{error}°");
        }
    }

    #[test]
    fn a_mask_without_depth_is_refused() {
        let seen = seen();
        let depth = vec![0.0; seen.depth.len()];
        let observation = Observation::new(seen.camera, &depth, &seen.mask).unwrap();
        let found = pose_from_hypotheses(
            &seen.model,
            &observation,
            &LabelOptions::default(),
            &[seen.truth.rotation],
        );
        assert_eq!(found, Err(LabelFailure::NoDepth));
    }
}
