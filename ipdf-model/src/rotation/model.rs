//! The rotation model: `F(R, I)` from a crop and a rotation query.
use tch::{Device, Kind, Tensor, nn};

use crate::encoding::{encode_rotations, encoded_len};
use crate::head::Head;
use crate::network::Network;
use crate::{ModelConfig, ModelError};

/// An Implicit-PDF model: `F(R, I)`, the unnormalised log-density of rotation `R` given image
/// `I`, with `p(R | I) = exp F(R, I) / ∫ exp F(R', I) dR'` (Murphy et al. 2021, eq. 1–2).
pub struct ImplicitPdf {
    network: Network,
    config: ModelConfig,
}

impl std::fmt::Debug for ImplicitPdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.network.debug(f, "ImplicitPdf", &self.config)
    }
}

impl ImplicitPdf {
    /// A freshly initialised model on `device`; its weights depend only on `config.seed`.
    pub fn new(config: ModelConfig, device: Device) -> Result<Self, ModelError> {
        config.validate()?;
        let query_len = encoded_len(config.fourier_components);
        let network = Network::new(&config, 0, query_len, device);
        Ok(Self { network, config })
    }

    /// The configuration the model was built from.
    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// The device holding the parameters.
    pub fn device(&self) -> Device {
        self.network.device()
    }

    /// The parameters' element kind (`Float` unless converted, e.g. by `VarStore::double`).
    pub fn kind(&self) -> Kind {
        self.network.kind()
    }

    /// The head, for inference copies in another precision.
    pub(crate) fn head(&self) -> &Head {
        self.network.head()
    }

    /// The parameters, named as in torchvision under `encoder.` and as `head.*`.
    pub fn var_store(&self) -> &nn::VarStore {
        self.network.var_store()
    }

    /// The parameters, mutably (to load weights or change their kind).
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        self.network.var_store_mut()
    }

    /// Checks that `images` is a float `[B, 3, S, S]` batch with `S` the configured input size.
    pub fn check_images(&self, images: &Tensor) -> Result<(), ModelError> {
        self.network.check_images(images)
    }

    /// The image term of the head, `[B, H]`, for crops `[B, 3, S, S]` with values in `[0, 1]`
    /// (the encoder, then the head's image layer). Computed once per image and broadcast over
    /// all queries. `train` selects batch statistics in batch norm.
    pub fn image_term(&self, images: &Tensor, train: bool) -> Result<Tensor, ModelError> {
        let features = self.network.features(images, train)?;
        Ok(self.network.head().image_term(&features))
    }

    /// The query term of the head, `[…, H]`, for row-major rotation matrices `[…, 9]` (the
    /// positional encoding, then the head's query layer). For a fixed grid it can be computed
    /// once and reused across images.
    pub fn query_term(&self, rotations: &Tensor) -> Tensor {
        let kind = self.kind();
        let encoded = encode_rotations(&rotations.to_kind(kind), self.config.fourier_components);
        self.network.head().query_term(&encoded)
    }

    /// `F(R, I)` for broadcastable terms: image `[B, 1, H]` with queries `[B, N, H]` gives
    /// `[B, N]`; image `[1, H]` with queries `[N, H]` gives `[N]`.
    pub fn scores(&self, image_term: &Tensor, query_term: &Tensor) -> Tensor {
        self.network.head().scores(image_term, query_term)
    }
}
