//! Pretrained backbone weights from a `.safetensors` file with torchvision's parameter names.
use std::path::Path;

use tch::nn;

use crate::checkpoint::{copy_checked, read_tensors};
use crate::rotation::ImplicitPdf;
use crate::translation::TranslationPdf;
use crate::{EncoderKind, ModelError};

/// Loads the encoder's weights (and batch-norm statistics) from `path`, a `.safetensors` file
/// of a torchvision model's `state_dict` (e.g. `resnet18` or `convnext_tiny`; names such as
/// `layer1.0.conv1.weight`, optionally prefixed with `encoder.`). Tensors the encoder does not
/// have (`fc.*`, `classifier.2.*`, `num_batches_tracked`) are ignored; a missing or misshapen
/// encoder tensor is an error naming it. Returns the number of tensors loaded.
///
/// Convert a torchvision model once with
/// `safetensors.torch.save_file(torchvision.models.resnet18(weights="DEFAULT").state_dict(), "resnet18.safetensors")`.
pub fn load_backbone(model: &mut ImplicitPdf, path: &Path) -> Result<usize, ModelError> {
    let encoder = model.config().encoder;
    load_encoder(model.var_store_mut(), encoder, path)
}

/// [`load_backbone`] for a translation model.
pub fn load_translation_backbone(
    model: &mut TranslationPdf,
    path: &Path,
) -> Result<usize, ModelError> {
    let encoder = model.config().network.encoder;
    load_encoder(model.var_store_mut(), encoder, path)
}

fn load_encoder(
    var_store: &mut nn::VarStore,
    encoder: EncoderKind,
    path: &Path,
) -> Result<usize, ModelError> {
    let mut saved = read_tensors(path, var_store.device())?;
    let mut variables: Vec<(String, tch::Tensor)> = var_store
        .variables()
        .into_iter()
        .filter_map(|(name, tensor)| {
            name.strip_prefix("encoder.")
                .map(|short| (short.to_string(), tensor))
        })
        .collect();
    variables.sort_by(|a, b| a.0.cmp(&b.0));
    for (name, variable) in &mut variables {
        let tensor = saved
            .remove(name.as_str())
            .or_else(|| saved.remove(&format!("encoder.{name}")))
            .ok_or_else(|| {
                ModelError::checkpoint(
                    path,
                    format!("{name}: missing (the file holds no {encoder} weights)"),
                )
            })?;
        copy_checked(variable, &tensor, name, path)?;
    }
    Ok(variables.len())
}
