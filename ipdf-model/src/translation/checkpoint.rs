//! Saving and loading translation models and their training state (see
//! [`crate::CheckpointInfo`]).
use std::path::Path;

use tch::Device;

use super::{TranslationConfig, TranslationPdf, TranslationTrainOptions, TranslationTrainer};
use crate::ModelError;
use crate::checkpoint::{
    CHECKPOINT_FILE, CheckpointInfo, empty_info, load_exact, restore_adam, write_checkpoint,
};

impl TranslationPdf {
    /// Writes the model as a checkpoint in `dir` (created if missing), with no training state.
    pub fn save(&self, dir: &Path) -> Result<(), ModelError> {
        write_checkpoint(dir, self.var_store(), translation_info(self, None), None)
    }

    /// The translation model of the checkpoint in `dir`, on `device`; a rotation model's
    /// checkpoint is refused.
    pub fn load(dir: &Path, device: Device) -> Result<Self, ModelError> {
        let info = CheckpointInfo::read(dir)?;
        let Some(space) = info.translation else {
            return Err(ModelError::checkpoint(
                &dir.join(CHECKPOINT_FILE),
                "translation: missing (a rotation model's checkpoint, not a translation model's)",
            ));
        };
        let config = TranslationConfig {
            network: info.model.clone(),
            space,
        };
        let mut model = TranslationPdf::new(config, device)?;
        load_exact(model.var_store_mut(), &dir.join(&info.weights))?;
        Ok(model)
    }
}

fn translation_info(
    model: &TranslationPdf,
    training: Option<&TranslationTrainOptions>,
) -> CheckpointInfo {
    CheckpointInfo {
        model: model.config().network.clone(),
        translation: Some(model.config().space),
        translation_training: training.cloned(),
        ..empty_info()
    }
}

impl TranslationTrainer {
    /// Writes the model, Adam's state, the options and the step as a checkpoint in `dir`.
    pub fn save(&self, dir: &Path) -> Result<(), ModelError> {
        write_checkpoint(
            dir,
            self.model().var_store(),
            translation_info(self.model(), Some(self.options())),
            Some((self.adam(), self.step())),
        )
    }

    /// Continues the training saved in `dir` on `device`, at its step, with its options.
    pub fn resume(dir: &Path, device: Device) -> Result<Self, ModelError> {
        let info = CheckpointInfo::read(dir)?;
        let json = dir.join(CHECKPOINT_FILE);
        let (Some(options), Some(optimizer)) =
            (info.translation_training.clone(), info.optimizer.clone())
        else {
            return Err(ModelError::checkpoint(
                &json,
                "translation_training, optimizer: missing (saved without training state)",
            ));
        };
        let model = TranslationPdf::load(dir, device)?;
        let mut trainer = TranslationTrainer::at_step(model, options, info.step)?;
        restore_adam(trainer.adam_mut(), &dir.join(optimizer), device)?;
        Ok(trainer)
    }
}
