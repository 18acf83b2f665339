//! The T-LESS-shaped fixture of `bop-dataset` (`examples/bop-dataset/tests/data/tless_layout`)
//! through the command line and the training data: full masks standing in for missing visible
//! ones, the models folder named by its flag. Its labels are tested through the library, in
//! `examples/pseudo-label/tests/tless_layout.rs`.
use crate::common;

use std::path::{Path, PathBuf};

use bop_dataset::BopDataset;
use common::{copy_dir, s};
use ipdf::training_data::{CropSource, ExampleOptions, LabelSource, load_examples};

/// The fixture's folder, in the crate that owns it (`examples/bop-dataset`).
const FIXTURE: &str = "../bop-dataset/tests/data/tless_layout";

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(FIXTURE)
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
        crop: CropSource::Mask,
        box_jitter: None,
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
