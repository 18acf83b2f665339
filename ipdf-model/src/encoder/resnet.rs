//! ResNet-18 (He et al. 2016) with torchvision's parameter names (`conv1`, `bn1`,
//! `layer1.0.conv1`, `layer2.0.downsample.0`, …), without its classifier.
use tch::{Tensor, nn};

use crate::layers::{BatchNorm2d, Conv2d, ConvShape, ParamInit, conv_output};

/// Where the network stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ResNetCut {
    /// After the fourth stage and global average pooling (512-d).
    Pooled,
    /// After the third stage, flattened (`256 · H/16 · W/16`).
    Stage3,
}

#[derive(Debug)]
struct BasicBlock {
    conv1: Conv2d,
    bn1: BatchNorm2d,
    conv2: Conv2d,
    bn2: BatchNorm2d,
    downsample: Option<(Conv2d, BatchNorm2d)>,
}

impl BasicBlock {
    fn new(path: nn::Path, input: i64, output: i64, stride: i64, init: &mut ParamInit) -> Self {
        let conv1 = Conv2d::new(
            &path / "conv1",
            ConvShape::plain(input, output, 3, stride, 1),
            init,
        );
        let bn1 = BatchNorm2d::new(&path / "bn1", output);
        let conv2 = Conv2d::new(
            &path / "conv2",
            ConvShape::plain(output, output, 3, 1, 1),
            init,
        );
        let bn2 = BatchNorm2d::new(&path / "bn2", output);
        let downsample = (stride != 1 || input != output).then(|| {
            let branch = &path / "downsample";
            (
                Conv2d::new(
                    &branch / "0",
                    ConvShape::plain(input, output, 1, stride, 0),
                    init,
                ),
                BatchNorm2d::new(&branch / "1", output),
            )
        });
        Self {
            conv1,
            bn1,
            conv2,
            bn2,
            downsample,
        }
    }

    fn forward_t(&self, xs: &Tensor, train: bool) -> Tensor {
        let ys = self.bn1.forward_t(&self.conv1.forward(xs), train).relu();
        let ys = self.bn2.forward_t(&self.conv2.forward(&ys), train);
        let shortcut = match &self.downsample {
            Some((conv, norm)) => norm.forward_t(&conv.forward(xs), train),
            None => xs.shallow_clone(),
        };
        (shortcut + ys).relu()
    }
}

#[derive(Debug)]
pub(crate) struct ResNet18 {
    conv1: Conv2d,
    bn1: BatchNorm2d,
    stages: Vec<Vec<BasicBlock>>,
    cut: ResNetCut,
}

impl ResNet18 {
    pub(crate) fn new(path: nn::Path, cut: ResNetCut, init: &mut ParamInit) -> Self {
        let conv1 = Conv2d::new(&path / "conv1", ConvShape::plain(3, 64, 7, 2, 3), init);
        let bn1 = BatchNorm2d::new(&path / "bn1", 64);
        let widths: &[(i64, i64, i64)] = match cut {
            ResNetCut::Pooled => &[(64, 64, 1), (64, 128, 2), (128, 256, 2), (256, 512, 2)],
            ResNetCut::Stage3 => &[(64, 64, 1), (64, 128, 2), (128, 256, 2)],
        };
        let stages = widths
            .iter()
            .enumerate()
            .map(|(i, &(input, output, stride))| {
                let layer = &path / format!("layer{}", i + 1);
                vec![
                    BasicBlock::new(&layer / "0", input, output, stride, init),
                    BasicBlock::new(&layer / "1", output, output, 1, init),
                ]
            })
            .collect();
        Self {
            conv1,
            bn1,
            stages,
            cut,
        }
    }

    pub(crate) fn feature_dim(&self, input_size: i64) -> i64 {
        match self.cut {
            ResNetCut::Pooled => 512,
            ResNetCut::Stage3 => {
                // conv1 (7, /2), max pool (3, /2), layer2 (/2), layer3 (/2).
                let mut side = conv_output(input_size, 7, 2, 3);
                side = conv_output(side, 3, 2, 1);
                side = conv_output(side, 3, 2, 1);
                side = conv_output(side, 3, 2, 1);
                256 * side * side
            }
        }
    }

    pub(crate) fn forward_t(&self, images: &Tensor, train: bool) -> Tensor {
        let mut xs = self
            .bn1
            .forward_t(&self.conv1.forward(images), train)
            .relu()
            .max_pool2d([3, 3], [2, 2], [1, 1], [1, 1], false);
        for block in self.stages.iter().flatten() {
            xs = block.forward_t(&xs, train);
        }
        match self.cut {
            ResNetCut::Pooled => xs.adaptive_avg_pool2d([1, 1]).flatten(1, -1),
            ResNetCut::Stage3 => xs.flatten(1, -1),
        }
    }
}
