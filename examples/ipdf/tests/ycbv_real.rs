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
    let run = ipdf_json(&[
        "label",
        "--dataset",
        s(&root),
        "--split",
        "test",
        "--sensor",
        "kinect",
    ]);
    // 3 images, 11 instances (the fixture's `scene_gt.json`), every one labelled.
    let counts = ["images", "instances", "labelled", "failed"].map(|key| run[key].as_u64());
    assert_eq!(counts, [Some(3), Some(11), Some(11), Some(0)], "{run}");
    for scene_id in 0..3 {
        let labels = root.join(format!("test/{scene_id:06}/scene_pseudo_gt.json"));
        assert!(labels.exists(), "{}", labels.display());
    }
}
