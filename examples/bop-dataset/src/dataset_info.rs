//! `dataset_info.json`: what a dataset written by `ipdf synth` holds (its generator, variant and
//! object names), so that tools can name objects and a rerun into the same folder with other
//! objects is refused. Datasets from elsewhere have none.
use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::{BopDataset, FileError, read_json_as, write_json};

/// The content of `dataset_info.json`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DatasetInfo {
    /// The program that wrote the dataset (`ipdf synth`).
    #[serde(default)]
    pub generator: String,
    /// `uniform` or `texture`.
    #[serde(default)]
    pub variant: String,
    /// Object names by object id.
    #[serde(rename = "objects", default)]
    pub names: BTreeMap<u32, String>,
}

impl BopDataset {
    /// `dataset_info.json` in the dataset's root.
    pub fn info_path(&self) -> PathBuf {
        self.root.join("dataset_info.json")
    }

    /// The dataset's `dataset_info.json`, or `None` for a dataset without one.
    pub fn read_info(&self) -> Result<Option<DatasetInfo>, FileError> {
        let path = self.info_path();
        if !path.exists() {
            return Ok(None);
        }
        read_json_as(&path).map(Some)
    }

    /// Writes `dataset_info.json` atomically.
    pub fn write_info(&self, info: &DatasetInfo) -> Result<(), FileError> {
        write_json(&self.info_path(), info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_a_damaged_file_names_it() {
        let dir = tempfile::tempdir().unwrap();
        let dataset = BopDataset::new(dir.path());
        assert_eq!(dataset.read_info().unwrap(), None);
        let info = DatasetInfo {
            generator: "ipdf synth".into(),
            variant: "uniform".into(),
            names: BTreeMap::from([(1, "can".into()), (12, "bowl".into())]),
        };
        dataset.write_info(&info).unwrap();
        let text = std::fs::read_to_string(dataset.info_path()).unwrap();
        assert!(text.contains("\"12\": \"bowl\""), "{text}");
        assert_eq!(dataset.read_info().unwrap(), Some(info));
        std::fs::write(dataset.info_path(), r#"{"objects": {"one": "can"}}"#).unwrap();
        let error = dataset.read_info().unwrap_err();
        assert!(error.path.ends_with("dataset_info.json"), "{error}");
    }
}
