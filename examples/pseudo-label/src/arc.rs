//! Dense labels along a continuous ambiguity. Where a view cannot fix a turn of the object (a
//! can about its axis, a mug whose handle is out of sight, a bowl), the accepted poses form an
//! arc, and a few labels spread over the model's symmetries cover a tenth of it. From each
//! label, the turns the observed points leave free ([`registration::weak_turns`]: a near-null
//! direction of the point-to-plane normal equations at the label) are walked both ways in
//! steps of `arc_step_deg`: each step, its shift refined, is scored by render-and-compare and
//! kept while the labels' acceptance rule accepts it (its score, and no part of the object
//! misplaced); a step that fails is refined in the directions the points constrain and kept if
//! it then passes without turning more than half a step (the rule of the reference labeller's
//! cells). A walk ends where the view tells the pose apart (the handle comes into view), where it
//! reaches a pose already kept (the circle closed), after a full turn, or when `arc_labels` poses
//! have been added.
//!
//! A turn about one of the model's own axes of symmetry ([`ObjectModel::symmetry_axes`]: a
//! can's, a bowl's) renders the same depth as the label it starts from: its poses, every
//! `arc_step_deg` round the circle, are added with the label's score and no render, and the
//! free turns along such an axis are not walked.
//!
//! Around the best label, the turns by a step about the model's axes are tried too; where the
//! view accepts them (real frames, whose noise leaves poses 10° apart equally good), the ball
//! they form around each label is filled.
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use registration::{IcpOptions, PreparedCloud, WeakTurn, weak_turns};
use so3_grid::geodesic_distance;

use crate::placement::{MAX_NORMAL_ANGLE, accepted_pose, place_rotation, refine_shift};
use crate::score::Acceptance;
use crate::symmetries::SymmetryAxis;
use crate::{LabelOptions, ObjectModel, Observation};

/// A pose and its score.
type Scored = (Isometry3<f64>, f64);

/// A turn whose eigenvalue is under this fraction of the largest is walked: looser than the
/// refinement's 10⁻³ ([`crate::placement`]), since a walk that the view does not allow ends at
/// its first step, and a can's turn about its axis measured up to 2·10⁻³ on Kinect depth.
const WALK_RATIO: f64 = 1e-2;

/// `labels` (best first) with the poses along their free turns added, best score first; each
/// added pose passes `acceptance`, and every pose kept scores within the score margin of the
/// best of them all.
pub(crate) fn along_free_turns(
    model: &ObjectModel,
    view: &PreparedCloud,
    observation: &Observation,
    options: &LabelOptions,
    labels: Vec<Scored>,
    acceptance: &Acceptance,
) -> Vec<Scored> {
    if options.arc_step_deg <= 0.0 || options.arc_labels == 0 {
        return labels;
    }
    let walk = Walk {
        model,
        view,
        observation,
        options,
        step: options.arc_step_deg.to_radians(),
        acceptance,
    };
    let cap = labels.len() + options.arc_labels;
    let mut kept = Vec::with_capacity(cap);
    // The neighbours of the best label are tried first: where the view tells them apart from
    // it, it tells those of its symmetric counterparts apart from theirs.
    let mut blurred = true;
    for label in &labels {
        // A label on the circle of one before it has its neighbours on theirs.
        if !walk.near_kept(&label.0, &kept) {
            kept.push(*label);
            walk.around_all(label, &mut kept, cap);
            if blurred {
                blurred = walk.nearby(label, &mut kept, cap);
            }
        }
    }
    for label in &labels {
        for turn in walk.free_turns(&label.0) {
            let symmetric = model
                .symmetry_axes
                .iter()
                .any(|a| a.holds(&turn.axis, &turn.point, SAME_AXIS * model.diameter));
            if symmetric {
                continue;
            }
            for sign in [1.0, -1.0] {
                walk.along(label, turn, sign, &mut kept, cap);
            }
        }
    }
    kept.sort_by(|a, b| a.1.total_cmp(&b.1));
    // A walk may find a better pose than the best before it: the score margin holds from that.
    if let Some(best) = kept.first().map(|k| k.1) {
        kept.retain(|k| k.1 <= acceptance.score.min(options.accepted_score(best)));
    }
    kept
}

/// A free turn is about an axis of symmetry when its axis lies within this fraction of the
/// diameter of it (and within 5° of its direction).
pub(crate) const SAME_AXIS: f64 = 0.05;

/// What one walk needs.
struct Walk<'a> {
    model: &'a ObjectModel,
    view: &'a PreparedCloud,
    observation: &'a Observation<'a>,
    options: &'a LabelOptions,
    /// Radians per step.
    step: f64,
    acceptance: &'a Acceptance,
}

impl Walk<'_> {
    /// The free turns of `pose` (model→camera), in the model's frame.
    fn free_turns(&self, pose: &Isometry3<f64>) -> Vec<WeakTurn> {
        let options = IcpOptions {
            max_correspondence_distance: 1.5 * self.model.voxel,
            max_normal_angle: Some(MAX_NORMAL_ANGLE),
            ..IcpOptions::default()
        };
        weak_turns(
            &self.view.cloud,
            &self.model.cloud.cloud,
            &self.model.cloud.index,
            &pose.inverse(),
            &options,
            WALK_RATIO,
        )
        .unwrap_or_default()
    }

    /// [`Walk::around`] each of the model's axes of symmetry.
    fn around_all(&self, start: &Scored, kept: &mut Vec<Scored>, cap: usize) {
        for axis in &self.model.symmetry_axes {
            self.around(start, axis, kept, cap);
        }
    }

    /// Adds the turns of `start` about `axis` every step round the circle, with `start`'s
    /// score, skipping those near a pose already kept, until there are `cap`.
    fn around(&self, start: &Scored, axis: &SymmetryAxis, kept: &mut Vec<Scored>, cap: usize) {
        let steps = (std::f64::consts::TAU / self.step).round().max(1.0) as usize;
        for k in 1..steps {
            if kept.len() >= cap {
                return;
            }
            let angle = std::f64::consts::TAU * k as f64 / steps as f64;
            let candidate = start.0 * axis.turn(angle);
            if !self.near_kept(&candidate, kept) {
                kept.push((candidate, start.1));
            }
        }
    }

    /// Adds the rotations around `start` that the view does not tell apart from it: a flood
    /// fill from `start` over the turns by a step about the model's axes through its centroid
    /// (the centroid kept in place), each kept with its circles about the model's axes of
    /// symmetry when [`Walk::shifted`] accepts it, until there are `cap`.
    /// On clean depth it stops at the first ring; on real frames, whose noise leaves poses
    /// 10° apart equally good, it fills that ball. Whether it added a pose.
    fn nearby(&self, start: &Scored, kept: &mut Vec<Scored>, cap: usize) -> bool {
        let centre = self
            .model
            .cloud
            .cloud
            .centroid()
            .unwrap_or_else(Point3::origin);
        let before = kept.len();
        let mut queue = vec![start.0];
        while let Some(from) = queue.pop() {
            for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
                for sign in [1.0, -1.0] {
                    if kept.len() >= cap {
                        return true;
                    }
                    let turn = UnitQuaternion::from_axis_angle(&axis, sign * self.step);
                    let candidate = from * Isometry3::rotation_wrt_point(turn, centre.cast());
                    if self.near_kept(&candidate, kept) {
                        continue;
                    }
                    if let Some(found) = self.shifted(&candidate) {
                        kept.push(found);
                        self.around_all(&found, kept, cap);
                        queue.push(found.0);
                    }
                }
            }
        }
        kept.len() > before
    }

    /// Whether a pose already kept is within half a step of `candidate`'s rotation.
    fn near_kept(&self, candidate: &Isometry3<f64>, kept: &[Scored]) -> bool {
        kept.iter()
            .any(|k| geodesic_distance(&k.0.rotation, &candidate.rotation) < 0.5 * self.step)
    }

    /// Walks from `start` about `turn` in the direction of `sign`, adding the poses it keeps
    /// to `kept` until there are `cap`.
    fn along(&self, start: &Scored, turn: WeakTurn, sign: f64, kept: &mut Vec<Scored>, cap: usize) {
        let mut current = start.0;
        let mut turned = 0.0;
        while turned + self.step < std::f64::consts::TAU && kept.len() < cap {
            // A left turn of camera→model is a right turn of model→camera.
            let candidate = current * turn.motion(sign * self.step).inverse();
            if self.near_kept(&candidate, kept) {
                return;
            }
            let Some(found) = self.accept(&candidate) else {
                return;
            };
            kept.push(found);
            current = found.0;
            turned += self.step;
        }
    }

    /// `candidate` with its shift refined ([`refine_shift`]) and its score, when it is accepted.
    fn shifted(&self, candidate: &Isometry3<f64>) -> Option<Scored> {
        let pose = refine_shift(self.model, self.view, candidate)?;
        accepted_pose(
            self.model,
            self.observation,
            self.options,
            self.acceptance,
            pose,
        )
    }

    /// `candidate` placed as the reference labeller places a cell ([`place_rotation`]), the
    /// fallback refinement turning it by at most half a step (a walk that strays off the arc
    /// comes back).
    fn accept(&self, candidate: &Isometry3<f64>) -> Option<Scored> {
        place_rotation(
            self.model,
            self.view,
            self.observation,
            self.options,
            self.acceptance,
            candidate,
            0.5 * self.step,
        )
    }
}
