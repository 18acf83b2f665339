//! The real YCB-Video frames of `pseudo-label` through the command line: `ipdf label` labels
//! every instance. The fixture and the tests of its labels (scored against the ground truth)
//! belong to `pseudo-label` (`examples/pseudo-label/tests/real_frames.rs`).
mod common;

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
            let r: Vec<f64> = instance["cam_R_m2c"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let m = nalgebra::Matrix3::from_row_slice(&r);
            let error = (m.transpose() * m - nalgebra::Matrix3::identity())
                .abs()
                .max();
            published += usize::from(error > 1e-4);
        }
    }
    assert!(published > 0);
    assert_eq!(run["report"]["repaired_rotations"]["count"], published);
}
