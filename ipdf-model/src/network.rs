//! The network both Implicit-PDFs are made of: the parameters, the image input (crop checks,
//! ImageNet normalisation, the encoder) and the head that sums an image term and a query term.
use tch::{Device, Kind, Tensor, nn};

use crate::encoder::Encoder;
use crate::head::Head;
use crate::layers::ParamInit;
use crate::{ModelConfig, ModelError};

/// The parameters of a model (`encoder.*` in torchvision names, `head.*`), its image input and
/// its head.
pub(crate) struct Network {
    var_store: nn::VarStore,
    images: ImageInput,
    head: Head,
}

impl Network {
    /// A freshly initialised network on `device` (weights from `config.seed`): the encoder of
    /// `config`, then a head whose image layer takes the encoder's features and
    /// `extra_image_features` more, and whose query layer takes `query_len` values.
    pub(crate) fn new(
        config: &ModelConfig,
        extra_image_features: i64,
        query_len: i64,
        device: Device,
    ) -> Self {
        let var_store = nn::VarStore::new(device);
        let mut init = ParamInit::new(config.seed);
        let root = var_store.root();
        let images = ImageInput::new(&root / "encoder", config, &mut init, device);
        let head = Head::new(
            &root / "head",
            images.feature_dim() + extra_image_features,
            query_len,
            &config.head_sizes,
            &mut init,
        );
        Self {
            var_store,
            images,
            head,
        }
    }

    /// The device holding the parameters.
    pub(crate) fn device(&self) -> Device {
        self.var_store.device()
    }

    /// The parameters' element kind.
    pub(crate) fn kind(&self) -> Kind {
        self.head.kind()
    }

    /// The head.
    pub(crate) fn head(&self) -> &Head {
        &self.head
    }

    /// The parameters.
    pub(crate) fn var_store(&self) -> &nn::VarStore {
        &self.var_store
    }

    /// The parameters, mutably.
    pub(crate) fn var_store_mut(&mut self) -> &mut nn::VarStore {
        &mut self.var_store
    }

    /// Checks that `images` is a float `[B, 3, S, S]` batch with `S` the configured input size.
    pub(crate) fn check_images(&self, images: &Tensor) -> Result<(), ModelError> {
        self.images.check(images)
    }

    /// The encoder's features `[B, D]` of crops `[B, 3, S, S]` in `[0, 1]`; `train` selects
    /// batch statistics in batch norm.
    pub(crate) fn features(&self, images: &Tensor, train: bool) -> Result<Tensor, ModelError> {
        self.images
            .features(images, self.kind(), self.device(), train)
    }

    /// Writes a model's `Debug` form: its name, configuration and device.
    pub(crate) fn debug(
        &self,
        f: &mut std::fmt::Formatter<'_>,
        name: &str,
        config: &dyn std::fmt::Debug,
    ) -> std::fmt::Result {
        f.debug_struct(name)
            .field("config", config)
            .field("device", &self.device())
            .finish_non_exhaustive()
    }
}

/// ImageNet channel means and standard deviations (torchvision's), applied to `[0, 1]` crops.
const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// The encoder of `[B, 3, S, S]` crops and the normalisation before it.
struct ImageInput {
    encoder: Encoder,
    input_size: i64,
    feature_dim: i64,
    mean: Tensor,
    std: Tensor,
}

impl ImageInput {
    /// The encoder of `config` under `path` (torchvision parameter names), on `device`.
    fn new(path: nn::Path, config: &ModelConfig, init: &mut ParamInit, device: Device) -> Self {
        let encoder = Encoder::new(path, config.encoder, config.frozen_blocks, init);
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
    fn feature_dim(&self) -> i64 {
        self.feature_dim
    }

    /// Checks that `images` is a float `[B, 3, S, S]` batch with `S` the configured input size.
    fn check(&self, images: &Tensor) -> Result<(), ModelError> {
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
    fn features(
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
