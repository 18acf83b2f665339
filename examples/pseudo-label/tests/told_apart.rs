//! The acceptance rule's pixel test (`Comparison::told_apart_from`) on a mug, against what the
//! geometry of the view says. With the handle in profile, a pose that puts it elsewhere round
//! the cup is told apart from the truth, even where the sensor reads only one pixel in three
//! of the handle (a thin part's readings are sparse on a real sensor); turns whose clean renders
//! match the truth's (the handle behind the cup) are not.
use depth_render::{DepthSensor, Instance, PinholeCamera, Scene, Window};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use pseudo_label::{Comparison, Observation, PixelLattice, compare_pose};
use synth_data::{ObjectKind, SynthObject, SynthOptions};

/// The sampling of the labeller's default `pixel_stride`.
const STRIDE: u32 = 2;

/// The outlier cap of the labeller's defaults.
const CAP: f32 = 3.0;

/// Model→camera: the mug 0.8 m away, its axis up in the image and tilted `tilt_deg` towards
/// the camera, turned `turn_deg` about its own axis; at turn 0 the handle points right, in
/// profile, and at +90° straight away from the camera, behind the cup.
fn pose(turn_deg: f64, tilt_deg: f64) -> Isometry3<f64> {
    // Columns: the model's x to the image's right, its y away from the camera, its z up.
    let upright = Rotation3::from_matrix_unchecked(Matrix3::new(
        1.0, 0.0, 0.0, //
        0.0, 0.0, -1.0, //
        0.0, 1.0, 0.0,
    ));
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians());
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn_deg.to_radians());
    Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.8),
        tilt * UnitQuaternion::from_rotation_matrix(&upright) * turn,
    )
}

struct View {
    scene: Scene,
    camera: PinholeCamera,
}

impl View {
    fn new() -> Self {
        let object = SynthObject::built_in(ObjectKind::Mug).unwrap();
        Self {
            scene: Scene::new(std::slice::from_ref(&object.mesh)),
            camera: SynthOptions::t_less_camera().camera,
        }
    }

    /// The clean depth of the whole image at `pose`.
    fn depth(&self, pose: &Isometry3<f64>) -> Vec<f32> {
        self.scene
            .render(
                &self.camera,
                &[Instance::new(0, *pose)],
                Window::full(&self.camera),
            )
            .unwrap()
            .depth
    }

    /// Whether the clean renders at `a` and `b` match to within 1 mm on all but 0.5% of the
    /// pixels either shows: the view cannot tell them apart, by brute force.
    fn look_alike(&self, a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
        let (a, b) = (self.depth(a), self.depth(b));
        let shown = a.iter().zip(&b).filter(|(x, y)| **x > 0.0 || **y > 0.0);
        let (count, differ) = shown.fold((0, 0), |(n, d), (x, y)| {
            (n + 1, d + usize::from((x - y).abs() > 0.001))
        });
        differ * 200 <= count
    }

    /// The comparisons of `candidates` with `depth` observed under `mask` (the image's size),
    /// sampled as the labeller samples it.
    fn compare(
        &self,
        depth: &[f32],
        mask: &[bool],
        candidates: &[Isometry3<f64>],
    ) -> Vec<Comparison> {
        let lattice = PixelLattice::new(&self.camera, STRIDE);
        let (depth, mask) = (lattice.sample(depth, 0.0), lattice.sample(mask, false));
        let observation = Observation::new(lattice.camera, &depth, &mask).unwrap();
        candidates
            .iter()
            .map(|pose| {
                compare_pose(&self.scene, &observation, pose, &DepthSensor::kinect(), CAP).unwrap()
            })
            .collect()
    }
}

/// The handle in profile, read at one pixel in three: every turn that moves it (20° to 180°
/// round the cup, either way) is told apart from the truth, though it explains the cup itself
/// as well as the truth does.
#[test]
fn a_handle_in_view_with_sparse_readings_tells_the_turns_that_move_it_apart() {
    let view = View::new();
    let truth = pose(0.0, 10.0);
    let hidden = view.depth(&pose(90.0, 10.0));
    let mut depth = view.depth(&truth);
    let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
    // The handle's pixels: where the truth shows something nearer than the mug with its handle
    // turned behind the cup shows, or something where it shows nothing.
    let handle: Vec<usize> = (0..depth.len())
        .filter(|&i| depth[i] > 0.0 && (hidden[i] == 0.0 || hidden[i] - depth[i] > 0.005))
        .collect();
    assert!(handle.len() > 300, "{} handle pixels", handle.len());
    for (k, &i) in handle.iter().enumerate() {
        if k % 3 != 0 {
            depth[i] = 0.0;
        }
    }
    let turns = [-180.0, -90.0, -45.0, -20.0, 20.0, 45.0, 90.0, 135.0];
    let mut candidates = vec![truth];
    candidates.extend(turns.iter().map(|&t| pose(t, 10.0)));
    let compared = view.compare(&depth, &mask, &candidates);
    let (best, others) = compared.split_first().unwrap();
    for (turn, comparison) in turns.iter().zip(others) {
        assert!(
            comparison.told_apart_from(best),
            "turned {turn}°: score {} against the truth's {}",
            comparison.score,
            best.score
        );
        assert!(!best.told_apart_from(comparison), "turned {turn}°");
    }
}

/// The handle behind the cup: the turns whose clean renders match the truth's (found by
/// rendering every 5°; at least 40° of them) are not told apart from it, nor it from them.
#[test]
fn turns_that_keep_the_handle_out_of_sight_are_not_told_apart() {
    let view = View::new();
    let truth = pose(90.0, 10.0);
    let alike: Vec<Isometry3<f64>> = (-12..=12)
        .filter(|&k| k != 0)
        .map(|k| pose(90.0 + 5.0 * f64::from(k), 10.0))
        .filter(|turned| view.look_alike(&truth, turned))
        .collect();
    assert!(alike.len() >= 8, "{} turns alike", alike.len());
    let depth = view.depth(&truth);
    let mask: Vec<bool> = depth.iter().map(|&d| d > 0.0).collect();
    let mut candidates = vec![truth];
    candidates.extend(&alike);
    let compared = view.compare(&depth, &mask, &candidates);
    let (best, others) = compared.split_first().unwrap();
    for (pose, comparison) in alike.iter().zip(others) {
        let turn = (truth.rotation.inverse() * pose.rotation)
            .angle()
            .to_degrees();
        assert!(!comparison.told_apart_from(best), "turned {turn:.0}°");
        assert!(!best.told_apart_from(comparison), "turned {turn:.0}°");
    }
}
