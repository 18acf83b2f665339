//! Helpers shared by the integration tests: fixtures copied into a temporary folder, since
//! labelling writes beside the images, and labelled through the library as `ipdf label` does.
#![allow(dead_code)] // each test file uses its own subset

use std::path::Path;

use bop_dataset::BopDataset;
use pseudo_label::{DatasetOptions, LabelError, LabelOptions, LabelSummary, Shard, label_dataset};

/// Copies the folder `from` into `to`, recursively.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Labels every scene of `split` of `dataset` with `options`, as `ipdf label --split split`
/// does (meshes in millimetres, object ids from `scene_gt.json`, one shard), showing no
/// progress.
pub fn label_split(
    dataset: &BopDataset,
    split: &str,
    options: &LabelOptions,
) -> Result<LabelSummary, LabelError> {
    let dataset_options = DatasetOptions {
        split: split.into(),
        mesh_scale: 0.001,
        obj_id: None,
        shard: Shard::ALL,
        relabel: false,
    };
    label_dataset(dataset, &dataset_options, options, &())
}
