//! A small CNN for quick CPU runs: four stride-2 3×3 convolutions with batch norm and ReLU
//! (32, 64, 128, 256 channels), then global average pooling.
use tch::{Tensor, nn};

use crate::layers::{BatchNorm2d, Conv2d, ConvShape, ParamInit};

const CHANNELS: [i64; 5] = [3, 32, 64, 128, 256];

#[derive(Debug)]
pub(crate) struct SmallCnn {
    stages: Vec<(Conv2d, BatchNorm2d)>,
}

impl SmallCnn {
    pub(crate) const FEATURES: i64 = CHANNELS[4];

    pub(crate) fn new(path: nn::Path, init: &mut ParamInit) -> Self {
        let stages = CHANNELS
            .windows(2)
            .enumerate()
            .map(|(i, pair)| {
                let conv = Conv2d::new(
                    &path / format!("conv{}", i + 1),
                    ConvShape::plain(pair[0], pair[1], 3, 2, 1),
                    init,
                );
                let norm = BatchNorm2d::new(&path / format!("bn{}", i + 1), pair[1]);
                (conv, norm)
            })
            .collect();
        Self { stages }
    }

    pub(crate) fn forward_t(&self, images: &Tensor, train: bool) -> Tensor {
        let mut xs = images.shallow_clone();
        for (conv, norm) in &self.stages {
            xs = norm.forward_t(&conv.forward(&xs), train).relu();
        }
        xs.adaptive_avg_pool2d([1, 1]).flatten(1, -1)
    }
}
