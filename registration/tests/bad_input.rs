//! Bad input gives a typed error, never a panic or a NaN pose.

use nalgebra::{Isometry3, Point3};
use registration::{
    IcpOptions, PointCloud, PrepareOptions, RegisterOptions, RegistrationError, prepare_cloud,
    refine_icp, register,
};

fn grid(count: usize, z: impl Fn(f32, f32) -> f32) -> Vec<Point3<f32>> {
    let side = (count as f32).sqrt().ceil() as usize;
    (0..count)
        .map(|i| {
            let (x, y) = ((i % side) as f32 * 0.002, (i / side) as f32 * 0.002);
            Point3::new(x, y, z(x, y))
        })
        .collect()
}

#[test]
fn empty_and_non_finite_clouds() {
    let empty = PointCloud::new(Vec::new()).unwrap();
    assert!(matches!(
        prepare_cloud(&empty, &PrepareOptions::default()),
        Err(RegistrationError::EmptyCloud { .. })
    ));
    let nan = PointCloud::new(vec![Point3::origin(), Point3::new(0.0, f32::INFINITY, 0.0)]);
    assert!(matches!(
        nan,
        Err(RegistrationError::NonFinite { index: 1, .. })
    ));
}

#[test]
fn collinear_coplanar_and_tiny_clouds() {
    let line = PointCloud::new(
        (0..200)
            .map(|i| Point3::new(i as f32 * 0.002, 0.0, 0.5))
            .collect(),
    )
    .unwrap();
    let plane = PointCloud::new(grid(2000, |_, _| 0.5)).unwrap();
    let two = PointCloud::new(vec![Point3::origin(), Point3::new(0.1, 0.0, 0.0)]).unwrap();
    let options = PrepareOptions::default();
    assert!(matches!(
        prepare_cloud(&line, &options),
        Err(RegistrationError::Degenerate {
            shape: "collinear",
            ..
        })
    ));
    assert!(matches!(
        prepare_cloud(&plane, &options),
        Err(RegistrationError::Degenerate {
            shape: "coplanar",
            ..
        })
    ));
    assert!(matches!(
        prepare_cloud(&two, &options),
        Err(RegistrationError::TooFewPoints { .. })
    ));
}

#[test]
fn bad_options() {
    let cloud = PointCloud::new(grid(2000, |x, y| 0.01 * (40.0 * x).sin() + y * y)).unwrap();
    for voxel_size in [0.0, -0.005, f32::NAN] {
        let options = PrepareOptions {
            voxel_size,
            ..PrepareOptions::default()
        };
        assert!(matches!(
            prepare_cloud(&cloud, &options),
            Err(RegistrationError::InvalidOption {
                name: "voxel_size",
                ..
            })
        ));
    }
    let prepared = prepare_cloud(&cloud, &PrepareOptions::default()).unwrap();
    let mut options = RegisterOptions::default();
    options.fgr.tuple_scale = 1.5;
    let err = register(&prepared, &prepared, &Isometry3::identity(), &options);
    assert!(matches!(
        err,
        Err(RegistrationError::InvalidOption {
            name: "tuple_scale",
            ..
        })
    ));
    options = RegisterOptions {
        hypotheses: 0,
        ..RegisterOptions::default()
    };
    assert!(matches!(
        register(&prepared, &prepared, &Isometry3::identity(), &options),
        Err(RegistrationError::InvalidOption { .. })
    ));
    let icp = IcpOptions {
        max_correspondence_distance: -1.0,
        ..IcpOptions::default()
    };
    let err = refine_icp(
        &prepared.cloud,
        &prepared.cloud,
        &prepared.index,
        &Isometry3::identity(),
        &icp,
    );
    assert!(matches!(err, Err(RegistrationError::InvalidOption { .. })));
}

#[test]
fn clouds_too_far_apart_have_no_icp_correspondences() {
    let cloud = PointCloud::new(grid(2000, |x, y| 0.01 * (40.0 * x).sin() + y * y)).unwrap();
    let prepared = prepare_cloud(&cloud, &PrepareOptions::default()).unwrap();
    let far = Isometry3::translation(10.0, 0.0, 0.0);
    let err = refine_icp(
        &prepared.cloud,
        &prepared.cloud,
        &prepared.index,
        &far,
        &IcpOptions::default(),
    );
    assert!(matches!(
        err,
        Err(RegistrationError::NoCorrespondences { stage: "ICP", .. })
    ));
}

#[test]
fn a_tiny_target_has_too_few_correspondences_and_no_nan_pose() {
    let source = PointCloud::new(grid(2000, |x, y| 0.01 * (40.0 * x).sin() + y * y)).unwrap();
    let target = PointCloud::new(vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.02, 0.0, 0.0),
        Point3::new(0.0, 0.03, 0.0),
        Point3::new(0.0, 0.0, 0.04),
    ])
    .unwrap();
    let options = PrepareOptions::default();
    assert!(matches!(
        prepare_cloud(&target, &options),
        Err(RegistrationError::TooFewPoints { .. })
    ));
    let options = PrepareOptions {
        voxel_size: 0.01,
        ..PrepareOptions::for_voxel(0.02)
    };
    let (source, target) = (
        prepare_cloud(&source, &options).unwrap(),
        prepare_cloud(&target, &options).unwrap(),
    );
    // Four target points cannot fix a pose: no pose at all, rather than one the points do
    // not determine (the identity, or a NaN from a singular solve).
    let found = register(
        &source,
        &target,
        &Isometry3::identity(),
        &RegisterOptions::default(),
    );
    assert!(
        matches!(found, Err(RegistrationError::NoCorrespondences { .. })),
        "{found:?}"
    );
}
