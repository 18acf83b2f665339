//! Hopf coordinates of SO(3) (Yershova et al. 2010, §2): a rotation is written as
//! `R = Rz(φ) · Ry(θ) · Rz(ψ)` where `(θ, φ)` (colatitude, longitude) is the direction `R·ẑ` of
//! the rotated z-axis on S² and `ψ ∈ [0, 2π)` the rotation about it. Haar measure factors as
//! `sin θ dθ dφ dψ / 8`, so equal-area cells on S² times equal arcs of ψ have equal volume.
//!
//! Quaternions here are `[w, x, y, z]` arrays of f64.

use std::f64::consts::{FRAC_PI_2, TAU};

/// `q_z(φ) ⊗ q_y(θ)`: the rotation taking ẑ to the direction with colatitude `θ`, longitude `φ`
/// (the base of the fibre; the fibre is `base ⊗ q_z(ψ)`).
pub(crate) fn fibre_base(colatitude: f64, longitude: f64) -> [f64; 4] {
    let (st, ct) = (0.5 * colatitude).sin_cos();
    let (sp, cp) = (0.5 * longitude).sin_cos();
    [cp * ct, -sp * st, cp * st, sp * ct]
}

/// `base ⊗ q_z(ψ)` where `cos_sin_half_psi = (cos ψ/2, sin ψ/2)`.
#[inline]
pub(crate) fn along_fibre(base: &[f64; 4], cos_sin_half_psi: [f64; 2]) -> [f64; 4] {
    let [p0, p1, p2, p3] = *base;
    let [c, s] = cos_sin_half_psi;
    [
        p0 * c - p3 * s,
        p1 * c + p2 * s,
        p2 * c - p1 * s,
        p3 * c + p0 * s,
    ]
}

/// The components `(w, z)` of `base⁻¹ ⊗ q`: for a rotation on the fibre of `base` these are
/// `(cos ψ/2, sin ψ/2)`; off the fibre, `|⟨q, base ⊗ q_z(ψ)⟩| = |w cos ψ/2 + z sin ψ/2|`.
#[inline]
pub(crate) fn fibre_components(base: &[f64; 4], q: &[f64; 4]) -> (f64, f64) {
    let [p0, p1, p2, p3] = *base;
    let [q0, q1, q2, q3] = *q;
    (
        p0 * q0 + p1 * q1 + p2 * q2 + p3 * q3,
        p0 * q3 - p1 * q2 + p2 * q1 - p3 * q0,
    )
}

/// The direction `R·ẑ` (third column of R) of a unit quaternion.
#[inline]
pub(crate) fn rotated_z_axis(q: &[f64; 4]) -> [f64; 3] {
    let [w, x, y, z] = *q;
    [
        2.0 * (x * z + w * y),
        2.0 * (y * z - w * x),
        1.0 - 2.0 * (x * x + y * y),
    ]
}

/// `(longitude ∈ [0, 2π), latitude ∈ [−π/2, π/2])` of a direction, as HEALPix takes them.
#[inline]
pub(crate) fn lon_lat(direction: &[f64; 3]) -> (f64, f64) {
    let [x, y, z] = *direction;
    let lon = y.atan2(x).rem_euclid(TAU);
    let lat = z.atan2(x.hypot(y)).clamp(-FRAC_PI_2, FRAC_PI_2);
    // rem_euclid can round a tiny negative angle up to exactly 2π.
    (if lon >= TAU { 0.0 } else { lon }, lat)
}

/// The unit direction of `(longitude, latitude)`.
#[inline]
pub(crate) fn direction(lon: f64, lat: f64) -> [f64; 3] {
    let (sl, cl) = lon.sin_cos();
    let (sb, cb) = lat.sin_cos();
    [cb * cl, cb * sl, sb]
}

/// The angle `ψ ∈ [0, 2π)` about the rotated z-axis: `atan2(R₂₁, −R₂₀)`. At the poles
/// (`R·ẑ = ±ẑ`), where ψ and φ are not separable, this gives 0.
#[inline]
pub(crate) fn psi(q: &[f64; 4]) -> f64 {
    let [w, x, y, z] = *q;
    let psi = (y * z + w * x).atan2(w * y - x * z).rem_euclid(TAU);
    if psi >= TAU { 0.0 } else { psi }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Quaternion, UnitQuaternion, Vector3};

    fn as_nalgebra(q: [f64; 4]) -> UnitQuaternion<f64> {
        UnitQuaternion::new_unchecked(Quaternion::new(q[0], q[1], q[2], q[3]))
    }

    #[test]
    fn coordinates_are_zyz_euler_angles() {
        let (theta, phi, psi_angle) = (1.1f64, 4.0f64, 2.5f64);
        let q = along_fibre(
            &fibre_base(theta, phi),
            [(0.5 * psi_angle).cos(), (0.5 * psi_angle).sin()],
        );
        let expected = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), phi)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), theta)
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), psi_angle);
        assert!(as_nalgebra(q).angle_to(&expected) < 1e-12);
        let axis = rotated_z_axis(&q);
        let (lon, lat) = lon_lat(&axis);
        assert!((lon - phi).abs() < 1e-12 && (lat - (FRAC_PI_2 - theta)).abs() < 1e-12);
        assert!((psi(&q) - psi_angle).abs() < 1e-12);
        let on_sphere = direction(lon, lat);
        assert!((0..3).all(|i| (on_sphere[i] - axis[i]).abs() < 1e-12));
    }

    #[test]
    fn the_pole_is_finite() {
        let q = [0.6f64.cos(), 0.0, 0.0, 0.6f64.sin()];
        let (lon, lat) = lon_lat(&rotated_z_axis(&q));
        assert!(lon.is_finite() && (lat - FRAC_PI_2).abs() < 1e-12);
        assert!(psi(&q).is_finite());
    }
}
