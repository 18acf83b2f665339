//! A dataset laid out as T-LESS ships it, labelled through the library: meshes in
//! `models_cad/`, split `test_primesense`, non-consecutive image ids, two instances in one
//! image. The fixture belongs to `bop-dataset`, whose reader tests it describe (see
//! [`FIXTURE`]); it is read from there, not copied into this crate.
use crate::common;

use std::path::{Path, PathBuf};

use bop_dataset::{BopDataset, read_models_info, read_pseudo_gt, read_scene_gt};
use common::{copy_dir, label_split};
use pseudo_label::LabelOptions;

/// The fixture's folder, relative to the crate that owns it (`examples/bop-dataset`).
const FIXTURE: &str = "tests/data/tless_layout";

/// The fixture copied into `dir` (labelling writes beside the images).
fn copy_fixture(dir: &Path) -> PathBuf {
    let owner = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bop-dataset");
    let root = dir.join("tless");
    copy_dir(&owner.join(FIXTURE), &root);
    root
}

#[test]
fn the_t_less_layout_is_labelled_in_place_of_synthetic_data() {
    let dir = tempfile::tempdir().unwrap();
    let root = copy_fixture(dir.path());
    let dataset = BopDataset::open(&root, "models_cad").unwrap();
    let summary = label_split(&dataset, "test_primesense", &LabelOptions::default()).unwrap();
    assert_eq!((summary.images, summary.instances), (2, 3), "{summary:?}");
    let scene = dataset.scene("test_primesense", 1);
    let labels = read_pseudo_gt(&scene.pseudo_gt_path()).unwrap();
    // Image 5 shows the can alone, and its labels are its symmetric poses.
    let truth = read_scene_gt(&scene.gt_path()).unwrap()[&5][0].pose;
    let group = read_models_info(&dataset.models_info_path()).unwrap()[&1]
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
fn labelling_without_the_models_folder_stops_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let root = copy_fixture(dir.path());
    // The default `models`, which T-LESS does not have.
    let dataset = BopDataset::new(&root);
    let error = label_split(&dataset, "test_primesense", &LabelOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("models_cad") && error.contains("--models-dir"),
        "{error}"
    );
    let split = root.join("test_primesense");
    assert!(!split.join("000001/scene_pseudo_gt.json").exists());
    assert!(!split.join(pseudo_label::LABEL_OPTIONS_FILE).exists());
}
