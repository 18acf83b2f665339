//! `run.json`, beside a training run's checkpoint: which dataset, split, object and labels the
//! model was trained on, so that `ipdf eval`, `predict` and `viz` need only the run folder.
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use bop_dataset::{BopDataset, FileError, write_json};

use crate::training_data::CropSource;

/// The name of the file in a run folder.
pub const RUN_FILE: &str = "run.json";

/// What a model was trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The dataset folder.
    pub dataset: PathBuf,
    /// Its folder of meshes and `models_info.json` (T-LESS: `models_cad`).
    #[serde(default = "default_models_dir")]
    pub models_dir: String,
    /// Its training split.
    pub split: String,
    /// `single`, `analytical` or `pseudo`.
    pub labels: String,
    /// `rotation` or `translation` (absent in runs from before translation models: rotation).
    #[serde(default = "default_target", skip_serializing_if = "is_rotation")]
    pub target: String,
    /// The object's id.
    pub obj_id: u32,
    /// The object's name (`dataset_info.json`) or `obj_NNNNNN`.
    pub object: String,
    /// Whether occlusion augmentation was on.
    pub occlusion: bool,
    /// What the crops were cut around (absent in runs on masks).
    #[serde(default, skip_serializing_if = "is_mask")]
    pub crop: CropSource,
}

fn is_mask(crop: &CropSource) -> bool {
    *crop == CropSource::Mask
}

fn default_models_dir() -> String {
    "models".into()
}

fn default_target() -> String {
    "rotation".into()
}

fn is_rotation(target: &str) -> bool {
    target == "rotation"
}

impl RunInfo {
    /// The dataset, at `root` when given (another copy of it), else where it was trained.
    pub fn dataset(&self, root: Option<&Path>) -> Result<BopDataset, FileError> {
        BopDataset::open(root.unwrap_or(&self.dataset), &self.models_dir)
    }

    /// Reads `run_dir/run.json`.
    pub fn read(run_dir: &Path) -> Result<Self, FileError> {
        let path = run_dir.join(RUN_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            FileError::new(
                &path,
                "file",
                format!("{e} (is this a run folder of `ipdf train`?)"),
            )
        })?;
        serde_json::from_str(&text).map_err(|e| FileError::new(&path, "file", e.to_string()))
    }

    /// Writes `run_dir/run.json` atomically.
    pub fn write(&self, run_dir: &Path) -> Result<(), FileError> {
        write_json(&run_dir.join(RUN_FILE), self)
    }
}
