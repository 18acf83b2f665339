//! The model: configuration, parameters, and `F(R, I)`.
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor, nn};

use crate::ModelError;
use crate::encoder::{Encoder, EncoderKind};
use crate::encoding::{encode_rotations, encoded_len};
use crate::head::Head;
use crate::layers::ParamInit;

/// ImageNet channel means and standard deviations (torchvision's), applied to `[0, 1]` crops.
const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// Everything that fixes a model's shape and initial weights; stored in every checkpoint.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelConfig {
    /// The image encoder.
    pub encoder: EncoderKind,
    /// Side of the square RGB crop, in pixels (224 in the paper).
    pub input_size: i64,
    /// Positional-encoding frequencies `F` of the rotation query (0: the raw matrix).
    pub fourier_components: i64,
    /// Widths of the head: the first is the summed image + query layer, then one ReLU layer
    /// per further entry.
    pub head_sizes: Vec<i64>,
    /// Seed of the initial weights.
    pub seed: u64,
}

impl Default for ModelConfig {
    /// The paper's model: ResNet-18, 224 px, F = 3, head 4 × 256.
    fn default() -> Self {
        Self {
            encoder: EncoderKind::Resnet18,
            input_size: 224,
            fourier_components: 3,
            head_sizes: vec![256; 4],
            seed: 0,
        }
    }
}

impl ModelConfig {
    /// A small configuration for quick CPU runs and tests: small CNN, `input_size` px, F = 3,
    /// head 2 × 128.
    pub fn small(input_size: i64) -> Self {
        Self {
            encoder: EncoderKind::SmallCnn,
            input_size,
            head_sizes: vec![128; 2],
            ..Self::default()
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), ModelError> {
        let minimum_size = match self.encoder {
            EncoderKind::ConvnextTiny => 32,
            _ => 16,
        };
        if !(minimum_size..=1024).contains(&self.input_size) {
            return Err(ModelError::option(
                "input_size",
                format!(
                    "{} px is outside {minimum_size}..=1024 for {}",
                    self.input_size, self.encoder
                ),
            ));
        }
        if !(0..=10).contains(&self.fourier_components) {
            return Err(ModelError::option(
                "fourier_components",
                format!("{} is outside 0..=10", self.fourier_components),
            ));
        }
        if self.head_sizes.is_empty() || self.head_sizes.iter().any(|&w| !(1..=8192).contains(&w)) {
            return Err(ModelError::option(
                "head_sizes",
                format!("{:?}: need one or more widths in 1..=8192", self.head_sizes),
            ));
        }
        Ok(())
    }
}

/// An Implicit-PDF model: `F(R, I)`, the unnormalised log-density of rotation `R` given image
/// `I`, with `p(R | I) = exp F(R, I) / ∫ exp F(R', I) dR'` (Murphy et al. 2021, eq. 1–2).
pub struct ImplicitPdf {
    var_store: nn::VarStore,
    config: ModelConfig,
    encoder: Encoder,
    head: Head,
    mean: Tensor,
    std: Tensor,
}

impl std::fmt::Debug for ImplicitPdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitPdf")
            .field("config", &self.config)
            .field("device", &self.var_store.device())
            .finish_non_exhaustive()
    }
}

impl ImplicitPdf {
    /// A freshly initialised model on `device`; its weights depend only on `config.seed`.
    pub fn new(config: ModelConfig, device: Device) -> Result<Self, ModelError> {
        config.validate()?;
        let var_store = nn::VarStore::new(device);
        let mut init = ParamInit::new(config.seed);
        let root = var_store.root();
        let encoder = Encoder::new(&root / "encoder", config.encoder, &mut init);
        let feature_dim = encoder.feature_dim(config.input_size);
        let head = Head::new(
            &root / "head",
            feature_dim,
            encoded_len(config.fourier_components),
            &config.head_sizes,
            &mut init,
        );
        let mean = Tensor::from_slice(&IMAGENET_MEAN)
            .reshape([1, 3, 1, 1])
            .to_device(device);
        let std = Tensor::from_slice(&IMAGENET_STD)
            .reshape([1, 3, 1, 1])
            .to_device(device);
        Ok(Self {
            var_store,
            config,
            encoder,
            head,
            mean,
            std,
        })
    }

    /// The configuration the model was built from.
    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// The device holding the parameters.
    pub fn device(&self) -> Device {
        self.var_store.device()
    }

    /// The parameters' element kind (`Float` unless converted, e.g. by `VarStore::double`).
    pub fn kind(&self) -> Kind {
        self.head.kind()
    }

    /// The head, for inference copies in another precision.
    pub(crate) fn head(&self) -> &Head {
        &self.head
    }

    /// The parameters, named as in torchvision under `encoder.` and as `head.*`.
    pub fn var_store(&self) -> &nn::VarStore {
        &self.var_store
    }

    /// The parameters, mutably (to load weights or change their kind).
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        &mut self.var_store
    }

    /// Checks that `images` is a float `[B, 3, S, S]` batch with `S` the configured input size.
    pub fn check_images(&self, images: &Tensor) -> Result<(), ModelError> {
        let size = images.size();
        let s = self.config.input_size;
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

    /// The image term of the head, `[B, H]`, for crops `[B, 3, S, S]` with values in `[0, 1]`
    /// (the encoder, then the head's image layer). Computed once per image and broadcast over
    /// all queries. `train` selects batch statistics in batch norm.
    pub fn image_term(&self, images: &Tensor, train: bool) -> Result<Tensor, ModelError> {
        self.check_images(images)?;
        let kind = self.kind();
        let images = images.to_device(self.device()).to_kind(kind);
        let normalised = (images - self.mean.to_kind(kind)) / self.std.to_kind(kind);
        let features = self.encoder.forward_t(&normalised, train);
        Ok(self.head.image_term(&features))
    }

    /// The query term of the head, `[…, H]`, for row-major rotation matrices `[…, 9]` (the
    /// positional encoding, then the head's query layer). For a fixed grid it can be computed
    /// once and reused across images.
    pub fn query_term(&self, rotations: &Tensor) -> Tensor {
        let kind = self.kind();
        let encoded = encode_rotations(&rotations.to_kind(kind), self.config.fourier_components);
        self.head.query_term(&encoded)
    }

    /// `F(R, I)` for broadcastable terms: image `[B, 1, H]` with queries `[B, N, H]` gives
    /// `[B, N]`; image `[1, H]` with queries `[N, H]` gives `[N]`.
    pub fn scores(&self, image_term: &Tensor, query_term: &Tensor) -> Tensor {
        self.head.scores(image_term, query_term)
    }
}
