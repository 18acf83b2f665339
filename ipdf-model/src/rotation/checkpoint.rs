//! Saving and loading rotation models and their training state (see [`crate::CheckpointInfo`]).
use std::path::Path;

use tch::Device;

use super::{ImplicitPdf, Trainer};
use crate::ModelError;
use crate::checkpoint::{
    CHECKPOINT_FILE, CheckpointInfo, empty_info, load_exact, restore_adam, write_checkpoint,
};

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
