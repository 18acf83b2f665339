//! Unprojection, the render-and-compare score, the visible surface discrepancy and surface
//! sampling.
use depth_render::{
    DepthSensor, Instance, PinholeCamera, Scene, SensorPreset, Window, depth_discrepancy,
    primitives, sample_surface, unproject, visible_surface_discrepancy,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

fn camera() -> PinholeCamera {
    PinholeCamera::new(600.0, 600.0, 80.0, 60.0, 160, 120).unwrap()
}

#[test]
fn unprojected_renders_lie_on_the_surface() {
    let camera = camera();
    let scene = Scene::new(&[primitives::cuboid([0.08, 0.05, 0.03]).unwrap()]);
    let pose = Isometry3::from_parts(
        Translation3::new(0.01, -0.01, 0.6),
        UnitQuaternion::from_euler_angles(0.4, -0.7, 0.2),
    );
    let window = Window {
        u0: 10,
        v0: 5,
        u1: 150,
        v1: 115,
    };
    let out = scene
        .render(&camera, &[Instance::new(0, pose)], window)
        .unwrap();
    let points = unproject(&camera, window, &out.depth, None);
    assert!(points.len() > 1000);
    let half = [0.04f64, 0.025, 0.015];
    for p in &points {
        // In the box frame a surface point has one coordinate at ±half and the others inside.
        let local = pose.inverse() * p.cast::<f64>();
        let gaps: Vec<f64> = (0..3).map(|i| (local[i].abs() - half[i]).abs()).collect();
        assert!(
            gaps.iter().cloned().fold(f64::INFINITY, f64::min) < 1e-5,
            "{local:?}"
        );
        assert!((0..3).all(|i| local[i].abs() <= half[i] + 1e-5));
    }
    // A mask keeps only the masked pixels.
    let mask: Vec<bool> = (0..out.depth.len()).map(|i| i % 2 == 0).collect();
    let masked = unproject(&camera, window, &out.depth, Some(&mask));
    let expected = out.depth.iter().step_by(2).filter(|&&d| d > 0.0).count();
    assert_eq!(masked.len(), expected);
}

#[test]
fn the_true_pose_scores_best_and_noise_costs_about_its_mean_absolute_value() {
    let camera = camera();
    let scene = Scene::new(&[primitives::cylinder(0.04, 0.1, 48).unwrap()]);
    let pose = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.7),
        UnitQuaternion::from_euler_angles(1.0, 0.3, 0.0),
    );
    let window = Window::full(&camera);
    let render = |pose: Isometry3<f64>| {
        scene
            .render(&camera, &[Instance::new(0, pose)], window)
            .unwrap()
            .depth
    };
    let observed = render(pose);
    // Axial noise alone.
    let noise = DepthSensor {
        disparity_step_px: 0.0,
        lateral_sigma_px: 0.0,
        shadows: false,
        edge_dropout: 0.0,
        dropout: 0.0,
        misregistration_px: 0.0,
        max_incidence_deg: 90.0,
        grazing_sigma: 0.0,
        ..DepthSensor::kinect()
    };
    let noisy = noise.apply(&observed, &camera, 5);
    let cap = 3.0;
    let at_truth =
        depth_discrepancy(&noisy, &observed, &sigma(&noise, &observed, &camera), cap).unwrap();
    // E[min(|N(0, 1)|, 3)].
    assert!((at_truth - 0.797).abs() < 0.08, "{at_truth}");
    let moved = Isometry3::from_parts(Translation3::new(0.005, 0.0, 0.7), pose.rotation);
    let turned = Isometry3::from_parts(
        pose.translation,
        UnitQuaternion::from_euler_angles(1.2, 0.3, 0.0),
    );
    for wrong in [moved, turned] {
        let rendered = render(wrong);
        let score = depth_discrepancy(&noisy, &rendered, &sigma(&noise, &rendered, &camera), cap);
        assert!(score.unwrap() > 2.0 * at_truth);
    }
}

/// The expected error of each pixel of a rendering.
fn sigma(sensor: &DepthSensor, rendered: &[f32], camera: &PinholeCamera) -> Vec<f32> {
    sensor.expected_errors(rendered, camera.width as usize, camera.fx as f32)
}

/// The yardstick of the score fits what the sensor reads: the true surface scores about
/// E[min(|N(0, 1)|, 3)] ≈ 0.80 whatever the sensor, depth and tilt, lateral noise and
/// quantisation included (shadows, edges and dropout aside, which leave holes).
#[test]
fn the_true_surface_scores_the_same_under_every_sensor_depth_and_tilt() {
    let camera = PinholeCamera::new(1075.0, 1075.0, 160.0, 120.0, 320, 240).unwrap();
    let scene = Scene::new(&[primitives::plane(20.0, 20.0).unwrap()]);
    for preset in SensorPreset::ALL {
        let sensor = DepthSensor {
            misregistration_px: 0.0,
            ..preset.sensor()
        };
        for z in [0.6, 1.0, 1.4] {
            for tilt in [0.0f64, 40.0, 65.0] {
                let facing = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt.to_radians())
                    * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
                let pose = Isometry3::from_parts(Translation3::new(0.0, 0.0, z), facing);
                let clean = scene
                    .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
                    .unwrap()
                    .depth;
                let read = sensor.apply(&clean, &camera, 9);
                let score = depth_discrepancy(&read, &clean, &sigma(&sensor, &clean, &camera), 3.0);
                let score = score.unwrap();
                assert!(
                    (0.6..1.0).contains(&score),
                    "{} at {z} m, tilt {tilt}°: {score:.3}",
                    preset.name()
                );
            }
        }
    }
}

#[test]
fn surface_samples_are_uniform_over_area_and_on_the_surface() {
    let mesh = primitives::cuboid([0.4, 0.1, 0.1]).unwrap();
    let (points, normals) = sample_surface(&mesh, 20_000, 3);
    assert_eq!(points.len(), 20_000);
    assert_eq!(
        (points.clone(), normals.clone()),
        sample_surface(&mesh, 20_000, 3)
    );
    let (mut on_big_faces, half) = (0usize, [0.2f32, 0.05, 0.05]);
    for (p, n) in points.iter().zip(&normals) {
        let face = (0..3)
            .find(|&i| (p[i].abs() - half[i]).abs() < 1e-6)
            .expect("on a face");
        assert!((n.norm() - 1.0).abs() < 1e-5);
        assert!(
            (n[face].abs() - 1.0).abs() < 1e-5 && n[face] * p[face] > 0.0,
            "normal points outwards"
        );
        on_big_faces += usize::from(face != 0);
    }
    // The four 0.4 × 0.1 faces hold 0.16 of the 0.18 m² total.
    let fraction = on_big_faces as f64 / points.len() as f64;
    assert!((fraction - 0.16 / 0.18).abs() < 0.01, "{fraction}");
}

proptest! {
    /// VSD is a fraction, the same whichever pose is called the truth, and 0 for a pose
    /// compared with itself.
    #[test]
    fn visible_surface_discrepancy_is_a_symmetric_fraction(
        pixels in prop::collection::vec((0.0f32..2.0, 0.0f32..2.0, 0.0f32..2.0), 1..64),
        delta in 0.001f32..0.05,
        tau in 0.001f32..0.05,
    ) {
        let observed: Vec<f32> = pixels.iter().map(|p| p.0).collect();
        let a: Vec<f32> = pixels.iter().map(|p| p.1).collect();
        let b: Vec<f32> = pixels.iter().map(|p| p.2).collect();
        // As documented: a rendered pixel is visible where the observed depth is missing or
        // lies no nearer than `delta` in front of it; VSD is `None` only when no pixel is
        // visible under either pose.
        let visible = |rendered: f32, observed: f32| {
            rendered > 0.0 && (observed <= 0.0 || rendered - observed <= delta)
        };
        let seen_a = pixels.iter().any(|p| visible(p.1, p.0));
        let seen_b = pixels.iter().any(|p| visible(p.2, p.0));
        let ab = visible_surface_discrepancy(&observed, &a, &b, delta, tau);
        prop_assert_eq!(ab, visible_surface_discrepancy(&observed, &b, &a, delta, tau));
        prop_assert_eq!(ab.is_some(), seen_a || seen_b);
        if let Some(error) = ab {
            prop_assert!((0.0..=1.0).contains(&error));
        }
        let same = visible_surface_discrepancy(&observed, &a, &a, delta, tau);
        prop_assert_eq!(same, seen_a.then_some(0.0));
    }
}
