//! The first label's search goes on past a pose it accepts but does not call good: on one
//! Kinect render of the demo's bowl (`tests/data/kinect_bowl`, see its `SOURCES.md`) the first
//! trials and the grid search leave a pose whose axis is 5.7° off at a score of 1.08, under the
//! acceptance bar of 1.3 but over the good score of 0.9; the further trials find the bowl's
//! true ring. The bowl is symmetric about its z axis, so a label is right exactly where its z
//! axis is the truth's: the angle between the two axes is the error, whatever the turn.
use crate::common;

use std::path::Path;

use bop_dataset::{BopDataset, read_pseudo_gt, read_scene_gt};
use common::{copy_dir, label_split};
use nalgebra::{UnitQuaternion, Vector3};
use pseudo_label::LabelOptions;

#[test]
fn an_accepted_pose_that_is_not_good_does_not_end_the_search() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kinect_bowl");
    let dir = tempfile::tempdir().unwrap();
    copy_dir(&fixture, dir.path());
    let dataset = BopDataset::open(dir.path(), "models").unwrap();
    let options = LabelOptions::default();
    label_split(&dataset, "train", &options).unwrap();

    let scene = dir.path().join("train/000002");
    let truth = read_scene_gt(&scene.join("scene_gt.json")).unwrap()[&15][0].pose;
    let labels = &read_pseudo_gt(&scene.join("scene_pseudo_gt.json")).unwrap()[&15][0];
    let axis = |rotation: &UnitQuaternion<f64>| rotation * Vector3::z();
    let true_axis = axis(&truth.rotation);
    assert!(!labels.labels.is_empty(), "the bowl is labelled");
    for label in &labels.labels {
        let error = axis(&label.pose.rotation).angle(&true_axis).to_degrees();
        assert!(
            error < 3.0,
            "a label's axis is {error:.2}° from the truth's (score {})",
            label.score
        );
    }
}
