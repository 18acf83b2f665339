//! The line of sight's frame, checked against the renderer: an object seen off the optical axis
//! looks, in its crop, as the same object seen on the axis at its rotation in that frame.
use std::path::PathBuf;

use depth_render::{Instance, PinholeCamera, Scene, Window};
use ipdf_model::rotation::RotationFrame;
use ipdf_model::translation::{CameraIntrinsics, CropGeometry};
use ipdf_model::{CropOptions, crop_box, crop_object};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use synth_data::SynthObject;

const SIZE: usize = 96;

/// The real mug scan of the YCB-Video fixture: no symmetry once its handle shows.
fn mug() -> SynthObject {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../pseudo-label/tests/data/ycbv_real/models/obj_000014.ply");
    SynthObject::from_mesh_file(&path, 0.001).unwrap().0
}

/// The object's silhouette at `pose`, cropped as the models' crops are, and the crop's geometry.
fn silhouette(
    scene: &Scene,
    camera: &PinholeCamera,
    pose: Isometry3<f64>,
) -> (Vec<f32>, CropGeometry) {
    let depth = scene
        .render(camera, &[Instance::new(0, pose)], Window::full(camera))
        .unwrap()
        .depth;
    let mask: Vec<u8> = depth.iter().map(|&z| u8::from(z > 0.0)).collect();
    let white: Vec<u8> = mask.iter().flat_map(|&m| [m * 255; 3]).collect();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let options = CropOptions::new(SIZE);
    let crop = crop_object(&white, &mask, w, h, &options).unwrap();
    let geometry = CropGeometry {
        crop: crop_box(&mask, w, h, &options).unwrap(),
        intrinsics: CameraIntrinsics {
            fx: camera.fx,
            fy: camera.fy,
            cx: camera.cx,
            cy: camera.cy,
        },
        width: w,
        height: h,
    };
    // One channel is enough.
    (crop[..SIZE * SIZE].to_vec(), geometry)
}

/// Intersection over union of two crops' silhouettes.
fn iou(a: &[f32], b: &[f32]) -> f64 {
    let (mut both, mut either) = (0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x > 0.5, y > 0.5);
        both += f64::from(u8::from(x && y));
        either += f64::from(u8::from(x || y));
    }
    both / either
}

#[test]
fn an_object_off_the_axis_looks_as_on_the_axis_at_its_line_of_sight_rotation() {
    let object = mug();
    let scene = Scene::new(std::slice::from_ref(&object.mesh));
    let camera = PinholeCamera::new(600.0, 600.0, 319.5, 239.5, 640, 480).unwrap();
    // Lying on its side and turned, so that a turn about any axis shows in its silhouette.
    let rotation = UnitQuaternion::from_euler_angles(1.3, 0.4, 0.9);
    let distance = 0.7;
    // Towards pixels far off the principal point, 14–24° off the optical axis.
    let mut gains = Vec::new();
    for (u, v) in [
        (540.0, 120.0),
        (100.0, 380.0),
        (560.0, 300.0),
        (200.0, 150.0),
    ] {
        let ray = Vector3::new(
            (u - camera.cx) / camera.fx,
            (v - camera.cy) / camera.fy,
            1.0,
        );
        let placed = Translation3::from(ray.normalize() * distance);
        let (off_axis, geometry) =
            silhouette(&scene, &camera, Isometry3::from_parts(placed, rotation));
        let turn = RotationFrame::LineOfSight.to_camera(&geometry);
        assert!(turn.angle().to_degrees() > 14.0, "{}", turn.angle());
        let on_axis = |r: UnitQuaternion<f64>| {
            let centred = Translation3::new(0.0, 0.0, distance);
            silhouette(&scene, &camera, Isometry3::from_parts(centred, r)).0
        };
        // The rotation in the line of sight's frame shows what the camera saw, but for the
        // perspective's stretch of a crop far off the axis; the camera's own rotation shows the
        // mug tilted by the angle off the axis, and the turn the other way by twice that.
        let same = iou(&off_axis, &on_axis(turn.inverse() * rotation));
        let unturned = iou(&off_axis, &on_axis(rotation));
        let wrong_way = iou(&off_axis, &on_axis(turn * rotation));
        let scores = format!(
            "({u}, {v}): IoU {same} in the line of sight's frame, {unturned} unturned, \
             {wrong_way} turned the other way"
        );
        assert!(same > 0.85, "{scores}");
        assert!(
            same > unturned + 0.02 && unturned > wrong_way + 0.05,
            "{scores}"
        );
        gains.push(same - unturned);
    }
    let mean = gains.iter().sum::<f64>() / gains.len() as f64;
    assert!(mean > 0.05, "{gains:?}");
}
