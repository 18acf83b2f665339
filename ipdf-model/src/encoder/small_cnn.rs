//! Small CNNs for quick CPU runs: four stages of 3×3 convolutions with batch norm and ReLU
//! (32, 64, 128, 256 channels), each opened by a stride-2 convolution, then global average
//! pooling. The plain net has one convolution per stage; the deep one adds a stride-1
//! convolution to each of the last two stages, so that its last features see the whole of a
//! 64-pixel crop (a receptive field of 79 pixels against 31).
use tch::{Tensor, nn};

use crate::layers::{BatchNorm2d, Conv2d, ConvShape, ParamInit};

const CHANNELS: [i64; 5] = [3, 32, 64, 128, 256];

/// The first stage (0-based) that the deep net gives a second convolution. The first two
/// stages work on the largest maps: a second convolution there too doubled the training time
/// of the quick mesh preset, where the last two alone cost half as much again, and placed no
/// more real instances on a true pose (docs/experiments.md, "A deeper small CNN").
const DEEP_FROM_STAGE: usize = 2;

#[derive(Debug)]
pub(crate) struct SmallCnn {
    layers: Vec<(Conv2d, BatchNorm2d)>,
}

impl SmallCnn {
    pub(crate) const FEATURES: i64 = CHANNELS[4];

    /// `deep`: a second convolution in each of the last two stages (named `conv{i}b`,
    /// `bn{i}b`).
    pub(crate) fn new(path: nn::Path, deep: bool, init: &mut ParamInit) -> Self {
        let mut layers = Vec::new();
        for (i, pair) in CHANNELS.windows(2).enumerate() {
            let (input, output) = (pair[0], pair[1]);
            let mut layer = |name: String, shape: ConvShape| {
                let conv = Conv2d::new(&path / format!("conv{name}"), shape, init);
                layers.push((conv, BatchNorm2d::new(&path / format!("bn{name}"), output)));
            };
            layer(
                format!("{}", i + 1),
                ConvShape::plain(input, output, 3, 2, 1),
            );
            if deep && i >= DEEP_FROM_STAGE {
                layer(
                    format!("{}b", i + 1),
                    ConvShape::plain(output, output, 3, 1, 1),
                );
            }
        }
        Self { layers }
    }

    pub(crate) fn forward_t(&self, images: &Tensor, train: bool) -> Tensor {
        let mut xs = images.shallow_clone();
        for (conv, norm) in &self.layers {
            xs = norm.forward_t(&conv.forward(&xs), train).relu();
        }
        xs.adaptive_avg_pool2d([1, 1]).flatten(1, -1)
    }
}
