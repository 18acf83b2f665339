//! The real YCB-Video frames of `pseudo-label` through the command line: `ipdf label` labels
//! every instance. The fixture and the tests of its labels (scored against the ground truth)
//! belong to `pseudo-label` (`examples/pseudo-label/tests/real_frames.rs`).
use crate::common;

use std::path::Path;

use common::{copy_dir, ipdf_json, s};

/// The fixture's folder, in the crate that owns it.
const FIXTURE: &str = "../pseudo-label/tests/data/ycbv_real";

#[test]
fn ipdf_label_labels_every_instance_of_the_real_frames() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("ycbv");
    copy_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join(FIXTURE), &root);
    // One rotation as a published file may hold it: scaled by 1.003 (|RᵀR − I| = 6e-3).
    let gt_path = root.join("test/000000/scene_gt.json");
    let mut gt = common::read_json(&gt_path);
    for entry in gt["1"][0]["cam_R_m2c"].as_array_mut().unwrap() {
        *entry = serde_json::json!(entry.as_f64().unwrap() * 1.003);
    }
    std::fs::write(&gt_path, gt.to_string()).unwrap();
    let run = ipdf_json(&[
        "label",
        "--dataset",
        s(&root),
        "--split",
        "test",
        "--sensor",
        "kinect",
        "--report",
        s(&dir.path().join("report.json")),
    ]);
    // 3 images, 11 instances (the fixture's `scene_gt.json`), every one labelled.
    let counts = ["images", "instances", "labelled", "failed"].map(|key| run[key].as_u64());
    assert_eq!(counts, [Some(3), Some(11), Some(11), Some(0)], "{run}");
    // The report counts the ground-truth rotations orthonormal only to more than 1e-4,
    // counted here from the files' numbers.
    let mut published = 0;
    for scene_id in 0..3 {
        let labels = root.join(format!("test/{scene_id:06}/scene_pseudo_gt.json"));
        assert!(labels.exists(), "{}", labels.display());
        let gt = common::read_json(&root.join(format!("test/{scene_id:06}/scene_gt.json")));
        for instance in gt["1"].as_array().unwrap() {
            let m = nalgebra::Matrix3::from_row_slice(&common::numbers(&instance["cam_R_m2c"]));
            let error = (m.transpose() * m - nalgebra::Matrix3::identity())
                .abs()
                .max();
            published += usize::from(error > 1e-4);
        }
    }
    assert!(published > 0);
    assert_eq!(run["report"]["repaired_rotations"]["count"], published);
}

/// Normalised cross-correlation of two equally long sequences.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let (ma, mb) = (mean(a), mean(b));
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += (x - ma) * (y - mb);
        aa += (x - ma) * (x - ma);
        bb += (y - mb) * (y - mb);
    }
    ab / (aa * bb).sqrt()
}

/// The RGB values of the pixels of `render` (rendered with `--mask`) that the real frame's
/// visible mask also covers, beside the real frame's values there.
fn paired_pixels(render: &Path, mask: &Path, visible: &Path, real: &Path) -> (Vec<f64>, Vec<f64>) {
    let read_mask = |path: &Path| bop_dataset::read_mask(path).unwrap().pixels;
    let (mask, visible) = (read_mask(mask), read_mask(visible));
    let render = bop_dataset::read_rgb(render).unwrap().pixels;
    let real = bop_dataset::read_rgb(real).unwrap().pixels;
    let mut pairs = (Vec::new(), Vec::new());
    for i in (0..mask.len()).filter(|&i| mask[i] && visible[i]) {
        pairs.0.extend(render[i].map(f64::from));
        pairs.1.extend(real[i].map(f64::from));
    }
    pairs
}

/// The fixture's texture images sit on the scans the right way up: rendered at the published
/// ground truth with `ipdf render --rgb`, every textured instance's pixels correlate with the
/// real frame's better than with the same texture turned upside down (`v ↦ 1 − v`, the
/// convention a texture source can get wrong). The oracle is the real camera image.
#[test]
fn the_fixture_textures_match_the_real_frames_at_the_ground_truth() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join(FIXTURE);
    let dir = tempfile::tempdir().unwrap();
    let flipped = dir.path().join("flipped");
    copy_dir(&fixture.join("models"), &flipped);
    let mut textured = 0;
    for scene_id in 0..3 {
        let scene = fixture.join(format!("test/{scene_id:06}"));
        let k = &common::read_json(&scene.join("scene_camera.json"))["1"]["cam_K"];
        let camera = dir.path().join("camera.json");
        let camera_json = serde_json::json!({"cam_K": k, "width": 640, "height": 480});
        std::fs::write(&camera, camera_json.to_string()).unwrap();
        let gt = common::read_json(&scene.join("scene_gt.json"));
        for (k, instance) in gt["1"].as_array().unwrap().iter().enumerate() {
            let obj_id = instance["obj_id"].as_u64().unwrap();
            let texture = format!("obj_{obj_id:06}.jpg");
            if !fixture.join("models").join(&texture).exists() {
                continue;
            }
            let upside_down = image::open(fixture.join("models").join(&texture))
                .unwrap()
                .flipv();
            upside_down.save(flipped.join(&texture)).unwrap();
            let pose = dir.path().join("pose.json");
            std::fs::write(&pose, instance.to_string()).unwrap();
            let score = |models: &Path| {
                let (render, mask) = (dir.path().join("rgb.png"), dir.path().join("mask.png"));
                let mesh = models.join(format!("obj_{obj_id:06}.ply"));
                let depth = dir.path().join("depth.png");
                ipdf_json(&[
                    "render",
                    "--mesh",
                    s(&mesh),
                    "--camera",
                    s(&camera),
                    "--pose",
                    s(&pose),
                    "--out",
                    s(&depth),
                    "--rgb",
                    s(&render),
                    "--mask",
                    s(&mask),
                ]);
                let visible = scene.join(format!("mask_visib/000001_{k:06}.png"));
                let (ours, real) =
                    paired_pixels(&render, &mask, &visible, &scene.join("rgb/000001.jpg"));
                correlation(&ours, &real)
            };
            let (right, wrong) = (score(&fixture.join("models")), score(&flipped));
            assert!(
                right > wrong + 0.05,
                "scene {scene_id}, object {obj_id}: {right:.2} against {wrong:.2} upside down"
            );
            textured += 1;
        }
    }
    // The seven YCB_sim scans carry textures; the mustard bottle appears twice.
    assert_eq!(textured, 8);
}
