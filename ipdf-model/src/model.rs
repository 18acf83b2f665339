//! The model: configuration, parameters, and `F(R, I)`.
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor, nn};

use crate::ModelError;
use crate::encoder::EncoderKind;
use crate::encoding::{encode_rotations, encoded_len};
use crate::head::Head;
use crate::image_input::ImageInput;
use crate::layers::ParamInit;

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
    images: ImageInput,
    head: Head,
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
        let images = ImageInput::new(&root / "encoder", &config, &mut init, device);
        let head = Head::new(
            &root / "head",
            images.feature_dim(),
            encoded_len(config.fourier_components),
            &config.head_sizes,
            &mut init,
        );
        Ok(Self {
            var_store,
            config,
            images,
            head,
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
        self.images.check(images)
    }

    /// The image term of the head, `[B, H]`, for crops `[B, 3, S, S]` with values in `[0, 1]`
    /// (the encoder, then the head's image layer). Computed once per image and broadcast over
    /// all queries. `train` selects batch statistics in batch norm.
    pub fn image_term(&self, images: &Tensor, train: bool) -> Result<Tensor, ModelError> {
        let features = self
            .images
            .features(images, self.kind(), self.device(), train)?;
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
