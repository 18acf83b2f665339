//! Checked conversions between plain arrays and nalgebra rotations, and the geodesic distance.
use nalgebra::{Matrix3, Quaternion, Rotation3, Unit, UnitQuaternion, Vector3};

use crate::GridError;

/// Largest |RᵀR − I| entry [`rotation_from_matrix`] converts directly: rotations stored as 6–8
/// significant digits. Beyond it, up to [`PUBLISHED_ROTATION_TOLERANCE`], a matrix is taken as
/// its nearest rotation.
pub const ORTHONORMALITY_TOLERANCE: f64 = 1e-4;

/// Largest |RᵀR − I| entry accepted by [`rotation_from_matrix`]: real BOP ground truth is
/// orthonormal only to about 10⁻² as published (YCB-Video's worst `cam_R_m2c`: 9.4·10⁻³), while
/// a scaled, sheared or garbled matrix is off by far more (a 30% scale: 0.69).
pub const PUBLISHED_ROTATION_TOLERANCE: f64 = 5e-2;

/// Geodesic distance on SO(3) in radians, in `[0, π]`: the angle of the rotation `a⁻¹·b`.
///
/// The quaternions (taken in one hemisphere) are unit vectors an angle β apart in R⁴ and the
/// rotation angle is 2β; `β/2 = atan2(|a − b|, |a + b|)` is accurate for tiny and for near-π
/// angles alike (unlike `2·acos(|⟨a, b⟩|)`).
pub fn geodesic_distance(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    let (a, mut b) = (a.as_ref().coords, b.as_ref().coords);
    if a.dot(&b) < 0.0 {
        b = -b;
    }
    4.0 * (a - b).norm().atan2((a + b).norm())
}

/// The rotation of a row-major 3×3 matrix (BOP's `cam_R_m2c` layout).
///
/// Rejects non-finite entries, reflections and matrices that are not orthonormal within
/// [`PUBLISHED_ROTATION_TOLERANCE`]. A matrix orthonormal within [`ORTHONORMALITY_TOLERANCE`]
/// is converted directly; one less orthonormal, as real datasets publish them, is replaced by
/// its nearest rotation in the Frobenius norm (`U Vᵀ` of its SVD). [`orthogonality_error`]
/// tells a caller which of the two happened, to count the repairs.
pub fn rotation_from_matrix(row_major: &[f64; 9]) -> Result<UnitQuaternion<f64>, GridError> {
    if row_major.iter().any(|v| !v.is_finite()) {
        return Err(GridError::NonFinite {
            what: "rotation matrix",
        });
    }
    let m = Matrix3::from_row_slice(row_major);
    let orthogonality_error = orthogonality_error(row_major);
    let determinant = m.determinant();
    if orthogonality_error > PUBLISHED_ROTATION_TOLERANCE || determinant <= 0.0 {
        return Err(GridError::NotARotation {
            orthogonality_error,
            determinant,
        });
    }
    let rotation = if orthogonality_error <= ORTHONORMALITY_TOLERANCE {
        m
    } else {
        nearest_rotation(&m)
    };
    let quaternion =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
    // A matrix stored with 6–8 digits gives a quaternion of norm 1 ± 1e-5: normalised, as its
    // type promises. Matrices as exact as f64 keep their bits.
    Ok(if (quaternion.norm() - 1.0).abs() > UNIT_NORM_TOLERANCE {
        UnitQuaternion::new_normalize(quaternion.into_inner())
    } else {
        quaternion
    })
}

/// How far from 1 the norm of [`rotation_from_matrix`]'s quaternion may be before it is
/// normalised.
const UNIT_NORM_TOLERANCE: f64 = 1e-12;

/// The largest absolute entry of `RᵀR − I` for a row-major 3×3 matrix `R`.
pub fn orthogonality_error(row_major: &[f64; 9]) -> f64 {
    let m = Matrix3::from_row_slice(row_major);
    (m.transpose() * m - Matrix3::identity()).amax()
}

/// The rotation nearest to `m` in the Frobenius norm: `U Vᵀ` for `m = U Σ Vᵀ` (`m` with a
/// positive determinant, so no reflection needs undoing).
fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => u * v_t,
        // nalgebra computes both factors when asked; keep the matrix if it ever does not.
        _ => *m,
    }
}

/// The row-major 3×3 matrix of a rotation (the inverse of [`rotation_from_matrix`]).
pub fn rotation_to_matrix(rotation: &UnitQuaternion<f64>) -> [f64; 9] {
    let m = rotation.to_rotation_matrix().into_inner();
    std::array::from_fn(|i| m[(i / 3, i % 3)])
}

/// The rotation by `angle` radians about `axis` (any non-zero length; right-hand rule).
pub fn rotation_from_axis_angle(
    axis: &Vector3<f64>,
    angle: f64,
) -> Result<UnitQuaternion<f64>, GridError> {
    if !angle.is_finite() || axis.iter().any(|v| !v.is_finite()) {
        return Err(GridError::NonFinite { what: "axis-angle" });
    }
    let axis = Unit::try_new(*axis, f64::EPSILON).ok_or(GridError::ZeroAxis)?;
    Ok(UnitQuaternion::from_axis_angle(&axis, angle))
}

/// The rotation of quaternion components `[w, x, y, z]` (normalised; any non-zero length).
pub fn rotation_from_wxyz(wxyz: &[f64; 4]) -> Result<UnitQuaternion<f64>, GridError> {
    if wxyz.iter().any(|v| !v.is_finite()) {
        return Err(GridError::NonFinite { what: "quaternion" });
    }
    let q = Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    if q.norm() < f64::EPSILON {
        return Err(GridError::ZeroAxis);
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// `[w, x, y, z]` of a rotation, in the hemisphere `w ≥ 0` (each rotation has one such form,
/// up to the measure-zero set `w = 0`).
pub fn rotation_to_wxyz(rotation: &UnitQuaternion<f64>) -> [f64; 4] {
    let q = rotation.as_ref();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn any_rotation() -> impl Strategy<Value = UnitQuaternion<f64>> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
            .prop_filter("non-zero", |(w, x, y, z)| {
                w * w + x * x + y * y + z * z > 1e-3
            })
            .prop_map(|(w, x, y, z)| UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)))
    }

    proptest! {
        #[test]
        fn matrix_round_trip(q in any_rotation()) {
            let back = rotation_from_matrix(&rotation_to_matrix(&q)).unwrap();
            prop_assert!(geodesic_distance(&q, &back) < 1e-9);
        }

        #[test]
        fn distance_is_the_angle_of_the_relative_rotation(a in any_rotation(), b in any_rotation()) {
            let d = geodesic_distance(&a, &b);
            prop_assert!((d - a.angle_to(&b)).abs() < 1e-7);
            prop_assert!((0.0..=PI + 1e-12).contains(&d));
            prop_assert!((d - geodesic_distance(&b, &a)).abs() < 1e-12);
            let negated = UnitQuaternion::new_unchecked(-b.into_inner());
            prop_assert!((d - geodesic_distance(&a, &negated)).abs() < 1e-12);
        }

        #[test]
        fn axis_angle_has_that_angle(x in -1.0..1.0f64, y in -1.0..1.0f64, z in 0.1..1.0f64, angle in 0.0..PI) {
            let q = rotation_from_axis_angle(&Vector3::new(x, y, z), angle).unwrap();
            prop_assert!((geodesic_distance(&UnitQuaternion::identity(), &q) - angle).abs() < 1e-9);
        }
    }

    #[test]
    fn tiny_angles_are_resolved() {
        let q = rotation_from_axis_angle(&Vector3::z(), 1e-9).unwrap();
        let d = geodesic_distance(&UnitQuaternion::identity(), &q);
        assert!((d - 1e-9).abs() < 1e-15, "{d}");
    }

    proptest! {
        /// A rotation stored with 6 significant digits (BOP files, |RᵀR − I| up to ~1e-5 and
        /// converted directly) still gives a unit quaternion, as training's checks ask (1e-6).
        #[test]
        fn rotations_stored_with_few_digits_give_unit_quaternions(q in any_rotation()) {
            let stored = rotation_to_matrix(&q).map(|v| format!("{v:.6}").parse::<f64>().unwrap());
            let back = rotation_from_matrix(&stored).unwrap();
            prop_assert!((back.norm() - 1.0).abs() <= 1e-12, "{}", back.norm());
            prop_assert!(geodesic_distance(&q, &back) < 1e-5);
        }
    }

    proptest! {
        /// A rotation published to a few digits comes back as the nearest rotation: within the
        /// perturbation's size of the true one, and equal to the polar factor `M (MᵀM)^(-1/2)`
        /// computed by an eigendecomposition (an independent route to the same matrix).
        #[test]
        fn perturbed_rotations_become_their_nearest_rotation(
            angles in prop::array::uniform3(-3.0f64..3.0),
            noise in prop::array::uniform9(-0.004f64..0.004),
        ) {
            let truth = UnitQuaternion::from_euler_angles(angles[0], angles[1], angles[2]);
            let mut published = rotation_to_matrix(&truth);
            for (entry, delta) in published.iter_mut().zip(noise) {
                *entry += delta;
            }
            let found = rotation_from_matrix(&published).unwrap();
            prop_assert!(geodesic_distance(&truth, &found) < 0.02);
            let m = Matrix3::from_row_slice(&published);
            let eigen = (m.transpose() * m).symmetric_eigen();
            let inverse_root = eigen.eigenvectors
                * Matrix3::from_diagonal(&eigen.eigenvalues.map(|l| 1.0 / l.sqrt()))
                * eigen.eigenvectors.transpose();
            let polar = m * inverse_root;
            let expected = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(polar));
            if orthogonality_error(&published) > ORTHONORMALITY_TOLERANCE {
                prop_assert!(geodesic_distance(&expected, &found) < 1e-9);
            }
        }
    }

    #[test]
    fn published_ground_truth_is_read_and_garbled_matrices_are_not() {
        // Orthonormal to about 1e-2, as YCB-Video publishes its worst poses: accepted, as the
        // rotation itself (the nearest rotation to a scaled rotation is that rotation).
        let q = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let published = rotation_to_matrix(&q).map(|v| 1.005 * v);
        assert!((orthogonality_error(&published) - (1.005f64.powi(2) - 1.0)).abs() < 1e-12);
        let found = rotation_from_matrix(&published).unwrap();
        assert!(geodesic_distance(&q, &found) < 1e-12);
        // A rotation scaled by 1.3 (off by 0.69): refused.
        let scaled = rotation_to_matrix(&q).map(|v| 1.3 * v);
        assert!(matches!(
            rotation_from_matrix(&scaled),
            Err(GridError::NotARotation { .. })
        ));
        // One entry off by 0.3: refused.
        let mut garbled = rotation_to_matrix(&q);
        garbled[2] += 0.3;
        assert!(matches!(
            rotation_from_matrix(&garbled),
            Err(GridError::NotARotation { .. })
        ));
    }

    #[test]
    fn bad_matrices_are_rejected() {
        let scaled = [2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert!(matches!(
            rotation_from_matrix(&scaled),
            Err(GridError::NotARotation { .. })
        ));
        let reflection = [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert!(matches!(
            rotation_from_matrix(&reflection),
            Err(GridError::NotARotation { determinant, .. }) if determinant < 0.0
        ));
        let nan = [f64::NAN, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert!(matches!(
            rotation_from_matrix(&nan),
            Err(GridError::NonFinite { .. })
        ));
        assert_eq!(
            rotation_from_axis_angle(&Vector3::zeros(), 1.0),
            Err(GridError::ZeroAxis)
        );
        assert_eq!(rotation_from_wxyz(&[0.0; 4]), Err(GridError::ZeroAxis));
    }

    #[test]
    fn wxyz_is_in_the_upper_hemisphere() {
        let q = UnitQuaternion::from_quaternion(Quaternion::new(-0.5, 0.5, 0.5, 0.5));
        assert_eq!(rotation_to_wxyz(&q), [0.5, -0.5, -0.5, -0.5]);
    }
}
