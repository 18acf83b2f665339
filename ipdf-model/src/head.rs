//! The Implicit-PDF head (Murphy et al. 2021, §3.4): `F(R, I)` from an image feature and an
//! encoded rotation.
use tch::{Tensor, nn};

use crate::layers::{Linear, ParamInit};

/// One linear layer on the image feature and one on the encoded query, summed, ReLU, then
/// `head_sizes[1..]` ReLU layers, then one output (`head_sizes[0]` is the width of the sum, as
/// `mlp_layer_sizes` in the reference implementation).
#[derive(Debug)]
pub(crate) struct Head {
    image: Linear,
    query: Linear,
    hidden: Vec<Linear>,
    output: Linear,
}

impl Head {
    pub(crate) fn new(
        path: nn::Path,
        feature_dim: i64,
        query_dim: i64,
        sizes: &[i64],
        init: &mut ParamInit,
    ) -> Self {
        let first = sizes[0];
        let image = Linear::new(&path / "image", feature_dim, first, init);
        let query = Linear::new(&path / "query", query_dim, first, init);
        let hidden = sizes
            .windows(2)
            .enumerate()
            .map(|(i, pair)| Linear::new(&path / "hidden" / i, pair[0], pair[1], init))
            .collect();
        let output = Linear::new(&path / "output", sizes[sizes.len() - 1], 1, init);
        Self {
            image,
            query,
            hidden,
            output,
        }
    }

    /// The parameters' element kind.
    pub(crate) fn kind(&self) -> tch::Kind {
        self.output.kind()
    }

    /// A detached copy of the head with parameters of element kind `kind` (for inference).
    pub(crate) fn to_kind(&self, kind: tch::Kind) -> Self {
        Self {
            image: self.image.to_kind(kind),
            query: self.query.to_kind(kind),
            hidden: self
                .hidden
                .iter()
                .map(|layer| layer.to_kind(kind))
                .collect(),
            output: self.output.to_kind(kind),
        }
    }

    /// The image term `[B, H]` from features `[B, D]`.
    pub(crate) fn image_term(&self, features: &Tensor) -> Tensor {
        self.image.forward(features)
    }

    /// The query term `[…, H]` from encoded rotations `[…, E]`.
    pub(crate) fn query_term(&self, encoded: &Tensor) -> Tensor {
        self.query.forward(encoded)
    }

    /// `F` for broadcastable image and query terms (`[B, 1, H]` and `[B, N, H]` or `[N, H]`):
    /// the trailing dimension is consumed.
    pub(crate) fn scores(&self, image_term: &Tensor, query_term: &Tensor) -> Tensor {
        let mut xs = (image_term + query_term).relu();
        for layer in &self.hidden {
            xs = layer.forward(&xs).relu_();
        }
        self.output.forward(&xs).squeeze_dim(-1)
    }
}
