//! EfficientNet-Lite0 (Tan & Le 2019; the Lite variants of TensorFlow's model garden: no
//! squeeze-and-excitation, ReLU6, stem and head unscaled) with the parameter names of the
//! `efficientnet_pytorch` family (`_conv_stem`, `_bn0`, `_blocks.N._expand_conv`, …), so that
//! ImageNet weights converted from that format load directly. Convolutions pad as TensorFlow's
//! `SAME` does (a stride-2 convolution of an even input pads one pixel more on the right and
//! bottom), as the weights were trained.
use tch::{Tensor, nn};

use crate::layers::{BatchNorm2d, Conv2d, ConvShape, ParamInit};

/// TensorFlow's batch-norm ε and momentum (0.99 there: 0.01 in torch's convention).
const BN_EPS: f64 = 1e-3;
const BN_MOMENTUM: f64 = 0.01;

/// One stage of MBConv blocks: repeats, kernel, stride of the first block, expansion, input
/// and output channels (`efficientnet_lite_builder.py`'s `r1_k3_s11_e1_i32_o16`, …).
struct Stage {
    repeats: usize,
    kernel: i64,
    stride: i64,
    expand: i64,
    input: i64,
    output: i64,
}

const STAGES: [Stage; 7] = [
    stage(1, [3, 1, 1, 32, 16]),
    stage(2, [3, 2, 6, 16, 24]),
    stage(2, [5, 2, 6, 24, 40]),
    stage(3, [3, 2, 6, 40, 80]),
    stage(3, [5, 1, 6, 80, 112]),
    stage(4, [5, 2, 6, 112, 192]),
    stage(1, [3, 1, 6, 192, 320]),
];

/// The MBConv blocks of all stages (16).
pub(crate) const BLOCKS: usize = {
    let (mut count, mut i) = (0, 0);
    while i < STAGES.len() {
        count += STAGES[i].repeats;
        i += 1;
    }
    count
};

/// A [`Stage`] from `repeats` and `[kernel, stride, expand, input, output]`, in the order of
/// the builder's block strings.
const fn stage(repeats: usize, [kernel, stride, expand, input, output]: [i64; 5]) -> Stage {
    Stage {
        repeats,
        kernel,
        stride,
        expand,
        input,
        output,
    }
}

/// Pads `[B, C, H, W]` as TensorFlow's `SAME` does for a `kernel`, `stride` convolution.
fn same_pad(xs: &Tensor, kernel: i64, stride: i64) -> Tensor {
    let (height, width) = (xs.size()[2], xs.size()[3]);
    let total = |side: i64| {
        let output = (side + stride - 1) / stride;
        ((output - 1) * stride + kernel - side).max(0)
    };
    let (pad_h, pad_w) = (total(height), total(width));
    if pad_h == 0 && pad_w == 0 {
        return xs.shallow_clone();
    }
    xs.constant_pad_nd([pad_w / 2, pad_w - pad_w / 2, pad_h / 2, pad_h - pad_h / 2])
}

/// A convolution padded as TensorFlow's `SAME`, its batch norm, and optionally ReLU6.
#[derive(Debug)]
struct ConvNorm {
    conv: Conv2d,
    norm: BatchNorm2d,
    kernel: i64,
    stride: i64,
}

impl ConvNorm {
    /// `conv` and `norm` are the names of the two layers under `path`.
    fn new(path: &nn::Path, names: (&str, &str), shape: ConvShape, init: &mut ParamInit) -> Self {
        Self {
            conv: Conv2d::new(path / names.0, shape, init),
            norm: BatchNorm2d::with_eps(path / names.1, shape.output, BN_EPS, BN_MOMENTUM),
            kernel: shape.kernel,
            stride: shape.stride,
        }
    }

    fn forward_t(&self, xs: &Tensor, train: bool) -> Tensor {
        let padded = same_pad(xs, self.kernel, self.stride);
        self.norm.forward_t(&self.conv.forward(&padded), train)
    }
}

/// An inverted residual block: 1×1 expansion (unless the ratio is 1), depthwise `k × k`, 1×1
/// projection, and the identity added where the shapes allow.
#[derive(Debug)]
struct MbConv {
    expand: Option<ConvNorm>,
    depthwise: ConvNorm,
    project: ConvNorm,
    residual: bool,
}

impl MbConv {
    fn new(
        path: nn::Path,
        input: i64,
        output: i64,
        spec: &Stage,
        stride: i64,
        init: &mut ParamInit,
    ) -> Self {
        let hidden = input * spec.expand;
        let expand = (spec.expand != 1).then(|| {
            ConvNorm::new(
                &path,
                ("_expand_conv", "_bn0"),
                ConvShape::plain(input, hidden, 1, 1, 0),
                init,
            )
        });
        let depthwise = ConvNorm::new(
            &path,
            ("_depthwise_conv", "_bn1"),
            ConvShape {
                groups: hidden,
                ..ConvShape::plain(hidden, hidden, spec.kernel, stride, 0)
            },
            init,
        );
        let project = ConvNorm::new(
            &path,
            ("_project_conv", "_bn2"),
            ConvShape::plain(hidden, output, 1, 1, 0),
            init,
        );
        Self {
            expand,
            depthwise,
            project,
            residual: stride == 1 && input == output,
        }
    }

    fn forward_t(&self, xs: &Tensor, train: bool) -> Tensor {
        let hidden = match &self.expand {
            Some(expand) => expand.forward_t(xs, train).relu6(),
            None => xs.shallow_clone(),
        };
        let hidden = self.depthwise.forward_t(&hidden, train).relu6();
        let ys = self.project.forward_t(&hidden, train);
        if self.residual { ys + xs } else { ys }
    }
}

/// EfficientNet-Lite0 without its classifier: 1280-d after global average pooling.
#[derive(Debug)]
pub(crate) struct EfficientNetLite0 {
    stem: ConvNorm,
    blocks: Vec<MbConv>,
    head: ConvNorm,
    /// The stem and this many first blocks run without gradients, in inference mode.
    frozen: usize,
}

impl EfficientNetLite0 {
    pub(crate) const FEATURES: i64 = 1280;

    /// The network with its stem and first `frozen` blocks frozen (at most [`BLOCKS`]).
    pub(crate) fn new(path: nn::Path, frozen: usize, init: &mut ParamInit) -> Self {
        let stem = ConvNorm::new(
            &path,
            ("_conv_stem", "_bn0"),
            ConvShape::plain(3, 32, 3, 2, 0),
            init,
        );
        let mut blocks = Vec::new();
        for spec in &STAGES {
            for repeat in 0..spec.repeats {
                let (input, stride) = if repeat == 0 {
                    (spec.input, spec.stride)
                } else {
                    (spec.output, 1)
                };
                let block_path = &path / "_blocks" / blocks.len();
                blocks.push(MbConv::new(
                    block_path,
                    input,
                    spec.output,
                    spec,
                    stride,
                    init,
                ));
            }
        }
        let head = ConvNorm::new(
            &path,
            ("_conv_head", "_bn1"),
            ConvShape::plain(320, Self::FEATURES, 1, 1, 0),
            init,
        );
        Self {
            stem,
            blocks,
            head,
            frozen: frozen.min(BLOCKS),
        }
    }

    /// The last feature map before pooling, `[B, 1280, ⌈S/32⌉, ⌈S/32⌉]`.
    fn features(&self, images: &Tensor, train: bool) -> Tensor {
        let (frozen, trained) = self.blocks.split_at(self.frozen);
        let mut xs = if self.frozen == 0 {
            self.stem.forward_t(images, train).relu6()
        } else {
            tch::no_grad(|| {
                let mut xs = self.stem.forward_t(images, false).relu6();
                for block in frozen {
                    xs = block.forward_t(&xs, false);
                }
                xs
            })
        };
        for block in trained {
            xs = block.forward_t(&xs, train);
        }
        self.head.forward_t(&xs, train).relu6()
    }

    pub(crate) fn forward_t(&self, images: &Tensor, train: bool) -> Tensor {
        self.features(images, train)
            .adaptive_avg_pool2d([1, 1])
            .flatten(1, -1)
    }
}

#[cfg(test)]
mod tests {
    //! The ImageNet weights of `scripts/setup-pretrained.sh`, run through this network, name a
    //! real camera's view of a mug as ImageNet does: an oracle for the block layout, the
    //! padding and the weights' conversion alike (a wrong one scatters the classes).
    use std::path::{Path, PathBuf};

    use tch::{Device, Kind, Tensor, nn};

    use super::EfficientNetLite0;
    use crate::checkpoint::read_tensors;
    use crate::layers::ParamInit;

    /// ImageNet's classes 504, "coffee mug", and 968, "cup".
    const MUG_CLASSES: [i64; 2] = [504, 968];

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    /// The YCB-Video fixture's mug (scene 0, instance 1) as a `[1, 3, 224, 224]` crop: its
    /// visible box made square with a tenth's margin, resized, ImageNet-normalised.
    fn mug_crop() -> Tensor {
        const MEAN: [f32; 3] = [0.485, 0.456, 0.406];
        const STD: [f32; 3] = [0.229, 0.224, 0.225];
        let dir = root().join("examples/pseudo-label/tests/data/ycbv_real/test/000000");
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("scene_gt_info.json")).unwrap())
                .unwrap();
        let bbox: Vec<f64> = info["1"][1]["bbox_visib"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let image = image::open(dir.join("rgb/000001.jpg")).unwrap().to_rgb8();
        let side = bbox[2].max(bbox[3]) * 1.1;
        let (cx, cy) = (bbox[0] + bbox[2] / 2.0, bbox[1] + bbox[3] / 2.0);
        let (x0, y0) = ((cx - side / 2.0).max(0.0), (cy - side / 2.0).max(0.0));
        let cut = image::imageops::crop_imm(&image, x0 as u32, y0 as u32, side as u32, side as u32)
            .to_image();
        let resized =
            image::imageops::resize(&cut, 224, 224, image::imageops::FilterType::Triangle);
        let mut values = vec![0f32; 3 * 224 * 224];
        for (x, y, pixel) in resized.enumerate_pixels() {
            for c in 0..3 {
                let v = f32::from(pixel[c]) / 255.0;
                values[c * 224 * 224 + (y * 224 + x) as usize] = (v - MEAN[c]) / STD[c];
            }
        }
        Tensor::from_slice(&values).reshape([1, 3, 224, 224])
    }

    /// The five most likely ImageNet classes of `images`, with the converted weights loaded
    /// or, with `pretrained` false, the network's seeded initial weights and the weights'
    /// classifier.
    fn top5(images: &Tensor, pretrained: bool) -> Vec<i64> {
        let path = root().join(".pretrained/efficientnet-lite0.safetensors");
        assert!(
            path.exists(),
            "{} is missing: run scripts/setup-pretrained.sh (make test does)",
            path.display()
        );
        let mut store = nn::VarStore::new(Device::Cpu);
        let net = EfficientNetLite0::new(store.root(), 0, &mut ParamInit::new(0));
        let mut saved = read_tensors(&path, Device::Cpu).unwrap();
        if pretrained {
            tch::no_grad(|| {
                for (name, mut variable) in store.variables() {
                    let tensor = saved.remove(&name).unwrap_or_else(|| panic!("{name}"));
                    variable.copy_(&tensor);
                }
            });
        }
        store.freeze();
        let features = tch::no_grad(|| net.forward_t(images, false));
        let logits = features.linear(&saved["_fc.weight"], Some(&saved["_fc.bias"]));
        let order = logits.argsort(-1, true).to_kind(Kind::Int64);
        Vec::<i64>::try_from(order.get(0).narrow(0, 0, 5)).unwrap()
    }

    #[test]
    fn imagenet_weights_name_a_real_mug() {
        let crop = mug_crop();
        let pretrained = top5(&crop, true);
        assert!(
            pretrained[..2].iter().any(|c| MUG_CLASSES.contains(c)),
            "top classes {pretrained:?}"
        );
        let untrained = top5(&crop, false);
        assert!(
            !untrained.iter().any(|c| MUG_CLASSES.contains(c)),
            "untrained top classes {untrained:?}"
        );
    }
}
