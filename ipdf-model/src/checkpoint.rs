//! Checkpoints: a folder with `checkpoint.json` (configuration, training options, step, and
//! the names of the tensor files), `model-<step>.safetensors` and, while training,
//! `optimizer-<step>.safetensors` (Adam's moments). Tensor files are written under a temporary
//! name (`.NAME.partial`, reused by the next write of the same file) and renamed;
//! `checkpoint.json` is renamed last, so a killed write leaves the previous checkpoint intact. Files of older steps are removed after the new JSON is in place.
use std::collections::HashMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use tch::{Device, Tensor, nn};

use crate::optim::Adam;
use crate::rotation::TrainOptions;
use crate::translation::{TranslationSpace, TranslationTrainOptions};
use crate::{ModelConfig, ModelError};

/// The name of a checkpoint's JSON file.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
const FORMAT: &str = "ipdf-rs checkpoint 1";

/// The contents of `checkpoint.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointInfo {
    /// Format tag, `"ipdf-rs checkpoint 1"`.
    pub format: String,
    /// The model's configuration.
    pub model: ModelConfig,
    /// The working volume and query normalisation of a translation model
    /// ([`crate::translation::TranslationPdf`]); absent for a rotation model
    /// ([`crate::rotation::ImplicitPdf`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<TranslationSpace>,
    /// Training options of a rotation model, when saved by a trainer.
    pub training: Option<TrainOptions>,
    /// Training options of a translation model, when saved by a trainer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation_training: Option<TranslationTrainOptions>,
    /// Training steps done.
    pub step: u64,
    /// The weights file, relative to the folder.
    pub weights: String,
    /// Adam's state file, relative to the folder, when saved by a trainer.
    pub optimizer: Option<String>,
}

impl CheckpointInfo {
    /// Reads `dir/checkpoint.json`.
    pub fn read(dir: &Path) -> Result<Self, ModelError> {
        let path = dir.join(CHECKPOINT_FILE);
        let text = std::fs::read_to_string(&path).map_err(|source| ModelError::Io {
            path: path.clone(),
            source,
        })?;
        let info: Self = serde_json::from_str(&text)
            .map_err(|e| ModelError::checkpoint(&path, format!("not a checkpoint: {e}")))?;
        if info.format != FORMAT {
            return Err(ModelError::checkpoint(
                &path,
                format!("format: {:?}, expected {FORMAT:?}", info.format),
            ));
        }
        Ok(info)
    }
}

/// A rotation model's info with no files or step yet.
pub(crate) fn empty_info() -> CheckpointInfo {
    CheckpointInfo {
        format: FORMAT.into(),
        model: ModelConfig::default(),
        translation: None,
        training: None,
        translation_training: None,
        step: 0,
        weights: String::new(),
        optimizer: None,
    }
}

/// Writes `var_store` (and Adam's state at a step) as `model-<step>.safetensors` (and
/// `optimizer-<step>.safetensors`), then `info` with those names and the step as
/// `checkpoint.json`, then removes the files of other steps.
pub(crate) fn write_checkpoint(
    dir: &Path,
    var_store: &nn::VarStore,
    mut info: CheckpointInfo,
    training: Option<(&Adam, u64)>,
) -> Result<(), ModelError> {
    std::fs::create_dir_all(dir).map_err(|source| ModelError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let step = training.map_or(0, |(_, step)| step);
    let weights = format!("model-{step:08}.safetensors");
    write_tensors(&dir.join(&weights), &named_variables(var_store))?;
    let optimizer = match training {
        Some((adam, _)) => {
            let name = format!("optimizer-{step:08}.safetensors");
            write_tensors(&dir.join(&name), &adam.state())?;
            Some(name)
        }
        None => None,
    };
    info.step = step;
    info.weights.clone_from(&weights);
    info.optimizer.clone_from(&optimizer);
    let json = dir.join(CHECKPOINT_FILE);
    let text = serde_json::to_string_pretty(&info)
        .map_err(|e| ModelError::checkpoint(&json, e.to_string()))?;
    write_text_atomically(&json, &text)?;
    remove_stale(dir, &[weights, optimizer.unwrap_or_default()]);
    Ok(())
}

/// Removes tensor files of other steps (best effort: a leftover file is harmless).
fn remove_stale(dir: &Path, keep: &[String]) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let ours = (name.starts_with("model-") || name.starts_with("optimizer-"))
            && name.ends_with(".safetensors");
        if ours && !keep.contains(&name) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The variables in name order, on the CPU.
fn named_variables(var_store: &nn::VarStore) -> Vec<(String, Tensor)> {
    let mut named: Vec<(String, Tensor)> = var_store.variables().into_iter().collect();
    named.sort_by(|a, b| a.0.cmp(&b.0));
    named
}

fn write_tensors(path: &Path, named: &[(String, Tensor)]) -> Result<(), ModelError> {
    write_then_rename(path, |tmp| {
        Tensor::write_safetensors(named, tmp)
            .map_err(|e| ModelError::checkpoint(tmp, e.to_string()))
    })
}

/// Writes `text` to `path` through [`write_then_rename`].
pub(crate) fn write_text_atomically(path: &Path, text: &str) -> Result<(), ModelError> {
    write_then_rename(path, |tmp| {
        std::fs::write(tmp, text.as_bytes()).map_err(|source| ModelError::Io {
            path: tmp.to_path_buf(),
            source,
        })
    })
}

/// Runs `write` on the hidden sibling `.NAME.partial` of `path`, then renames it to `path`: the
/// crate's one atomic write. A sibling left by a killed writer is overwritten by the next write
/// of the same file (a resumed run writes the same step's files again); one left by a failed
/// `write` is removed. The same naming as the dataset crates' writer.
fn write_then_rename(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), ModelError>,
) -> Result<(), ModelError> {
    let Some(name) = path.file_name() else {
        return Err(ModelError::checkpoint(path, "not a file path"));
    };
    let mut partial = std::ffi::OsString::from(".");
    partial.push(name);
    partial.push(".partial");
    let partial = path.with_file_name(partial);
    let renamed = write(&partial).and_then(|()| {
        std::fs::rename(&partial, path).map_err(|source| ModelError::Io {
            path: path.to_path_buf(),
            source,
        })
    });
    if renamed.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    renamed
}

/// The tensors of a `.safetensors` file, by name, on `device`.
pub(crate) fn read_tensors(
    path: &Path,
    device: Device,
) -> Result<HashMap<String, Tensor>, ModelError> {
    if !path.is_file() {
        return Err(ModelError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    let named = Tensor::read_safetensors(path)
        .map_err(|e| ModelError::checkpoint(path, format!("unreadable safetensors: {e}")))?;
    Ok(named
        .into_iter()
        .map(|(name, tensor)| (name, tensor.to_device(device)))
        .collect())
}

/// Loads every variable of `var_store` from `path`, which must hold exactly those names and
/// shapes.
pub(crate) fn load_exact(var_store: &mut nn::VarStore, path: &Path) -> Result<(), ModelError> {
    let mut saved = read_tensors(path, var_store.device())?;
    for (name, mut variable) in named_variables(var_store) {
        let tensor = saved
            .remove(&name)
            .ok_or_else(|| ModelError::checkpoint(path, format!("{name}: missing")))?;
        copy_checked(&mut variable, &tensor, &name, path)?;
    }
    if let Some(extra) = saved.keys().min() {
        return Err(ModelError::checkpoint(
            path,
            format!("{extra}: not a parameter of this model (another configuration?)"),
        ));
    }
    Ok(())
}

/// Restores Adam's state from the `.safetensors` file at `path`, on `device`.
pub(crate) fn restore_adam(adam: &mut Adam, path: &Path, device: Device) -> Result<(), ModelError> {
    let saved = read_tensors(path, device)?;
    adam.load_state(saved)
        .map_err(|reason| ModelError::checkpoint(path, reason))
}

/// Copies `source` into `target` after checking the shape.
pub(crate) fn copy_checked(
    target: &mut Tensor,
    source: &Tensor,
    name: &str,
    path: &Path,
) -> Result<(), ModelError> {
    if source.size() != target.size() {
        return Err(ModelError::checkpoint(
            path,
            format!(
                "{name}: shape {:?}, the model has {:?}",
                source.size(),
                target.size()
            ),
        ));
    }
    tch::no_grad(|| target.f_copy_(&source.to_kind(target.kind())))?;
    Ok(())
}
