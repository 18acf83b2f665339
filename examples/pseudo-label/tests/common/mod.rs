//! Helpers shared by the integration tests: fixtures copied into a temporary folder, since
//! labelling writes beside the images, and labelled through the library as `ipdf label` does.
#![allow(dead_code)] // each test file uses its own subset

use std::path::Path;

use bop_dataset::BopDataset;
use pseudo_label::{DatasetOptions, LabelError, LabelOptions, LabelSummary, Shard, label_dataset};

/// Copies the fixture folder `from` into `to`.
pub fn copy_dir(from: &Path, to: &Path) {
    bop_dataset::copy_dataset(from, to).unwrap();
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
