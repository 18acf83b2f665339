//! Pose solves: Gauss–Newton normal equations in the 6-DoF twist, and closed-form Kabsch.

use std::ops::{AddAssign, SubAssign};

use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, SymmetricEigen, Translation3, Unit, UnitQuaternion,
    Vector3, Vector6,
};

/// Normal equations JᵀWJ ξ = −JᵀWr for a left update `exp(ξ) · pose`, ξ = (ω, t): rotation
/// vector ω (radians) then translation t (metres). Residuals are linearised at ξ = 0, where
/// the moved point p becomes p + ω × p + t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NormalEquations {
    jtj: Matrix6<f64>,
    jtr: Vector6<f64>,
}

impl NormalEquations {
    /// No residuals yet.
    pub(crate) fn new() -> Self {
        Self {
            jtj: Matrix6::zeros(),
            jtr: Vector6::zeros(),
        }
    }

    fn add_row(&mut self, jacobian: Vector6<f64>, residual: f64, weight: f64) {
        self.jtj += jacobian * jacobian.transpose() * weight;
        self.jtr += jacobian * (residual * weight);
    }

    /// The Gauss–Newton update without the directions the residuals hardly constrain (Zhang,
    /// Kaess & Singh 2016, "On degeneracy of optimization-based state estimation problems"):
    /// the system is taken to a turn about `centre` and a shift, the turn in metres swept at
    /// `radius`, and only its eigenvectors with an eigenvalue of at least `min_ratio` times the
    /// largest are solved for. `None` when no direction is constrained or the result is not
    /// finite.
    pub(crate) fn solve_constrained(
        &self,
        centre: &Point3<f64>,
        radius: f64,
        min_ratio: f64,
    ) -> Option<Isometry3<f64>> {
        let (change, eigen) = self.about_centre(centre, radius);
        let gradient = change.transpose() * self.jtr;
        let largest = eigen.eigenvalues.max();
        if !(largest.is_finite() && largest > 0.0) {
            return None;
        }
        let mut solved = Vector6::zeros();
        for (k, &value) in eigen.eigenvalues.iter().enumerate() {
            if value >= min_ratio * largest && value > 0.0 {
                let direction = eigen.eigenvectors.column(k);
                solved -= direction * (direction.dot(&gradient) / value);
            }
        }
        let step = change * solved;
        step.iter()
            .all(|v| v.is_finite())
            .then(|| isometry_from_twist(&step))
    }

    /// The turns the residuals hardly constrain: in the frame of [`Self::solve_constrained`]
    /// (a turn about `centre` swept at `radius`, and a shift), the eigenvectors with an
    /// eigenvalue under `min_ratio` times the largest whose turn sweeps more than their shift
    /// moves, each as a unit axis and a point on it (the shift that goes with the turn, taken
    /// back to an axis; a component along the axis, a screw's pitch, is dropped), with its
    /// eigenvalue ratio.
    pub(crate) fn weak_turns(
        &self,
        centre: &Point3<f64>,
        radius: f64,
        min_ratio: f64,
    ) -> Vec<(Unit<Vector3<f64>>, Point3<f64>, f64)> {
        let (change, eigen) = self.about_centre(centre, radius);
        let largest = eigen.eigenvalues.max();
        if !(largest.is_finite() && largest > 0.0) {
            return Vec::new();
        }
        let mut turns = Vec::new();
        for (k, &value) in eigen.eigenvalues.iter().enumerate() {
            let direction: Vector6<f64> = eigen.eigenvectors.column(k).into();
            let (turn, shift) = (
                direction.fixed_rows::<3>(0).norm(),
                direction.fixed_rows::<3>(3).norm(),
            );
            if value >= min_ratio * largest || turn <= shift {
                continue;
            }
            let twist = change * direction;
            let omega: Vector3<f64> = twist.fixed_rows::<3>(0).into();
            let t: Vector3<f64> = twist.fixed_rows::<3>(3).into();
            let point = Point3::from(omega.cross(&t) / omega.norm_squared());
            turns.push((Unit::new_normalize(omega), point, value / largest));
        }
        turns
    }

    /// The system taken to a turn about `centre` swept at `radius` and a shift: the change of
    /// variables ξ = M ξc and the eigen-decomposition of MᵀJᵀJM.
    fn about_centre(
        &self,
        centre: &Point3<f64>,
        radius: f64,
    ) -> (Matrix6<f64>, SymmetricEigen<f64, nalgebra::U6>) {
        // ξ (about the origin) = M ξc (a turn about the centre): t = tc + c × ω.
        let mut about_centre = Matrix6::identity();
        about_centre
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&centre.coords.cross_matrix());
        let turn = 1.0 / radius.max(f64::MIN_POSITIVE);
        let scale = Matrix6::from_diagonal(&Vector6::new(turn, turn, turn, 1.0, 1.0, 1.0));
        let change = about_centre * scale;
        let eigen = SymmetricEigen::new(change.transpose() * self.jtj * change);
        (change, eigen)
    }

    /// Residual `moved − target` (3 rows), Jacobian [−[moved]×, I]. Accumulated in closed form:
    /// JᵀJ = [[‖p‖²I − ppᵀ, [p]×], [−[p]×, I]] and Jᵀr = [p × r, r] for p = `moved`.
    pub(crate) fn add_point_to_point(
        &mut self,
        moved: &Vector3<f64>,
        target: &Vector3<f64>,
        weight: f64,
    ) {
        let residual = (moved - target) * weight;
        let p = moved;
        let skew = p.cross_matrix() * weight;
        let rotational = (Matrix3::identity() * p.norm_squared() - p * p.transpose()) * weight;
        self.jtj
            .fixed_view_mut::<3, 3>(0, 0)
            .add_assign(&rotational);
        self.jtj.fixed_view_mut::<3, 3>(0, 3).add_assign(&skew);
        self.jtj.fixed_view_mut::<3, 3>(3, 0).sub_assign(&skew);
        self.jtj
            .fixed_view_mut::<3, 3>(3, 3)
            .add_assign(&(Matrix3::identity() * weight));
        self.jtr
            .fixed_rows_mut::<3>(0)
            .add_assign(&p.cross(&residual));
        self.jtr.fixed_rows_mut::<3>(3).add_assign(&residual);
    }

    /// Residual `(moved − target) · normal` (1 row), Jacobian [moved × normal, normal].
    pub(crate) fn add_point_to_plane(
        &mut self,
        moved: &Vector3<f64>,
        target: &Vector3<f64>,
        normal: &Vector3<f64>,
        weight: f64,
    ) {
        let residual = (moved - target).dot(normal);
        let rotation = moved.cross(normal);
        self.add_row(
            Vector6::new(
                rotation.x, rotation.y, rotation.z, normal.x, normal.y, normal.z,
            ),
            residual,
            weight,
        );
    }

    /// The Gauss–Newton update of the shift alone, the rotation held, without the directions
    /// whose eigenvalue is under `min_ratio` times the largest (and never one under 10⁻⁹ of
    /// it: those are numerically zero). `None` when the residuals fix no direction of the
    /// shift or the result is not finite.
    pub(crate) fn solve_shift(&self, min_ratio: f64) -> Option<Isometry3<f64>> {
        let normal: Matrix3<f64> = self.jtj.fixed_view::<3, 3>(3, 3).into_owned();
        let gradient: Vector3<f64> = self.jtr.fixed_rows::<3>(3).into_owned();
        let eigen = SymmetricEigen::new(normal);
        let largest = eigen.eigenvalues.max();
        if !(largest.is_finite() && largest > 0.0) {
            return None;
        }
        let mut shift = Vector3::zeros();
        for (k, &value) in eigen.eigenvalues.iter().enumerate() {
            if value >= min_ratio.max(1e-9) * largest {
                let direction = eigen.eigenvectors.column(k);
                shift -= direction * (direction.dot(&gradient) / value);
            }
        }
        shift
            .iter()
            .all(|v| v.is_finite())
            .then(|| Isometry3::from_parts(Translation3::from(shift), UnitQuaternion::identity()))
    }

    /// The Gauss–Newton update, or `None` when the system is singular (too few or degenerate
    /// residuals) or not finite.
    pub(crate) fn solve(&self) -> Option<Isometry3<f64>> {
        let step = -self.jtj.cholesky()?.solve(&self.jtr);
        step.iter()
            .all(|v| v.is_finite())
            .then(|| isometry_from_twist(&step))
    }
}

/// exp of the twist (ω, t), taken as rotation by ω followed by translation by t.
pub(crate) fn isometry_from_twist(twist: &Vector6<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(twist[3], twist[4], twist[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(twist[0], twist[1], twist[2])),
    )
}

/// The shift minimising Σ wᵢ ‖sᵢ + t − dᵢ‖²: the weighted mean of dᵢ − sᵢ. `None` for no pairs
/// or zero total weight.
pub(crate) fn mean_shift(pairs: &[(Point3<f64>, Point3<f64>, f64)]) -> Option<Isometry3<f64>> {
    let total: f64 = pairs.iter().map(|p| p.2).sum();
    if pairs.is_empty() || total.is_nan() || total <= 0.0 {
        return None;
    }
    let shift = pairs
        .iter()
        .map(|(s, d, w)| (d - s) * *w)
        .sum::<Vector3<f64>>()
        / total;
    Some(Isometry3::from_parts(
        Translation3::from(shift),
        UnitQuaternion::identity(),
    ))
}

/// The rigid transform minimising Σ wᵢ ‖T sᵢ − dᵢ‖² in closed form (Kabsch 1976 / Umeyama
/// 1991 without scale): SVD of the weighted cross-covariance. `None` for fewer than three
/// pairs, zero total weight or collinear points.
pub fn kabsch(pairs: &[(Point3<f64>, Point3<f64>, f64)]) -> Option<Isometry3<f64>> {
    let total: f64 = pairs.iter().map(|p| p.2).sum();
    if pairs.len() < 3 || total.is_nan() || total <= 0.0 {
        return None;
    }
    let source_mean = pairs
        .iter()
        .map(|(s, _, w)| s.coords * *w)
        .sum::<Vector3<f64>>()
        / total;
    let target_mean = pairs
        .iter()
        .map(|(_, d, w)| d.coords * *w)
        .sum::<Vector3<f64>>()
        / total;
    let covariance = pairs.iter().fold(Matrix3::zeros(), |c, (s, d, w)| {
        c + (s.coords - source_mean) * (d.coords - target_mean).transpose() * *w
    });
    let svd = covariance.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut singular = svd.singular_values;
    singular.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if singular[1] <= singular[0] * 1e-12 {
        return None;
    }
    let mut correction = Matrix3::identity();
    correction[(2, 2)] = (v_t.transpose() * u.transpose()).determinant().signum();
    let rotation = v_t.transpose() * correction * u.transpose();
    let rotation = UnitQuaternion::from_matrix(&rotation);
    let translation = target_mean - rotation * source_mean;
    Some(Isometry3::from_parts(
        Translation3::from(translation),
        rotation,
    ))
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn cloud() -> Vec<Point3<f64>> {
        (0..40)
            .map(|i| {
                let t = f64::from(i);
                Point3::new(
                    (0.7 * t).sin() * 0.1,
                    (1.3 * t).cos() * 0.08,
                    0.05 * (0.31 * t).sin() + 0.002 * t,
                )
            })
            .collect()
    }

    proptest! {
        /// Gauss–Newton on noise-free point-to-point residuals reaches Kabsch's closed form.
        #[test]
        fn gauss_newton_matches_kabsch(
            axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
            angle in 0.0f64..1.2,
            shift in (-0.5f64..0.5, -0.5f64..0.5, -0.5f64..0.5),
        ) {
            let axis = Vector3::new(axis.0, axis.1, axis.2);
            prop_assume!(axis.norm() > 0.1);
            let truth = Isometry3::new(Vector3::new(shift.0, shift.1, shift.2), axis.normalize() * angle);
            let source = cloud();
            let pairs: Vec<_> = source.iter().map(|s| (*s, truth * s, 1.0)).collect();
            let closed_form = kabsch(&pairs).unwrap();
            prop_assert!((closed_form.to_homogeneous() - truth.to_homogeneous()).amax() < 1e-9);

            let mut pose = Isometry3::identity();
            for _ in 0..20 {
                let mut equations = NormalEquations::new();
                for (s, d, _) in &pairs {
                    equations.add_point_to_point(&(pose * s).coords, &d.coords, 1.0);
                }
                pose = equations.solve().unwrap() * pose;
            }
            prop_assert!((pose.to_homogeneous() - closed_form.to_homogeneous()).amax() < 1e-9);
        }
    }

    /// Point-to-plane rows of `cloud()` against itself moved by `truth`, each point's normal
    /// along `normal(i)`.
    fn planar_rows(
        truth: &Isometry3<f64>,
        normal: impl Fn(usize) -> Vector3<f64>,
    ) -> NormalEquations {
        let mut equations = NormalEquations::new();
        for (i, s) in cloud().iter().enumerate() {
            equations.add_point_to_plane(&s.coords, &(truth * s).coords, &normal(i), 1.0);
        }
        equations
    }

    proptest! {
        /// Where every direction is constrained, turning about another centre and measuring
        /// the turn at another radius changes nothing: the update is the plain solve's.
        #[test]
        fn a_constrained_solve_of_a_well_posed_system_is_the_plain_one(
            centre in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
            radius in 0.01f64..1.0,
            turn in (-0.05f64..0.05, -0.05f64..0.05, -0.05f64..0.05),
            shift in (-0.02f64..0.02, -0.02f64..0.02, -0.02f64..0.02),
        ) {
            let truth = Isometry3::new(
                Vector3::new(shift.0, shift.1, shift.2),
                Vector3::new(turn.0, turn.1, turn.2),
            );
            let equations = planar_rows(&truth, |i| {
                let t = i as f64;
                Vector3::new((0.9 * t).sin(), (1.7 * t).cos(), 0.6).normalize()
            });
            let centre = Point3::new(centre.0, centre.1, centre.2);
            let plain = equations.solve().unwrap();
            let constrained = equations.solve_constrained(&centre, radius, 1e-9).unwrap();
            prop_assert!(
                (plain.to_homogeneous() - constrained.to_homogeneous()).amax() < 1e-9,
                "{plain:?} {constrained:?}"
            );
        }

        /// Against planes whose normals all lie across z, nothing fixes a shift along z: the
        /// plain solve fails, the constrained one leaves that shift out and finds the rest.
        #[test]
        fn a_constrained_solve_leaves_out_what_nothing_fixes(
            turn in (-0.05f64..0.05, -0.05f64..0.05, -0.05f64..0.05),
            shift in (-0.02f64..0.02, -0.02f64..0.02, -0.02f64..0.02),
        ) {
            let truth = Isometry3::new(
                Vector3::new(shift.0, shift.1, shift.2),
                Vector3::new(turn.0, turn.1, turn.2),
            );
            let across_z = |i: usize| {
                let a = 0.9 * i as f64;
                Vector3::new(a.cos(), a.sin(), 0.0)
            };
            let equations = planar_rows(&truth, across_z);
            prop_assert!(equations.solve().is_none());
            let (centre, radius) = (Point3::new(0.0, 0.0, 0.01), 0.1);
            // Iterated, it reaches the truth but for a shift along z.
            let mut pose = equations.solve_constrained(&centre, radius, 1e-6).unwrap();
            for _ in 0..10 {
                let rows = planar_rows(&(truth * pose.inverse()), across_z);
                pose = rows.solve_constrained(&(pose * centre), radius, 1e-6).unwrap() * pose;
            }
            let rest = truth * pose.inverse();
            prop_assert!(rest.rotation.angle() < 1e-9, "{rest:?}");
            prop_assert!(rest.translation.vector.xy().norm() < 1e-9, "{rest:?}");
        }
    }

    /// The closed-form accumulation equals the sum of the three Jacobian rows' outer products.
    #[test]
    fn point_to_point_accumulation_matches_row_form() {
        let (p, q, w) = (
            Vector3::new(0.3, -0.2, 0.5),
            Vector3::new(0.1, 0.4, -0.3),
            0.7,
        );
        let mut closed = NormalEquations::new();
        closed.add_point_to_point(&p, &q, w);
        let mut rows = NormalEquations::new();
        let r = p - q;
        rows.add_row(Vector6::new(0.0, p.z, -p.y, 1.0, 0.0, 0.0), r.x, w);
        rows.add_row(Vector6::new(-p.z, 0.0, p.x, 0.0, 1.0, 0.0), r.y, w);
        rows.add_row(Vector6::new(p.y, -p.x, 0.0, 0.0, 0.0, 1.0), r.z, w);
        assert!((closed.jtj - rows.jtj).amax() < 1e-12);
        assert!((closed.jtr - rows.jtr).amax() < 1e-12);
    }

    #[test]
    fn point_to_plane_recovers_a_small_motion_in_one_step_direction() {
        // Planar residuals against three orthogonal planes fix the translation exactly.
        let truth = Isometry3::translation(0.01, -0.02, 0.005);
        let mut equations = NormalEquations::new();
        for (i, s) in cloud().iter().enumerate() {
            let normal = [Vector3::x(), Vector3::y(), Vector3::z()][i % 3];
            equations.add_point_to_plane(&s.coords, &(truth * s).coords, &normal, 1.0);
        }
        let step = equations.solve().unwrap();
        assert!((step.translation.vector - truth.translation.vector).norm() < 1e-6);
        assert!(step.rotation.angle() < 1e-6);
    }

    #[test]
    fn degenerate_inputs_give_none() {
        assert!(NormalEquations::new().solve().is_none());
        let line: Vec<_> = (0..5)
            .map(|i| {
                (
                    Point3::new(f64::from(i), 0.0, 0.0),
                    Point3::new(f64::from(i), 0.0, 0.0),
                    1.0,
                )
            })
            .collect();
        assert!(kabsch(&line).is_none());
        assert!(kabsch(&line[..2]).is_none());
    }
}
