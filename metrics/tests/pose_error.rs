//! Invariants of the pose errors (ADD, ADD-S, translation error) and of their AUC.
use ipdf_metrics::{MetricsError, ModelPoints, SymmetryGroup, add, add_s, auc, translation_error};
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use proptest::prelude::*;

/// Points in a 200 mm cube about the model origin.
fn cloud(max_len: usize) -> impl Strategy<Value = Vec<Point3<f64>>> {
    prop::collection::vec(prop::array::uniform3(-100.0..100.0), 1..max_len)
        .prop_map(|points| points.into_iter().map(Point3::from).collect())
}

/// A pose in front of a camera: translation up to 1 m, any rotation (axis-angle up to π·√3).
fn pose() -> impl Strategy<Value = Isometry3<f64>> {
    (
        prop::array::uniform3(-300.0..300.0),
        500.0..1000.0,
        prop::array::uniform3(-3.0..3.0),
    )
        .prop_map(|([x, y, _], z, axis_angle)| {
            Isometry3::new(Vector3::new(x, y, z), Vector3::from(axis_angle))
        })
}

/// `a` and `b` agree to 1e-9 relative (of 1 mm below 1 mm).
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

fn brute_force_add_s(
    points: &[Point3<f64>],
    estimate: &Isometry3<f64>,
    truth: &Isometry3<f64>,
) -> f64 {
    let sum: f64 = points
        .iter()
        .map(|x| {
            points
                .iter()
                .map(|y| (estimate * x - truth * y).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .sum();
    sum / points.len() as f64
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// The nearest model point is never farther than the corresponding one.
    #[test]
    fn add_s_never_exceeds_add(points in cloud(200), estimate in pose(), truth in pose()) {
        let model = ModelPoints::new(&points).unwrap();
        let (add, add_s) = (add(&model, &estimate, &truth), add_s(&model, &estimate, &truth));
        prop_assert!(add_s <= add || close(add_s, add), "ADD-S {add_s} > ADD {add}");
    }

    /// The k-d tree search in the model frame gives the camera-frame definition.
    #[test]
    fn add_s_matches_its_definition(points in cloud(150), estimate in pose(), truth in pose()) {
        let model = ModelPoints::new(&points).unwrap();
        let expected = brute_force_add_s(&points, &estimate, &truth);
        let got = add_s(&model, &estimate, &truth);
        prop_assert!(close(got, expected), "{got} vs {expected}");
    }

    /// The diameter is the largest distance over all pairs.
    #[test]
    fn diameter_is_the_largest_pair_distance(points in cloud(300)) {
        let expected = points
            .iter()
            .flat_map(|p| points.iter().map(move |q| (p - q).norm()))
            .fold(0.0, f64::max);
        let got = ModelPoints::new(&points).unwrap().diameter();
        prop_assert!(close(got, expected), "{got} vs {expected}");
    }

    /// On an object symmetric under an n-fold rotation (the orbits of random points), ADD-S
    /// cannot tell `T_est` from `T_est · S` for any symmetry `S`; ADD can.
    #[test]
    fn add_s_is_invariant_under_symmetries(
        n in 2u32..8,
        axis in prop::array::uniform3(-1.0..1.0f64)
            .prop_filter("axis far from zero", |a| Vector3::from(*a).norm() > 0.1),
        seeds in cloud(20),
        estimate in pose(),
        truth in pose(),
    ) {
        let group = SymmetryGroup::cyclic(&Vector3::from(axis), n).unwrap();
        let symmetries = group.rotations(1);
        prop_assert_eq!(symmetries.len(), n as usize);
        let points: Vec<Point3<f64>> = seeds
            .iter()
            .flat_map(|p| symmetries.iter().map(move |s| s * p))
            .collect();
        let model = ModelPoints::new(&points).unwrap();
        let (add_0, add_s_0) = (add(&model, &estimate, &truth), add_s(&model, &estimate, &truth));
        let mut add_changed = false;
        for rotation in group.expand(&estimate.rotation) {
            let symmetric = Isometry3::from_parts(estimate.translation, rotation);
            let add_s_s = add_s(&model, &symmetric, &truth);
            prop_assert!(close(add_s_s, add_s_0), "ADD-S {add_s_s} vs {add_s_0}");
            add_changed |= (add(&model, &symmetric, &truth) - add_0).abs() > 1e-6;
        }
        prop_assert!(add_changed, "ADD {add_0} is the same for every symmetry");
    }

    /// Identical poses score 0; a pure translation offset `d` scores ADD = |d|.
    #[test]
    fn identical_and_shifted_poses(
        points in cloud(200),
        truth in pose(),
        offset in prop::array::uniform3(-50.0..50.0f64),
    ) {
        let model = ModelPoints::new(&points).unwrap();
        prop_assert_eq!(add(&model, &truth, &truth), 0.0);
        prop_assert!(add_s(&model, &truth, &truth) < 1e-9);
        let offset = Vector3::from(offset);
        let shifted = Translation3::from(offset) * truth;
        prop_assert!(close(add(&model, &shifted, &truth), offset.norm()));
        prop_assert!(close(
            translation_error(&shifted.translation.vector, &truth.translation.vector),
            offset.norm()
        ));
    }
}

proptest! {
    /// The translation error is a metric: symmetric, and satisfies the triangle inequality.
    #[test]
    fn translation_error_is_a_metric(
        a in prop::array::uniform3(-1e3..1e3f64),
        b in prop::array::uniform3(-1e3..1e3f64),
        c in prop::array::uniform3(-1e3..1e3f64),
    ) {
        let (a, b, c) = (Vector3::from(a), Vector3::from(b), Vector3::from(c));
        prop_assert_eq!(translation_error(&a, &b), translation_error(&b, &a));
        prop_assert_eq!(translation_error(&a, &a), 0.0);
        let direct = translation_error(&a, &c);
        let detour = translation_error(&a, &b) + translation_error(&b, &c);
        prop_assert!(direct <= detour || close(direct, detour));
    }

    /// AUC lies in [0, 1], is 1 for perfect poses and 0 when every error reaches the threshold.
    #[test]
    fn auc_bounds(
        errors in prop::collection::vec(0.0..200.0f64, 1..50),
        max_threshold in 0.1..100.0f64,
    ) {
        let value = auc(&errors, max_threshold).unwrap();
        prop_assert!((0.0..=1.0).contains(&value));
        prop_assert_eq!(auc(&vec![0.0; errors.len()], max_threshold).unwrap(), 1.0);
        let failed: Vec<f64> = errors.iter().map(|e| max_threshold + e).collect();
        prop_assert_eq!(auc(&failed, max_threshold).unwrap(), 0.0);
    }

    /// Increasing any one error never increases the AUC.
    #[test]
    fn auc_does_not_increase_with_an_error(
        errors in prop::collection::vec(0.0..200.0f64, 1..50),
        position in any::<prop::sample::Index>(),
        increase in 0.0..100.0f64,
        max_threshold in 0.1..100.0f64,
    ) {
        let before = auc(&errors, max_threshold).unwrap();
        let mut worse = errors.clone();
        worse[position.index(errors.len())] += increase;
        prop_assert!(auc(&worse, max_threshold).unwrap() <= before);
    }

    /// Bad model points and bad errors are refused, naming the first offending position.
    #[test]
    fn bad_input_gives_typed_errors(
        points in cloud(50),
        position in any::<prop::sample::Index>(),
        coordinate in 0usize..3,
        bad in prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY]),
        negative in -1e3..-1e-12f64,
    ) {
        let position = position.index(points.len());
        let mut broken = points.clone();
        broken[position][coordinate] = bad;
        let refused = matches!(
            ModelPoints::new(&broken),
            Err(MetricsError::InvalidModelPoint { position: p, .. }) if p == position
        );
        prop_assert!(refused);

        let mut errors = vec![1.0; points.len()];
        errors[position] = if coordinate == 0 { negative } else { bad };
        let refused = matches!(
            auc(&errors, 10.0),
            Err(MetricsError::InvalidPoseError { position: p, .. }) if p == position
        );
        prop_assert!(refused);
        let refused = matches!(
            auc(&[1.0], if coordinate == 0 { negative } else { bad }),
            Err(MetricsError::InvalidThreshold { .. })
        );
        prop_assert!(refused);
    }
}

#[test]
fn empty_inputs_are_refused() {
    assert!(matches!(
        ModelPoints::new(&[]),
        Err(MetricsError::NoModelPoints)
    ));
    assert!(matches!(auc(&[], 1.0), Err(MetricsError::NoPoseErrors)));
    assert!(matches!(
        auc(&[1.0], 0.0),
        Err(MetricsError::InvalidThreshold { .. })
    ));
}
