//! FGR + ICP recovers random rigid transforms of a non-symmetric object's partial view.

use crate::common;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use registration::{
    FeatureCorrespondences, FgrOptions, Fpfh, IcpOptions, NormalOrientation, PointCloud,
    PrepareOptions, PreparedCloud, RegisterOptions, align_fgr, prepare_cloud, refine_icp, register,
};

const VOXEL: f32 = 0.005;

fn prepared_model() -> (common::Samples, PreparedCloud) {
    let model = common::model(40_000);
    let cloud = PointCloud::new(model.0.clone())
        .unwrap()
        .with_normals(model.1.clone())
        .unwrap();
    // Normals estimated from the samples, as a scanned model gets them, not the surface's
    // exact ones.
    let options = PrepareOptions {
        keep_normals: false,
        ..PrepareOptions::for_voxel(VOXEL)
            .oriented(NormalOrientation::Consistent { neighbours: 10 })
    };
    let prepared = prepare_cloud(&cloud, &options).unwrap();
    (model, prepared)
}

fn prepared_view(model: &common::Samples, truth: &Isometry3<f64>, seed: u64) -> PreparedCloud {
    let view = common::view(model, truth, 0.001, seed);
    let options = PrepareOptions::for_voxel(VOXEL)
        .oriented(NormalOrientation::TowardsViewpoint(Point3::origin()));
    prepare_cloud(&view, &options).unwrap()
}

/// Uniform random rotations (Shoemake) and translations up to 0.5 m, in front of the camera.
fn poses() -> impl Strategy<Value = Isometry3<f64>> {
    (
        0.0f64..1.0,
        0.0f64..std::f64::consts::TAU,
        0.0f64..std::f64::consts::TAU,
        -0.25f64..0.25,
        -0.25f64..0.25,
        0.25f64..0.35,
    )
        .prop_map(|(u, a, b, x, y, z)| {
            let (s, t) = ((1.0 - u).sqrt(), u.sqrt());
            common::pose(
                [t * b.cos(), s * a.sin(), s * a.cos(), t * b.sin()],
                [x, y, z],
            )
        })
}

#[test]
fn fgr_and_icp_recover_95_percent_of_random_transforms() {
    let (model, source) = prepared_model();
    let mut runner = TestRunner::deterministic();
    let strategy = poses();
    let trials = 40;
    let mut failures = Vec::new();
    for trial in 0..trials {
        let truth = strategy.new_tree(&mut runner).unwrap().current();
        let target = prepared_view(&model, &truth, trial);
        let options = RegisterOptions {
            fgr: registration::FgrOptions {
                seed: trial,
                ..RegisterOptions::default().fgr
            },
            ..RegisterOptions::default()
        };
        let found = register(&source, &target, &Isometry3::identity(), &options).unwrap();
        let (rotation, translation) = common::errors(&found.alignment.pose, &truth);
        if rotation > 2.0 || translation > 0.005 {
            let at_truth = refine_icp(
                &source.cloud,
                &target.cloud,
                &target.index,
                &truth,
                &IcpOptions::default(),
            )
            .unwrap();
            failures.push(format!("trial {trial}: {rotation:.2}° {:.2} mm fit {:.3} rmse {:.2}mm vs truth fit {:.3} rmse {:.2}mm", translation * 1e3, found.alignment.fitness, found.alignment.inlier_rmse * 1e3, at_truth.fitness, at_truth.inlier_rmse * 1e3));
        }
    }
    let successes = trials as usize - failures.len();
    eprintln!("{successes}/{trials} recovered; failures: {failures:?}");
    assert!(
        successes * 100 >= 95 * trials as usize,
        "{successes}/{trials} recovered; failures: {failures:?}"
    );
}

/// FGR alone (its own solution, no consensus starts, no ICP), with the paper's mutual
/// filter and with target-to-source candidates: most views land within 10° and 1 cm.
#[test]
fn fgr_alone_lands_near_most_views() {
    let (model, source) = prepared_model();
    let mut runner = TestRunner::deterministic();
    let strategy = poses();
    let mut near = [0; 2];
    let trials = 10;
    for trial in 0..trials {
        let truth = strategy.new_tree(&mut runner).unwrap().current();
        let target = prepared_view(&model, &truth, trial);
        for (k, correspondences) in [
            FeatureCorrespondences::Mutual,
            FeatureCorrespondences::TargetToSource,
        ]
        .into_iter()
        .enumerate()
        {
            let options = FgrOptions {
                correspondences,
                seed: trial,
                ..RegisterOptions::default().fgr
            };
            let Ok(found) = align_fgr(&source, &target, &Isometry3::identity(), &options) else {
                continue;
            };
            // The candidates are what the filter names: every target point's nearest source
            // feature, or only the pairs that are each other's nearest (counted here by brute
            // force, on the first view), 157–329 of a view's 2,300–3,100 points.
            let expected = match correspondences {
                FeatureCorrespondences::TargetToSource => Some(target.features.len()),
                FeatureCorrespondences::Mutual if trial == 0 => {
                    Some(mutual_pairs(&source.features, &target.features))
                }
                _ => None,
            };
            if let Some(expected) = expected {
                assert!(
                    found.candidates.abs_diff(expected) <= 2 + expected / 50,
                    "{correspondences:?}: {} candidates, brute force {expected}",
                    found.candidates
                );
            }
            let (rotation, translation) = common::errors(&found.pose, &truth);
            near[k] += usize::from(rotation < 10.0 && translation < 0.01);
        }
    }
    eprintln!(
        "FGR alone within 10° and 1 cm: mutual {}/{trials}, target-to-source {}/{trials}",
        near[0], near[1]
    );
    // The floors: nothing in these views is ambiguous (the egg has no symmetry; each view
    // keeps 2,300–3,100 of its points), so FGR may miss a view only where its candidates are
    // mostly outliers. Checked once, outside the test (exhaustive feature matching is too slow
    // to run every time), against the true pose (an inlier: within 1 cm of its partner):
    // - target-to-source, one candidate per view point, 4.5–23% inliers: FGR must land near
    //   every view but those at or near the twenty-to-one ratio where graduated
    //   non-convexity can settle in a wrong mode (see `align_modes`), that is under one inlier
    //   in 18 (5.6%): three of the ten views (4.5%, 5.4%, 5.5%). Hence 7.
    // - mutual, only 157–329 pairs per view (7–46% inliers): FGR must land near the views
    //   where at least one pair in five is an inlier (three: 23%, 32%, 46%); below that a
    //   random triple of the tuple test is all inliers less than once in 125 draws. Hence 3.
    assert!(near[1] >= 7, "target-to-source: {}/{trials} near", near[1]);
    assert!(near[0] >= 3, "mutual: {}/{trials} near", near[0]);
}

/// How many (source, target) feature pairs are each other's nearest neighbour (squared
/// Euclidean distance, summed term by term; ties to the lower index), by brute force. The
/// library's distances come from a matrix product, whose rounding can flip a near tie.
fn mutual_pairs(source: &[Fpfh], target: &[Fpfh]) -> usize {
    let distance =
        |a: &Fpfh, b: &Fpfh| -> f32 { a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum() };
    let nearest = |from: &Fpfh, to: &[Fpfh]| {
        (0..to.len())
            .min_by(|&i, &j| distance(from, &to[i]).total_cmp(&distance(from, &to[j])))
            .unwrap()
    };
    let to_source: Vec<usize> = target.iter().map(|t| nearest(t, source)).collect();
    source
        .iter()
        .enumerate()
        .filter(|&(s, f)| to_source[nearest(f, target)] == s)
        .count()
}

#[test]
fn registration_is_deterministic_across_thread_counts() {
    let (model, source) = prepared_model();
    let truth = common::pose([0.2, -0.7, 0.4, 0.5], [0.1, -0.05, 0.3]);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let target = prepared_view(&model, &truth, 9);
            register(
                &source,
                &target,
                &Isometry3::identity(),
                &RegisterOptions::default(),
            )
            .unwrap()
            .alignment
        })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.pose, two.pose);
    assert_eq!(one.fitness, two.fitness);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// ICP alone (no global step) converges from any perturbation under 15° (and 1 cm).
    #[test]
    fn icp_converges_from_perturbations_under_15_degrees(
        truth in poses(),
        axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
        angle in 0.0f64..15.0,
        shift in (-0.006f64..0.006, -0.006f64..0.006, -0.006f64..0.006),
    ) {
        let axis = Vector3::new(axis.0, axis.1, axis.2);
        prop_assume!(axis.norm() > 0.1);
        let (model, source) = prepared_model();
        let target = prepared_view(&model, &truth, 3);
        let perturbation = Isometry3::from_parts(
            Vector3::new(shift.0, shift.1, shift.2).into(),
            UnitQuaternion::from_scaled_axis(axis.normalize() * angle.to_radians()),
        );
        let centre = source.cloud.centroid().unwrap().coords;
        // Perturb about the object's centre, in the camera frame.
        let start = Isometry3::translation(centre.x, centre.y, centre.z);
        let initial = truth * start * perturbation * start.inverse();
        let options = IcpOptions { max_correspondence_distance: 0.02, max_iterations: 60, ..IcpOptions::default() };
        let coarse = refine_icp(&source.cloud, &target.cloud, &target.index, &initial, &options).unwrap();
        let fine = refine_icp(&source.cloud, &target.cloud, &target.index, &coarse.pose, &IcpOptions::default()).unwrap();
        let (rotation, translation) = common::errors(&fine.pose, &truth);
        prop_assert!(rotation < 2.0 && translation < 0.005, "{rotation:.2}° {:.2} mm from {angle:.1}°", translation * 1e3);
    }
}
