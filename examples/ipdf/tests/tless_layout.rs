//! The T-LESS-shaped fixture of `bop-dataset` (`examples/bop-dataset/tests/data/tless_layout`)
//! through the command line and the training data: labelled in place of synthetic data, full
//! masks standing in for missing visible ones, the models folder named by its flag.
mod common;

use std::path::{Path, PathBuf};

use bop_dataset::{BopDataset, read_models_info, read_pseudo_gt, read_scene_gt};
use common::{copy_dir, ipdf_json, s};
use ipdf::training_data::{ExampleOptions, LabelSource, load_examples};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bop-dataset/tests/data/tless_layout")
}

#[test]
fn the_t_less_layout_is_labelled_in_place_of_synthetic_data() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("tless");
    copy_dir(&fixture(), &root);
    let run = ipdf_json(&[
        "label",
        "--dataset",
        s(&root),
        "--split",
        "test_primesense",
        "--models-dir",
        "models_cad",
    ]);
    assert_eq!(
        (run["images"].as_u64(), run["instances"].as_u64()),
        (Some(2), Some(3)),
        "{run}"
    );
    let labels = read_pseudo_gt(&root.join("test_primesense/000001/scene_pseudo_gt.json")).unwrap();
    // Image 5 shows the can alone, and its labels are its symmetric poses.
    let truth =
        read_scene_gt(&root.join("test_primesense/000001/scene_gt.json")).unwrap()[&5][0].pose;
    let group = read_models_info(&root.join("models_cad/models_info.json")).unwrap()[&1]
        .symmetry
        .clone();
    let found = &labels[&5][0];
    assert!(
        found.error.is_none() && !found.labels.is_empty(),
        "{found:?}"
    );
    for label in &found.labels {
        let error = group
            .class_distances(&truth.rotation, &label.pose.rotation)
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        assert!(error.to_degrees() < 2.0, "{}", error.to_degrees());
    }
}

#[test]
fn without_mask_visib_the_full_masks_serve_and_fully_occluded_instances_are_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("tless");
    copy_dir(&fixture(), &root);
    let scene_dir = root.join("test_primesense/000001");
    std::fs::remove_dir_all(scene_dir.join("mask_visib")).unwrap();
    let dataset = BopDataset::open(&root, "models_cad").unwrap();
    let scene = dataset.scene("test_primesense", 1);
    assert_eq!(scene.visible_mask_path(5, 0), scene.mask_path(5, 0));
    let options = ExampleOptions {
        split: "test_primesense".into(),
        obj_id: 1,
        labels: LabelSource::Single,
        input_size: 32,
        min_visible_fraction: 0.0,
        continuous_steps: 1,
    };
    let both = load_examples(&dataset, &options).unwrap();
    assert_eq!(both.instances.len(), 2);
    // The can of image 0 fully occluded: an empty mask, as BOP ships such instances.
    let blank = image::GrayImage::new(160, 120);
    blank.save(scene.mask_path(0, 0)).unwrap();
    let left = load_examples(&dataset, &options).unwrap();
    assert_eq!(left.instances.len(), 1);
    assert_eq!(left.instances[0].im_id, 5);
    // With none left, the error says so.
    blank.save(scene.mask_path(5, 0)).unwrap();
    let error = load_examples(&dataset, &options).err().unwrap().to_string();
    assert!(error.contains("empty visible mask"), "{error}");
}

#[test]
fn labelling_without_the_models_folder_stops_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("tless");
    copy_dir(&fixture(), &root);
    let out = common::ipdf(&["label", "--dataset", s(&root), "--split", "test_primesense"]);
    assert!(!out.status.success());
    let error = String::from_utf8_lossy(&out.stderr);
    assert!(
        error.contains("models") && error.contains("--models-dir"),
        "{error}"
    );
    assert!(
        !root
            .join("test_primesense/000001/scene_pseudo_gt.json")
            .exists()
    );
}
