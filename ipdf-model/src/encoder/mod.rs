//! Image encoders: an RGB crop `[B, 3, S, S]` (ImageNet-normalised) to a feature `[B, D]`.
mod convnext;
mod efficientnet;
mod resnet;
mod small_cnn;

use serde::{Deserialize, Serialize};
use tch::{Tensor, nn};

use crate::layers::ParamInit;
use convnext::ConvNextTiny;
use efficientnet::EfficientNetLite0;
use resnet::{ResNet18, ResNetCut};
use small_cnn::SmallCnn;

/// Which image encoder a model uses. Parameter names follow torchvision, so the ResNet and
/// ConvNeXt weights of a torchvision checkpoint converted to `.safetensors` load directly
/// (see [`crate::load_backbone`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EncoderKind {
    /// ResNet-18 without its classifier: 512-d after global average pooling (the paper's).
    Resnet18,
    /// ResNet-18 cut after its third stage, flattened: `256 · ⌈S/16⌉²`-d, keeps spatial layout.
    #[serde(rename = "resnet18-2")]
    Resnet18Stage3,
    /// ConvNeXt-Tiny without its final linear layer: 768-d.
    ConvnextTiny,
    /// EfficientNet-Lite0 without its classifier: 1280-d; ImageNet weights in the
    /// `efficientnet_pytorch` names (`scripts/setup-pretrained.sh`) make it the pretrained CPU
    /// encoder (a tenth of ResNet-18's operations per crop).
    #[serde(rename = "efficientnet-lite0")]
    EfficientnetLite0,
    /// Four stride-2 3×3 convolutions (32–256 channels) and global pooling: 256-d; for quick
    /// CPU runs.
    SmallCnn,
    /// The small CNN with a stride-1 3×3 convolution added to each of its last two stages (six
    /// in all): 256-d, its last features see the whole of a 64-pixel crop; the quick mesh
    /// preset's.
    SmallCnnDeep,
}

impl EncoderKind {
    /// Every encoder, in the order of the command line's list.
    pub const ALL: [Self; 6] = [
        Self::Resnet18,
        Self::Resnet18Stage3,
        Self::ConvnextTiny,
        Self::EfficientnetLite0,
        Self::SmallCnn,
        Self::SmallCnnDeep,
    ];

    /// The command line's name: `resnet18`, `resnet18-2`, `convnext-tiny`,
    /// `efficientnet-lite0`, `small-cnn`, `small-cnn-deep`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Resnet18 => "resnet18",
            Self::Resnet18Stage3 => "resnet18-2",
            Self::ConvnextTiny => "convnext-tiny",
            Self::EfficientnetLite0 => "efficientnet-lite0",
            Self::SmallCnn => "small-cnn",
            Self::SmallCnnDeep => "small-cnn-deep",
        }
    }

    /// How many blocks of the encoder [`crate::ModelConfig::frozen_blocks`] may freeze:
    /// EfficientNet-Lite0's 16 MBConv blocks (with its stem); none of the others'.
    pub const fn freezable_blocks(self) -> usize {
        match self {
            Self::EfficientnetLite0 => efficientnet::BLOCKS,
            _ => 0,
        }
    }

    /// The encoder called `name` (see [`EncoderKind::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == name)
    }
}

impl std::fmt::Display for EncoderKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A built encoder.
#[derive(Debug)]
pub(crate) enum Encoder {
    ResNet(ResNet18),
    ConvNext(ConvNextTiny),
    EfficientNet(EfficientNetLite0),
    Small(SmallCnn),
}

impl Encoder {
    /// The encoder of `kind` with its first `frozen` blocks frozen (see
    /// [`crate::ModelConfig::frozen_blocks`]; the configuration's check keeps it in range).
    pub(crate) fn new(
        path: nn::Path,
        kind: EncoderKind,
        frozen: usize,
        init: &mut ParamInit,
    ) -> Self {
        match kind {
            EncoderKind::Resnet18 => Self::ResNet(ResNet18::new(path, ResNetCut::Pooled, init)),
            EncoderKind::Resnet18Stage3 => {
                Self::ResNet(ResNet18::new(path, ResNetCut::Stage3, init))
            }
            EncoderKind::ConvnextTiny => Self::ConvNext(ConvNextTiny::new(path, init)),
            EncoderKind::EfficientnetLite0 => {
                Self::EfficientNet(EfficientNetLite0::new(path, frozen, init))
            }
            EncoderKind::SmallCnn => Self::Small(SmallCnn::new(path, false, init)),
            EncoderKind::SmallCnnDeep => Self::Small(SmallCnn::new(path, true, init)),
        }
    }

    /// The feature length for `input_size × input_size` crops.
    pub(crate) fn feature_dim(&self, input_size: i64) -> i64 {
        match self {
            Self::ResNet(net) => net.feature_dim(input_size),
            Self::ConvNext(_) => ConvNextTiny::FEATURES,
            Self::EfficientNet(_) => EfficientNetLite0::FEATURES,
            Self::Small(_) => SmallCnn::FEATURES,
        }
    }

    /// `[B, 3, S, S]` → `[B, D]`.
    pub(crate) fn forward_t(&self, images: &Tensor, train: bool) -> Tensor {
        match self {
            Self::ResNet(net) => net.forward_t(images, train),
            Self::ConvNext(net) => net.forward(images),
            Self::EfficientNet(net) => net.forward_t(images, train),
            Self::Small(net) => net.forward_t(images, train),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_encoder_is_found_by_its_name_and_only_by_it() {
        for kind in EncoderKind::ALL {
            assert_eq!(EncoderKind::from_name(kind.name()), Some(kind));
            assert_eq!(EncoderKind::from_name(&kind.name().to_uppercase()), None);
        }
        assert_eq!(
            EncoderKind::from_name("efficientnet-lite0"),
            Some(EncoderKind::EfficientnetLite0)
        );
        assert_eq!(EncoderKind::from_name("resnet"), None);
    }
}
