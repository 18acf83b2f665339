//! ConvNeXt-Tiny (Liu et al. 2022) with torchvision's parameter names (`features.0.0`,
//! `features.1.0.block.0`, `features.1.0.layer_scale`, `classifier.0`, …), ending with the
//! classifier's layer norm: 768-d. Stochastic depth is left out (identity at inference).
use tch::{Tensor, nn};

use crate::layers::{Conv2d, ConvShape, LayerNorm, Linear, ParamInit, constant};

const DIMS: [i64; 4] = [96, 192, 384, 768];
const DEPTHS: [usize; 4] = [3, 3, 9, 3];

#[derive(Debug)]
struct Block {
    depthwise: Conv2d,
    norm: LayerNorm,
    expand: Linear,
    project: Linear,
    layer_scale: Tensor,
}

impl Block {
    fn new(path: nn::Path, dim: i64, init: &mut ParamInit) -> Self {
        let block = &path / "block";
        Self {
            depthwise: Conv2d::new(
                &block / "0",
                ConvShape {
                    input: dim,
                    output: dim,
                    kernel: 7,
                    stride: 1,
                    padding: 3,
                    groups: dim,
                    bias: true,
                },
                init,
            ),
            norm: LayerNorm::new(&block / "2", dim),
            expand: Linear::new(&block / "3", dim, 4 * dim, init),
            project: Linear::new(&block / "5", 4 * dim, dim, init),
            layer_scale: constant(&path, "layer_scale", &[dim, 1, 1], 1e-6),
        }
    }

    fn forward(&self, xs: &Tensor) -> Tensor {
        let ys = self.depthwise.forward(xs).permute([0, 2, 3, 1]);
        let ys = self
            .project
            .forward(&self.expand.forward(&self.norm.forward(&ys)).gelu("none"))
            .permute([0, 3, 1, 2]);
        xs + &self.layer_scale * ys
    }
}

/// A stem (4×4 patchify) or a downsampling step (norm, then 2×2 stride-2 convolution).
#[derive(Debug)]
enum Transition {
    Stem(Conv2d, LayerNorm),
    Downsample(LayerNorm, Conv2d),
}

#[derive(Debug)]
pub(crate) struct ConvNextTiny {
    stages: Vec<(Transition, Vec<Block>)>,
    head_norm: LayerNorm,
}

impl ConvNextTiny {
    pub(crate) const FEATURES: i64 = DIMS[3];

    pub(crate) fn new(path: nn::Path, init: &mut ParamInit) -> Self {
        let features = &path / "features";
        let mut stages = Vec::with_capacity(4);
        for (stage, (&dim, &depth)) in DIMS.iter().zip(&DEPTHS).enumerate() {
            let transition_path = &features / (2 * stage);
            let transition = if stage == 0 {
                let conv = Conv2d::new(
                    &transition_path / "0",
                    ConvShape {
                        bias: true,
                        ..ConvShape::plain(3, dim, 4, 4, 0)
                    },
                    init,
                );
                Transition::Stem(conv, LayerNorm::new(&transition_path / "1", dim))
            } else {
                let previous = DIMS[stage - 1];
                let norm = LayerNorm::new(&transition_path / "0", previous);
                let conv = Conv2d::new(
                    &transition_path / "1",
                    ConvShape {
                        bias: true,
                        ..ConvShape::plain(previous, dim, 2, 2, 0)
                    },
                    init,
                );
                Transition::Downsample(norm, conv)
            };
            let blocks_path = &features / (2 * stage + 1);
            let blocks = (0..depth)
                .map(|i| Block::new(&blocks_path / i, dim, init))
                .collect();
            stages.push((transition, blocks));
        }
        let head_norm = LayerNorm::new(&path / "classifier" / "0", Self::FEATURES);
        Self { stages, head_norm }
    }

    pub(crate) fn forward(&self, images: &Tensor) -> Tensor {
        let mut xs = images.shallow_clone();
        for (transition, blocks) in &self.stages {
            xs = match transition {
                Transition::Stem(conv, norm) => norm.forward_channels_first(&conv.forward(&xs)),
                Transition::Downsample(norm, conv) => {
                    conv.forward(&norm.forward_channels_first(&xs))
                }
            };
            for block in blocks {
                xs = block.forward(&xs);
            }
        }
        let pooled = xs.adaptive_avg_pool2d([1, 1]).flatten(1, -1);
        self.head_norm.forward(&pooled)
    }
}
