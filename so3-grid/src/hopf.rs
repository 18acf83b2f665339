//! Hopf coordinates of SO(3) (Yershova et al. 2010, §2): a rotation is `R = σ(s) · Rz(ψ)`
//! where `s = R·ẑ` is the direction of the rotated z-axis on S², `σ(s)` is a fixed rotation
//! taking ẑ to `s` (a *section* of the fibration) and `ψ ∈ [0, 2π)` the rotation about the
//! z-axis after it. Haar measure factors into area on S² times arc length of ψ for any
//! section, so equal-area cells on S² times equal arcs of ψ have equal volume.
//!
//! No section is continuous on the whole sphere, and a cell is compact only where its section
//! is continuous (with Euler angles, `σ = Rz(φ)Ry(θ)`, cells at the poles stretch over 90° of
//! rotation). So two sections are used: the shortest arc from ẑ ("north", singular only at
//! −ẑ) for the northern and equatorial HEALPix base pixels, and the shortest arc from −ẑ
//! after a half turn about x ("south", singular only at +ẑ) for the southern ones.
//!
//! Quaternions here are `[w, x, y, z]` arrays of f64.

use std::f64::consts::{FRAC_PI_2, TAU};

/// The section used for a pixel: by its HEALPix base pixel (0–7 north, 8–11 south).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Section {
    /// Shortest arc ẑ → s: `(1 + z, −y, x, 0) / √(2(1 + z))`.
    North,
    /// Shortest arc −ẑ → s after `Rx(π)`: `(−y, 1 − z, 0, x) / √(2(1 − z))`.
    South,
}

impl Section {
    /// The section of a HEALPix pixel at `depth`.
    pub(crate) fn of_pixel(depth: u8, pixel: u64) -> Self {
        if pixel >> (2 * u32::from(depth)) >= 8 {
            Section::South
        } else {
            Section::North
        }
    }

    /// `σ(s)`: a rotation taking ẑ to the unit direction `s`.
    pub(crate) fn base(self, s: &[f64; 3]) -> [f64; 4] {
        let [x, y, z] = *s;
        let q = match self {
            Section::North => [1.0 + z, -y, x, 0.0],
            Section::South => [-y, 1.0 - z, 0.0, x],
        };
        let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        if norm < 1e-300 {
            // The section's singular pole (never reached by the pixels using it): a rotation
            // that still takes ẑ there, the half turn about x for North's −ẑ, the identity
            // for South's +ẑ.
            return match self {
                Section::North => [0.0, 1.0, 0.0, 0.0],
                Section::South => [1.0, 0.0, 0.0, 0.0],
            };
        }
        q.map(|c| c / norm)
    }
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

/// The fibre angle `ψ ∈ [0, 2π)` of `q` relative to `base` (exact when `q` is on its fibre).
#[inline]
pub(crate) fn psi(base: &[f64; 4], q: &[f64; 4]) -> f64 {
    let (w, z) = fibre_components(base, q);
    let psi = (2.0 * z.atan2(w)).rem_euclid(TAU);
    // rem_euclid can round a tiny negative angle up to exactly 2π.
    if psi >= TAU { 0.0 } else { psi }
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
    (if lon >= TAU { 0.0 } else { lon }, lat)
}

/// The unit direction of `(longitude, latitude)`.
#[inline]
pub(crate) fn direction(lon: f64, lat: f64) -> [f64; 3] {
    let (sl, cl) = lon.sin_cos();
    let (sb, cb) = lat.sin_cos();
    [cb * cl, cb * sl, sb]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn sections_take_z_to_the_direction_and_psi_round_trips(
            lon in 0.0..TAU, lat in -1.5..1.5f64, psi_angle in 0.0..TAU, south in any::<bool>()
        ) {
            let s = direction(lon, lat);
            let section = if south { Section::South } else { Section::North };
            let base = section.base(&s);
            let q = along_fibre(&base, [(0.5 * psi_angle).cos(), (0.5 * psi_angle).sin()]);
            let axis = rotated_z_axis(&q);
            prop_assert!((0..3).all(|i| (axis[i] - s[i]).abs() < 1e-12));
            let back = psi(&base, &q);
            let gap = (back - psi_angle).abs();
            prop_assert!(gap.min(TAU - gap) < 1e-9);
            let (lon2, lat2) = lon_lat(&axis);
            prop_assert!((lat2 - lat).abs() < 1e-9);
            let lon_gap = (lon2 - lon).abs();
            prop_assert!(lon_gap.min(TAU - lon_gap) < 1e-9);
        }
    }

    #[test]
    fn sections_take_z_to_both_poles_even_the_singular_one() {
        for section in [Section::North, Section::South] {
            for s in [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]] {
                let base = section.base(&s);
                let norm = base.iter().map(|c| c * c).sum::<f64>().sqrt();
                assert!((norm - 1.0).abs() < 1e-12, "{section:?} at {s:?}: {base:?}");
                let axis = rotated_z_axis(&base);
                assert!(
                    (0..3).all(|i| (axis[i] - s[i]).abs() < 1e-12),
                    "{section:?} at {s:?} takes z to {axis:?}"
                );
            }
        }
        assert_eq!(Section::of_pixel(2, 8 << 4), Section::South);
        assert_eq!(Section::of_pixel(2, (8 << 4) - 1), Section::North);
    }
}
