//! Saving and loading rotation models and their training state (see [`crate::CheckpointInfo`]).
use std::path::Path;

use serde::{Deserialize, Serialize};
use tch::Device;

use super::predict::member_mismatch;
use super::{ImplicitPdf, Trainer};
use crate::ModelError;
use crate::checkpoint::{
    CHECKPOINT_FILE, CheckpointInfo, empty_info, load_exact, restore_adam, write_checkpoint,
    write_text_atomically,
};

/// The file in a rotation model's checkpoint that names the other members of its ensemble
/// ([`ImplicitPdf::load_ensemble`]).
pub const ENSEMBLE_FILE: &str = "ensemble.json";

/// The contents of [`ENSEMBLE_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnsembleInfo {
    /// The other members' checkpoint folders, relative to the folder of the file.
    members: Vec<String>,
}

/// Names `members` (checkpoint folders relative to `dir`) as the other members of the ensemble
/// whose first member is the checkpoint in `dir`, written atomically; none removes the file.
pub fn write_ensemble(dir: &Path, members: &[String]) -> Result<(), ModelError> {
    let path = dir.join(ENSEMBLE_FILE);
    if members.is_empty() {
        return match std::fs::remove_file(&path) {
            Err(source) if source.kind() != std::io::ErrorKind::NotFound => {
                Err(ModelError::Io { path, source })
            }
            _ => Ok(()),
        };
    }
    let info = EnsembleInfo {
        members: members.to_vec(),
    };
    let text = serde_json::to_string_pretty(&info)
        .map_err(|e| ModelError::checkpoint(&path, e.to_string()))?;
    write_text_atomically(&path, &text)
}

impl ImplicitPdf {
    /// Writes the model as a checkpoint in `dir` (created if missing), with no training state.
    pub fn save(&self, dir: &Path) -> Result<(), ModelError> {
        let info = CheckpointInfo {
            model: self.config().clone(),
            ..empty_info()
        };
        write_checkpoint(dir, self.var_store(), info, None)
    }

    /// The model of the checkpoint in `dir`, on `device`; a translation model's checkpoint is
    /// refused.
    pub fn load(dir: &Path, device: Device) -> Result<Self, ModelError> {
        let info = CheckpointInfo::read(dir)?;
        if info.translation.is_some() {
            return Err(ModelError::checkpoint(
                &dir.join(CHECKPOINT_FILE),
                "translation: this is a translation model's checkpoint, not a rotation model's",
            ));
        }
        let mut model = ImplicitPdf::new(info.model.clone(), device)?;
        load_exact(model.var_store_mut(), &dir.join(&info.weights))?;
        Ok(model)
    }

    /// The models of the checkpoint in `dir`: its own, then those of the members its
    /// [`ENSEMBLE_FILE`] names, if it has one ([`crate::rotation::Predictor::ensemble`] scores
    /// them together). A member that is missing, unreadable, or reads other crops than the first
    /// (input size, rotation frame) is refused, naming the file.
    pub fn load_ensemble(dir: &Path, device: Device) -> Result<Vec<Self>, ModelError> {
        let first = ImplicitPdf::load(dir, device)?;
        let path = dir.join(ENSEMBLE_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(text) => text,
            Err(source) if source.kind() == std::io::ErrorKind::NotFound => {
                return Ok(vec![first]);
            }
            Err(source) => return Err(ModelError::Io { path, source }),
        };
        let info: EnsembleInfo = serde_json::from_str(&text)
            .map_err(|e| ModelError::checkpoint(&path, format!("members: {e}")))?;
        let mut models = vec![first];
        for member in &info.members {
            let model = ImplicitPdf::load(&dir.join(member), device)?;
            if let Some(difference) = member_mismatch(&models[0], &model) {
                return Err(ModelError::checkpoint(
                    &path,
                    format!("members: {member:?} {difference}"),
                ));
            }
            models.push(model);
        }
        Ok(models)
    }
}

impl Trainer {
    /// Writes the model, Adam's state, the options and the step as a checkpoint in `dir`.
    pub fn save(&self, dir: &Path) -> Result<(), ModelError> {
        let info = CheckpointInfo {
            model: self.model.config().clone(),
            training: Some(self.options.clone()),
            ..empty_info()
        };
        write_checkpoint(
            dir,
            self.model.var_store(),
            info,
            Some((&self.adam, self.step)),
        )
    }

    /// Continues the training saved in `dir` on `device`, at its step, with its options.
    pub fn resume(dir: &Path, device: Device) -> Result<Self, ModelError> {
        let info = CheckpointInfo::read(dir)?;
        let json = dir.join(CHECKPOINT_FILE);
        let (Some(options), Some(optimizer)) = (info.training.clone(), info.optimizer.clone())
        else {
            return Err(ModelError::checkpoint(
                &json,
                "training, optimizer: missing (saved without training state)",
            ));
        };
        let model = ImplicitPdf::load(dir, device)?;
        let mut trainer = Trainer::at_step(model, options, info.step)?;
        restore_adam(&mut trainer.adam, &dir.join(optimizer), device)?;
        Ok(trainer)
    }
}
