//! The image side shared by the rotation and translation models: crop checks, ImageNet
//! normalisation and the encoder.
use tch::{Device, Kind, Tensor, nn};

use crate::ModelError;
use crate::encoder::Encoder;
use crate::layers::ParamInit;
use crate::model::ModelConfig;

/// ImageNet channel means and standard deviations (torchvision's), applied to `[0, 1]` crops.
const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// The encoder of `[B, 3, S, S]` crops and the normalisation before it.
pub(crate) struct ImageInput {
    encoder: Encoder,
    input_size: i64,
    feature_dim: i64,
    mean: Tensor,
    std: Tensor,
}

impl ImageInput {
    /// The encoder of `config` under `path` (torchvision parameter names), on `device`.
    pub(crate) fn new(
        path: nn::Path,
        config: &ModelConfig,
        init: &mut ParamInit,
        device: Device,
    ) -> Self {
        let encoder = Encoder::new(path, config.encoder, init);
        let feature_dim = encoder.feature_dim(config.input_size);
        let mean = Tensor::from_slice(&IMAGENET_MEAN)
            .reshape([1, 3, 1, 1])
            .to_device(device);
        let std = Tensor::from_slice(&IMAGENET_STD)
            .reshape([1, 3, 1, 1])
            .to_device(device);
        Self {
            encoder,
            input_size: config.input_size,
            feature_dim,
            mean,
            std,
        }
    }

    /// The length of one image's feature vector.
    pub(crate) fn feature_dim(&self) -> i64 {
        self.feature_dim
    }

    /// Checks that `images` is a float `[B, 3, S, S]` batch with `S` the configured input size.
    pub(crate) fn check(&self, images: &Tensor) -> Result<(), ModelError> {
        let size = images.size();
        let s = self.input_size;
        if size.len() != 4 || size[1] != 3 || size[2] != s || size[3] != s || size[0] == 0 {
            return Err(ModelError::ImageShape {
                field: "images",
                expected: format!("[B ≥ 1, 3, {s}, {s}]"),
                got: format!("{size:?}"),
            });
        }
        if !matches!(images.kind(), Kind::Float | Kind::Double) {
            return Err(ModelError::ImageShape {
                field: "images",
                expected: "float values in [0, 1]".into(),
                got: format!("{:?}", images.kind()),
            });
        }
        Ok(())
    }

    /// Features `[B, D]` of crops `[B, 3, S, S]` with values in `[0, 1]`, computed in `kind` on
    /// `device`; `train` selects batch statistics in batch norm.
    pub(crate) fn features(
        &self,
        images: &Tensor,
        kind: Kind,
        device: Device,
        train: bool,
    ) -> Result<Tensor, ModelError> {
        self.check(images)?;
        let images = images.to_device(device).to_kind(kind);
        let normalised = (images - self.mean.to_kind(kind)) / self.std.to_kind(kind);
        Ok(self.encoder.forward_t(&normalised, train))
    }
}
