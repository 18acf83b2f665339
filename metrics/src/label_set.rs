//! How well one set of rotations stands for another: a label set against the reference set A
//! of the poses a view cannot tell apart. Completeness is the share of A within an angle of a
//! label (the ambiguity the labels cover), precision the share of labels within that angle of
//! A (the labels that are right).
use nalgebra::UnitQuaternion;

use crate::nearest_distances;

/// The share of `from` within `angle` radians of some rotation of `to`; `None` when `from` is
/// empty (nothing to share), 0 when `to` is.
pub fn share_within(
    from: &[UnitQuaternion<f64>],
    to: &[UnitQuaternion<f64>],
    angle: f64,
) -> Option<f64> {
    if from.is_empty() {
        return None;
    }
    let near = nearest_distances(from, to)
        .iter()
        .filter(|&&d| d <= angle)
        .count();
    Some(near as f64 / from.len() as f64)
}

/// Completeness of `labels` against the reference set `reference`: the share of the
/// reference within `angle` radians of a label (`None` for an empty reference).
pub fn completeness(
    labels: &[UnitQuaternion<f64>],
    reference: &[UnitQuaternion<f64>],
    angle: f64,
) -> Option<f64> {
    share_within(reference, labels, angle)
}

/// Precision of `labels` against the reference set `reference`: the share of labels within
/// `angle` radians of the reference (`None` without labels).
pub fn precision(
    labels: &[UnitQuaternion<f64>],
    reference: &[UnitQuaternion<f64>],
    angle: f64,
) -> Option<f64> {
    share_within(labels, reference, angle)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;
    use so3_grid::{geodesic_distance, random_rotations};

    /// The share by brute force: every pair's geodesic distance.
    fn brute_force(from: &[UnitQuaternion<f64>], to: &[UnitQuaternion<f64>], angle: f64) -> f64 {
        let near = from
            .iter()
            .filter(|f| to.iter().any(|t| geodesic_distance(f, t) <= angle))
            .count();
        near as f64 / from.len() as f64
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Against brute force; a set is complete and precise against itself; labels drawn
        /// from the reference are precise, and all of it is covered once every member is a
        /// label; a wider angle never covers less.
        #[test]
        fn shares_match_brute_force_and_order(
            seed in 0u64..1000,
            labels in 1usize..40,
            reference in 1usize..60,
            degrees in 1.0..60.0f64,
        ) {
            let angle = degrees.to_radians();
            let l = random_rotations(labels, seed);
            let a = random_rotations(reference, seed + 1);
            let c = completeness(&l, &a, angle).unwrap();
            let p = precision(&l, &a, angle).unwrap();
            prop_assert!((c - brute_force(&a, &l, angle)).abs() < 1e-12);
            prop_assert!((p - brute_force(&l, &a, angle)).abs() < 1e-12);
            prop_assert_eq!(completeness(&a, &a, 1e-9), Some(1.0));
            prop_assert_eq!(precision(&a[..reference / 2 + 1], &a, 1e-9), Some(1.0));
            prop_assert!(completeness(&l, &a, 2.0 * angle).unwrap() >= c);
            prop_assert!(precision(&l, &a, 2.0 * angle).unwrap() >= p);
        }
    }

    /// Four labels a quarter turn apart about an axis cover, within 5°, the whole-degree turns
    /// about it that lie within 5° of a multiple of 90°: 4 · 11 of 360.
    #[test]
    fn labels_on_a_circle_cover_their_arcs() {
        let turn = |degrees: f64| {
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), degrees.to_radians())
        };
        let labels: Vec<_> = (0..4).map(|k| turn(90.0 * f64::from(k))).collect();
        let circle: Vec<_> = (0..360).map(|d| turn(f64::from(d))).collect();
        let c = completeness(&labels, &circle, 5f64.to_radians() + 1e-9).unwrap();
        assert!((c - 44.0 / 360.0).abs() < 1e-12, "{c}");
        assert_eq!(precision(&labels, &circle, 1e-9), Some(1.0));
        assert_eq!(completeness(&labels, &[], 0.1), None);
        assert_eq!(precision(&[], &circle, 0.1), None);
        assert_eq!(precision(&labels, &[], 0.1), Some(0.0));
    }
}
