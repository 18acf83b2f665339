//! Pose errors of 6-D object poses against a ground-truth pose, in BOP's conventions: a pose
//! maps model points to the camera frame (`x_cam = R·x + t`) and lengths are in millimetres.
//!
//! - [`translation_error`]: distance between the two translations;
//! - [`add`]: Average Distance of model points, ADD (Hinterstoisser et al., ACCV 2012);
//! - [`add_s`]: its symmetric form ADD-S (ADI in Hodaň et al., ECCVW 2016), the distance to
//!   the nearest transformed model point, through a k-d tree built once in [`ModelPoints`];
//! - [`auc`]: area under the accuracy–threshold curve of such errors (Xiang et al., PoseCNN,
//!   RSS 2018, on YCB-Video).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Isometry3, Point3, Vector3};

use crate::MetricsError;

/// The translation error `|t_est − t_gt|` (mm, camera frame) of two pose translations.
pub fn translation_error(estimate: &Vector3<f64>, truth: &Vector3<f64>) -> f64 {
    (estimate - truth).norm()
}

/// The points of an object model (model frame, mm) and a k-d tree over them, built once and
/// shared by every [`add_s`] call on the model.
pub struct ModelPoints {
    points: Vec<Point3<f64>>,
    tree: ImmutableKdTree<f64, 3>,
}

impl std::fmt::Debug for ModelPoints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModelPoints")
            .field("len", &self.points.len())
            .finish_non_exhaustive()
    }
}

impl ModelPoints {
    /// Copies `points` (model frame, mm) and indexes them. Errors: an empty slice
    /// ([`MetricsError::NoModelPoints`]), a NaN or infinite coordinate
    /// ([`MetricsError::InvalidModelPoint`], naming the first such point).
    pub fn new(points: &[Point3<f64>]) -> Result<Self, MetricsError> {
        if points.is_empty() {
            return Err(MetricsError::NoModelPoints);
        }
        if let Some(position) = points
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(MetricsError::InvalidModelPoint {
                position,
                coordinates: points[position].coords.into(),
            });
        }
        let entries: Vec<[f64; 3]> = points.iter().map(|p| p.coords.into()).collect();
        let tree = ImmutableKdTree::new_from_slice(&entries).map_err(|e| {
            MetricsError::ModelPointIndex {
                reason: e.to_string(),
            }
        })?;
        Ok(Self {
            points: points.to_vec(),
            tree,
        })
    }

    /// Number of points (at least 1).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Always `false`: [`ModelPoints::new`] refuses an empty slice.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points, model frame (mm), in the order given to [`ModelPoints::new`].
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points
    }

    /// The largest distance between two points (mm; 0 for a single point), BOP's object
    /// diameter when the points are the model's vertices.
    ///
    /// Exact (up to rounding) and computed on each call: pairs are visited by decreasing
    /// distance `r` from the centroid and a pair is skipped once `r_i + r_j`, which bounds its
    /// distance, cannot beat the best so far. That prunes most pairs of compact objects; the
    /// worst case (all points on a sphere about the centroid) is all n²/2 pairs: about 50 ms
    /// for 10 000 points, growing as n².
    pub fn diameter(&self) -> f64 {
        let centroid =
            self.points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / self.points.len() as f64;
        let mut by_radius: Vec<(f64, &Point3<f64>)> = self
            .points
            .iter()
            .map(|p| ((p.coords - centroid).norm(), p))
            .collect();
        by_radius.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut best_squared = 0.0_f64;
        for (i, &(r_i, p_i)) in by_radius.iter().enumerate() {
            for &(r_j, p_j) in &by_radius[i + 1..] {
                // r_j only decreases along the inner loop: no later pair can do better.
                if (r_i + r_j).powi(2) <= best_squared {
                    break;
                }
                best_squared = best_squared.max((p_i - p_j).norm_squared());
            }
        }
        best_squared.sqrt()
    }
}

/// ADD: the mean over model points `x` of `|T_est·x − T_gt·x|` (mm, camera frame), where the
/// poses map the model frame to the camera frame (Hinterstoisser et al., "Model based training,
/// detection and pose estimation of texture-less 3D objects in heavily cluttered scenes",
/// ACCV 2012). NaN or infinite when a pose is not finite.
pub fn add(points: &ModelPoints, estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    let sum: f64 = points
        .points
        .iter()
        .map(|x| (estimate * x - truth * x).norm())
        .sum();
    sum / points.len() as f64
}

/// ADD-S: the mean over model points `x` of `min_y |T_est·x − T_gt·y|` (mm), the distance to
/// the nearest ground-truth-posed model point (Hinterstoisser et al., ACCV 2012, for symmetric
/// objects; ADI in Hodaň et al., ECCVW 2016). Unchanged when `estimate` is composed
/// with a symmetry of the point set, and never above [`add`] (up to rounding).
///
/// Queried in the model frame, on the tree built once by [`ModelPoints::new`]:
/// `|T_est·x − T_gt·y| = |T_gt⁻¹·T_est·x − y|` since `T_gt` is rigid. Sequential, hence
/// deterministic: on 10 000 points (about 4 ms) rayon over the points measured no faster on a
/// 2-core machine; parallelise over poses or instances, the outer loop, instead. NaN when a
/// pose is not finite.
pub fn add_s(points: &ModelPoints, estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    let model_from_estimate = truth.inverse() * estimate;
    let sum: f64 = points
        .points
        .iter()
        .map(|x| {
            let query = model_from_estimate * x;
            if !query.coords.iter().all(|c| c.is_finite()) {
                return f64::NAN;
            }
            let nearest = points
                .tree
                .query(&query.coords.into())
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute();
            nearest.distance.sqrt()
        })
        .sum();
    sum / points.len() as f64
}

/// Area under the accuracy–threshold curve, normalised to `[0, 1]`: the fraction of `errors`
/// (mm) below a threshold `τ`, integrated over `τ ∈ [0, max_threshold]` and divided by
/// `max_threshold` (mm). PoseCNN's YCB-Video evaluation (Xiang et al., RSS 2018) scores ADD and
/// ADD-S this way up to 10 cm; BOP-style evaluations up to 10 % of the object diameter.
///
/// Exact, not sampled at thresholds: for one error `e`, `∫₀^M [e < τ] dτ / M = max(0, 1 − e/M)`,
/// so the AUC is the mean of `max(0, 1 − e/M)` over the errors.
///
/// Errors: an empty list ([`MetricsError::NoPoseErrors`]), an error that is negative, NaN or
/// infinite ([`MetricsError::InvalidPoseError`]), a threshold that is not finite and positive
/// ([`MetricsError::InvalidThreshold`]).
pub fn auc(errors: &[f64], max_threshold: f64) -> Result<f64, MetricsError> {
    if !(max_threshold.is_finite() && max_threshold > 0.0) {
        return Err(MetricsError::InvalidThreshold {
            value: max_threshold,
        });
    }
    if errors.is_empty() {
        return Err(MetricsError::NoPoseErrors);
    }
    if let Some(position) = errors.iter().position(|e| !(e.is_finite() && *e >= 0.0)) {
        return Err(MetricsError::InvalidPoseError {
            position,
            value: errors[position],
        });
    }
    let sum: f64 = errors
        .iter()
        .map(|e| (1.0 - e / max_threshold).max(0.0))
        .sum();
    Ok(sum / errors.len() as f64)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    fn cube_corners(half_side: f64) -> Vec<Point3<f64>> {
        (0..8)
            .map(|k| {
                let s = |bit: u32| {
                    if k & (1 << bit) == 0 {
                        -half_side
                    } else {
                        half_side
                    }
                };
                Point3::new(s(0), s(1), s(2))
            })
            .collect()
    }

    fn pseudo_random_points(n: usize) -> Vec<Point3<f64>> {
        // A fixed low-discrepancy-like sequence: deterministic, no rand dependency.
        (0..n)
            .map(|i| {
                let f = |a: f64| ((i as f64 + 1.0) * a).fract() * 100.0 - 50.0;
                Point3::new(f(0.754_877_666), f(0.569_840_291), f(0.362_436_069) * 0.4)
            })
            .collect()
    }

    #[test]
    fn translation_error_is_euclidean() {
        let d = translation_error(&Vector3::new(1.0, 2.0, 3.0), &Vector3::new(4.0, 6.0, 3.0));
        assert_eq!(d, 5.0);
    }

    #[test]
    fn model_points_refuse_bad_input() {
        assert!(matches!(
            ModelPoints::new(&[]),
            Err(MetricsError::NoModelPoints)
        ));
        let points = [Point3::origin(), Point3::new(1.0, f64::NAN, 0.0)];
        assert!(matches!(
            ModelPoints::new(&points),
            Err(MetricsError::InvalidModelPoint { position: 1, .. })
        ));
        let points = [Point3::new(f64::NEG_INFINITY, 0.0, 0.0)];
        assert!(matches!(
            ModelPoints::new(&points),
            Err(MetricsError::InvalidModelPoint { position: 0, .. })
        ));
    }

    #[test]
    fn cube_diameter_is_its_space_diagonal() {
        let model = ModelPoints::new(&cube_corners(10.0)).unwrap();
        assert_eq!(model.len(), 8);
        assert!(!model.is_empty());
        assert!((model.diameter() - 20.0 * 3f64.sqrt()).abs() < 1e-12);
        let single = ModelPoints::new(&[Point3::new(1.0, 2.0, 3.0)]).unwrap();
        assert_eq!(single.diameter(), 0.0);
    }

    #[test]
    fn diameter_matches_all_pairs() {
        let points = pseudo_random_points(500);
        let expected = points
            .iter()
            .flat_map(|p| points.iter().map(move |q| (p - q).norm()))
            .fold(0.0, f64::max);
        let model = ModelPoints::new(&points).unwrap();
        assert!((model.diameter() - expected).abs() <= 1e-12 * expected);
    }

    #[test]
    fn cube_quarter_turn_is_free_for_add_s_only() {
        let model = ModelPoints::new(&cube_corners(10.0)).unwrap();
        let truth = Isometry3::translation(0.0, 0.0, 500.0);
        let quarter_turn =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let estimate = truth * Isometry3::from_parts(Translation3::identity(), quarter_turn);
        assert!(add_s(&model, &estimate, &truth) < 1e-9);
        // Every corner moves to a neighbouring corner, one side (20 mm) away.
        assert!((add(&model, &estimate, &truth) - 20.0).abs() < 1e-9);
    }

    #[test]
    fn non_finite_poses_give_nan() {
        let model = ModelPoints::new(&cube_corners(1.0)).unwrap();
        let bad = Isometry3::translation(f64::NAN, 0.0, 0.0);
        let good = Isometry3::identity();
        assert!(add(&model, &bad, &good).is_nan());
        assert!(add_s(&model, &bad, &good).is_nan());
        assert!(add_s(&model, &good, &bad).is_nan());
        let far = Isometry3::translation(f64::INFINITY, 0.0, 0.0);
        assert!(add_s(&model, &far, &good).is_nan());
    }

    #[test]
    fn auc_is_the_mean_clipped_score() {
        let auc = auc(&[0.0, 2.5, 5.0, 20.0], 10.0).unwrap();
        assert!((auc - (1.0 + 0.75 + 0.5 + 0.0) / 4.0).abs() < 1e-15);
    }

    #[test]
    fn auc_refuses_bad_input() {
        assert!(matches!(auc(&[], 1.0), Err(MetricsError::NoPoseErrors)));
        for value in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                auc(&[1.0], value),
                Err(MetricsError::InvalidThreshold { .. })
            ));
        }
        for value in [-1e-12, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                auc(&[0.0, value], 1.0),
                Err(MetricsError::InvalidPoseError { position: 1, .. })
            ));
        }
    }
}
