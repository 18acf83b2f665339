//! The sensor presets against their documented parameters, measured on rendered planes and
//! boxes, and a detector's mask errors.
use depth_render::{
    DepthSensor, Instance, MaskErrors, PinholeCamera, Scene, SensorPreset, Window, primitives,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

/// A 640 × 480 camera with the sensor's own focal length, so that sensor pixels are image
/// pixels.
fn camera_of(sensor: &DepthSensor) -> PinholeCamera {
    let f = f64::from(sensor.focal_px);
    PinholeCamera::new(f, f, 319.5, 239.5, 640, 480).unwrap()
}

/// Only the axial noise and the quantisation of `sensor`.
fn axial_only(sensor: DepthSensor) -> DepthSensor {
    DepthSensor {
        lateral_sigma_px: 0.0,
        shadows: false,
        stereo_band: false,
        edge_dropout: 0.0,
        dropout: 0.0,
        misregistration_px: 0.0,
        ..sensor
    }
}

/// Clean depth of a 20 m square plane facing the camera at `z`, turned by `tilt` radians
/// about the camera's y-axis, with a 0.2 m square, 5 cm deep box in front of it whose front
/// face is at `box_front` when given.
fn render(camera: &PinholeCamera, z: f64, tilt: f64, box_front: Option<f64>) -> Vec<f32> {
    let facing = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let mut instances = vec![Instance::new(
        0,
        Isometry3::from_parts(Translation3::new(0.0, 0.0, z), facing),
    )];
    if let Some(front) = box_front {
        instances.push(Instance::new(
            1,
            Isometry3::translation(0.0, 0.0, front + 0.025),
        ));
    }
    let scene = Scene::new(&[
        primitives::plane(20.0, 20.0).unwrap(),
        primitives::cuboid([0.2, 0.2, 0.05]).unwrap(),
    ]);
    scene
        .render(camera, &instances, Window::full(camera))
        .unwrap()
        .depth
}

fn mean_and_std(values: &[f32]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let variance = values
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    (mean, variance.sqrt())
}

#[test]
fn axial_noise_on_a_plane_has_the_documented_sigma_at_each_depth() {
    for preset in SensorPreset::ALL {
        let sensor = preset.sensor();
        let camera = camera_of(&sensor);
        for z in [0.6, 0.9, 1.2, 1.6] {
            let clean = render(&camera, z, 0.0, None);
            let read: Vec<f32> = axial_only(sensor)
                .apply(&clean, &camera, 7)
                .into_iter()
                .filter(|&d| d > 0.0)
                .collect();
            assert_eq!(read.len(), clean.len(), "{}: pixels lost", preset.name());
            let (mean, std) = mean_and_std(&read);
            let expected = f64::from(sensor.reading_sigma(z as f32));
            assert!(
                (std / expected - 1.0).abs() < 0.1,
                "{} at {z} m: σ {:.3} mm, documented {:.3} mm",
                preset.name(),
                std * 1e3,
                expected * 1e3
            );
            assert!((mean - z).abs() < 0.2 * expected + f64::from(sensor.step(z as f32)));
        }
    }
    // The documented figures themselves: Nguyen's 1.88 mm at 1 m (plus the 2.9 mm disparity
    // steps of Khoshelham's model), Intel's 3.77 mm at 1 m for a D435.
    let (kinect, realsense) = (DepthSensor::kinect(), DepthSensor::realsense());
    assert!((kinect.sigma(1.0) - 0.001884).abs() < 1e-6);
    assert!((kinect.step(1.0) - 0.00285).abs() < 1e-5);
    assert!((realsense.sigma(1.0) - 0.003774).abs() < 1e-6);
}

#[test]
fn readings_lie_on_the_sensors_depth_lattice() {
    let kinect = DepthSensor::kinect();
    let camera = camera_of(&kinect);
    let clean = render(&camera, 1.1, 0.5, None);
    let focal_baseline = kinect.focal_px * kinect.baseline;
    for &d in kinect
        .apply(&clean, &camera, 3)
        .iter()
        .filter(|&&d| d > 0.0)
    {
        let steps = focal_baseline / d / kinect.disparity_step_px;
        assert!(
            (steps - steps.round()).abs() < 0.02,
            "{d} m is {steps} steps"
        );
    }
    let realsense = DepthSensor::realsense();
    let camera = camera_of(&realsense);
    let clean = render(&camera, 1.1, 0.5, None);
    for &d in realsense
        .apply(&clean, &camera, 3)
        .iter()
        .filter(|&&d| d > 0.0)
    {
        assert!(
            (d * 1e3 - (d * 1e3).round()).abs() < 1e-3,
            "{d} m not in mm"
        );
    }
}

#[test]
fn random_dropout_loses_the_documented_fraction_of_a_plane() {
    for preset in SensorPreset::ALL {
        let sensor = DepthSensor {
            misregistration_px: 0.0,
            ..preset.sensor()
        };
        let camera = camera_of(&sensor);
        let z = 1.0;
        let read = sensor.apply(&render(&camera, z, 0.0, None), &camera, 11);
        // Away from the image's edges and the stereo band (f·B/z pixels on the left).
        let band = (f64::from(sensor.focal_px * sensor.baseline) / z).ceil() as usize + 2;
        let interior: Vec<f32> = (0..read.len())
            .filter(|&i| (i % 640 >= band.max(4) && i % 640 < 636) && (4..476).contains(&(i / 640)))
            .map(|i| read[i])
            .collect();
        let lost = interior.iter().filter(|&&d| d == 0.0).count() as f64 / interior.len() as f64;
        assert!(
            (lost / f64::from(sensor.dropout) - 1.0).abs() < 0.1,
            "{}: {:.4} lost, documented {}",
            preset.name(),
            lost,
            sensor.dropout
        );
    }
}

#[test]
fn pixels_near_depth_steps_are_lost_at_the_documented_rate() {
    for preset in SensorPreset::ALL {
        let sensor = DepthSensor {
            shadows: false,
            stereo_band: false,
            lateral_sigma_px: 0.0,
            dropout: 0.0,
            misregistration_px: 0.0,
            ..preset.sensor()
        };
        let camera = camera_of(&sensor);
        let clean = render(&camera, 1.0, 0.0, Some(0.7));
        let read = sensor.apply(&clean, &camera, 5);
        // Pixels within the edge radius (Chebyshev) of one whose 4-neighbour is 2% away.
        let (width, height) = (640i64, 480i64);
        let at = |u: i64, v: i64| clean[(v * width + u) as usize];
        let step = |u: i64, v: i64| {
            [(u - 1, v), (u + 1, v), (u, v - 1), (u, v + 1)]
                .iter()
                .filter(|&&(x, y)| (0..width).contains(&x) && (0..height).contains(&y))
                .any(|&(x, y)| (at(x, y) - at(u, v)).abs() > 0.02 * at(x, y).min(at(u, v)))
        };
        let radius = sensor.edge_radius_px as i64;
        let (mut near, mut near_lost, mut far_lost) = (0usize, 0usize, 0usize);
        for v in 0..height {
            for u in 0..width {
                let is_near = (-radius..=radius).any(|dv| {
                    (-radius..=radius).any(|du| {
                        let (x, y) = (u + du, v + dv);
                        (0..width).contains(&x) && (0..height).contains(&y) && step(x, y)
                    })
                });
                let lost = read[(v * width + u) as usize] == 0.0;
                if is_near {
                    near += 1;
                    near_lost += usize::from(lost);
                } else {
                    far_lost += usize::from(lost);
                }
            }
        }
        let fraction = near_lost as f64 / near as f64;
        assert!(near > 1000, "{near} edge pixels");
        assert!(
            (fraction / f64::from(sensor.edge_dropout) - 1.0).abs() < 0.1,
            "{}: {fraction:.3} of {near} edge pixels lost, documented {}",
            preset.name(),
            sensor.edge_dropout
        );
        assert_eq!(
            far_lost,
            0,
            "{}: pixels lost away from edges",
            preset.name()
        );
    }
}

/// The lost pixels of row 240 just left of the box (whose edges are at columns `left` and
/// `right`), and whether any right of it is lost.
fn shadow_left_of(read: &[f32], left: usize, right: usize) -> (usize, bool) {
    let row = &read[240 * 640..241 * 640];
    let width = row[..left].iter().rev().take_while(|&&d| d == 0.0).count();
    (width, row[right + 1..].contains(&0.0))
}

#[test]
fn shadows_and_the_stereo_band_are_as_wide_as_the_baseline_makes_them() {
    for preset in SensorPreset::ALL {
        let sensor = DepthSensor {
            lateral_sigma_px: 0.0,
            edge_dropout: 0.0,
            dropout: 0.0,
            misregistration_px: 0.0,
            ..preset.sensor()
        };
        let camera = camera_of(&sensor);
        let (front, back) = (0.6, 1.2);
        let read = sensor.apply(&render(&camera, back, 0.0, Some(front)), &camera, 2);
        let fb = camera.fx * f64::from(sensor.baseline);
        // The box's edges: x = ∓0.1 m at the front face.
        let left = (camera.cx - camera.fx * 0.1 / front).ceil() as usize;
        let right = (camera.cx + camera.fx * 0.1 / front).floor() as usize;
        let (width, right_lost) = shadow_left_of(&read, left, right);
        let expected = fb * (1.0 / front - 1.0 / back);
        assert!(
            (width as f64 - expected).abs() <= 1.5,
            "{}: shadow {width} px, expected {expected:.1}",
            preset.name()
        );
        assert!(
            !right_lost,
            "{}: lost pixels right of the box",
            preset.name()
        );
        let row = &read[100 * 640..101 * 640];
        let band = row.iter().take_while(|&&d| d == 0.0).count();
        let expected_band = if sensor.stereo_band { fb / back } else { 0.0 };
        assert!(
            (band as f64 - expected_band).abs() <= 1.0,
            "{}: band {band} px, expected {expected_band:.1}",
            preset.name()
        );
    }
}

#[test]
fn grazing_surfaces_read_nothing_and_oblique_ones_more_noise() {
    let sensor = DepthSensor {
        misregistration_px: 0.0,
        lateral_sigma_px: 0.0,
        dropout: 0.0,
        ..DepthSensor::kinect()
    };
    let camera = camera_of(&sensor);
    // The middle column, where the incidence is the tilt or more (up to 5° more at the top and
    // bottom rows).
    let read_fraction = |tilt_deg: f64| {
        let clean = render(&camera, 1.0, tilt_deg.to_radians(), None);
        let read = sensor.apply(&clean, &camera, 4);
        let column: Vec<usize> = (0..480)
            .map(|v| v * 640 + 320)
            .filter(|&i| clean[i] > 0.0)
            .collect();
        assert!(column.len() > 400);
        column.iter().filter(|&&i| read[i] > 0.0).count() as f64 / column.len() as f64
    };
    assert!(read_fraction(40.0) > 0.98);
    assert!(read_fraction(89.0) < 0.02);
    assert!(sensor.sigma_at_incidence(1.0, 80f32.to_radians()) > 4.0 * sensor.sigma(1.0));
    assert_eq!(sensor.sigma_at_incidence(1.0, 0.5), sensor.sigma(1.0));
}

#[test]
fn readings_are_seeded_and_independent_of_threads() {
    let sensor = DepthSensor::kinect();
    let camera = PinholeCamera::new(1075.0, 1075.0, 160.0, 120.0, 320, 240).unwrap();
    let clean = render(&camera, 1.0, 0.3, Some(0.8));
    let a = sensor.apply(&clean, &camera, 1);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    assert_eq!(a, one_thread.install(|| sensor.apply(&clean, &camera, 1)));
    assert_ne!(a, sensor.apply(&clean, &camera, 2));
}

proptest! {
    /// A reading is the depth of a nearby pixel of the scene (within the misregistration and
    /// five lateral σ) plus at most five axial σ and one quantisation step, within the
    /// sensor's range: nothing is invented.
    #[test]
    fn every_reading_comes_from_a_nearby_surface(
        seed in 0u64..1000,
        preset in prop::sample::select(SensorPreset::ALL.to_vec()),
        depths in prop::collection::vec(prop_oneof![Just(0.0f32), 0.3f32..3.0], 24 * 16),
    ) {
        let sensor = preset.sensor();
        let camera = PinholeCamera::new(800.0, 800.0, 12.0, 8.0, 24, 16).unwrap();
        let scale = 800.0 / sensor.focal_px;
        let reach = ((sensor.misregistration_px * scale).round()
            + (5.0 * sensor.lateral_sigma_px * scale).ceil()) as i64;
        let read = sensor.apply(&depths, &camera, seed);
        prop_assert_eq!(read.len(), depths.len());
        for (i, &d) in read.iter().enumerate() {
            if d == 0.0 {
                continue;
            }
            prop_assert!(d >= sensor.range[0] - 0.1 && d <= sensor.range[1] + 0.5);
            let (u, v) = ((i % 24) as i64, (i / 24) as i64);
            let explained = (-reach..=reach).any(|dv| (-reach..=reach).any(|du| {
                let (x, y) = (u + du, v + dv);
                (0..24).contains(&x) && (0..16).contains(&y) && {
                    let z = depths[(y * 24 + x) as usize];
                    z > 0.0 && (d - z).abs() <= 5.0 * sensor.sigma_at_incidence(z, 1.39)
                        + sensor.step(z)
                }
            }));
            prop_assert!(explained, "reading {} at ({}, {}) explained by no pixel", d, u, v);
        }
    }

    /// A detector's mask differs from the true one only within the shift and one more pixel of
    /// its boundary, is seeded, and without raggedness is the true mask grown or shrunk by a
    /// whole number of pixels.
    #[test]
    fn mask_errors_stay_at_the_boundary(
        seed in 0u64..1000,
        max_shift in 0u32..3,
        (u0, v0, side) in (3usize..10, 3usize..10, 4usize..12),
    ) {
        let width = 24usize;
        let mask: Vec<bool> = (0..width * width)
            .map(|i| (u0..u0 + side).contains(&(i % width)) && (v0..v0 + side).contains(&(i / width)))
            .collect();
        let errors = MaskErrors { max_shift_px: max_shift, ragged: 0.3 };
        let noisy = errors.apply(&mask, width, seed);
        prop_assert_eq!(&noisy, &errors.apply(&mask, width, seed));
        let reach = max_shift as i64 + 1;
        for (i, (&a, &b)) in mask.iter().zip(&noisy).enumerate() {
            if a != b {
                let (u, v) = ((i % width) as i64, (i / width) as i64);
                let near_boundary = (-reach..=reach).any(|dv| (-reach..=reach).any(|du| {
                    let (x, y) = (u + du, v + dv);
                    (0..width as i64).contains(&x) && (0..width as i64).contains(&y)
                        && mask[y as usize * width + x as usize] != a
                }));
                prop_assert!(near_boundary, "pixel {} changed far from the boundary", i);
            }
        }
        let square = MaskErrors { max_shift_px: max_shift, ragged: 0.0 }.apply(&mask, width, seed);
        let count = square.iter().filter(|&&m| m).count();
        let grown = |k: i64| ((side as i64 + 2 * k).max(0) as usize).pow(2);
        prop_assert!((-(max_shift as i64)..=max_shift as i64).any(|k| count == grown(k)),
            "{} pixels from a {}-pixel square", count, side);
    }
}
