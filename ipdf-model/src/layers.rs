//! The building blocks of the networks: convolutions, linear layers and normalisations whose
//! parameters are named as in torchvision (`weight`, `bias`, `running_mean`, `running_var`) and
//! initialised from a seeded ChaCha stream, so that a model depends only on its seed (libtorch's
//! own initialisers draw from a process-wide generator).
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tch::{Tensor, nn};

/// Draws initial parameter values; one per model, consumed in construction order.
pub(crate) struct ParamInit {
    rng: ChaCha8Rng,
}

impl ParamInit {
    pub(crate) fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A trainable variable with entries uniform in `[−bound, bound]`.
    fn uniform(&mut self, path: &nn::Path, name: &str, dims: &[i64], bound: f64) -> Tensor {
        let count: i64 = dims.iter().product();
        let values: Vec<f32> = (0..count)
            .map(|_| self.rng.random_range(-bound..bound) as f32)
            .collect();
        path.var_copy(name, &Tensor::from_slice(&values).reshape(dims))
    }

    /// He (Kaiming) uniform initialisation for a weight whose fan-in is `fan_in`: variance
    /// `2 / fan_in`, suited to the ReLU networks here.
    fn he_uniform(&mut self, path: &nn::Path, dims: &[i64], fan_in: i64) -> Tensor {
        let bound = (6.0 / fan_in as f64).sqrt();
        self.uniform(path, "weight", dims, bound)
    }
}

/// A 2-D convolution, `weight [out, in/groups, k, k]` and an optional `bias [out]`.
#[derive(Debug)]
pub(crate) struct Conv2d {
    weight: Tensor,
    bias: Option<Tensor>,
    stride: i64,
    padding: i64,
    groups: i64,
}

/// Shape of a [`Conv2d`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct ConvShape {
    pub(crate) input: i64,
    pub(crate) output: i64,
    pub(crate) kernel: i64,
    pub(crate) stride: i64,
    pub(crate) padding: i64,
    pub(crate) groups: i64,
    pub(crate) bias: bool,
}

impl ConvShape {
    /// A `kernel × kernel` convolution without bias and with one group.
    pub(crate) const fn plain(
        input: i64,
        output: i64,
        kernel: i64,
        stride: i64,
        padding: i64,
    ) -> Self {
        Self {
            input,
            output,
            kernel,
            stride,
            padding,
            groups: 1,
            bias: false,
        }
    }
}

impl Conv2d {
    pub(crate) fn new(path: nn::Path, shape: ConvShape, init: &mut ParamInit) -> Self {
        let per_group = shape.input / shape.groups;
        let fan_in = per_group * shape.kernel * shape.kernel;
        let weight = init.he_uniform(
            &path,
            &[shape.output, per_group, shape.kernel, shape.kernel],
            fan_in,
        );
        let bias = shape.bias.then(|| path.zeros("bias", &[shape.output]));
        Self {
            weight,
            bias,
            stride: shape.stride,
            padding: shape.padding,
            groups: shape.groups,
        }
    }

    pub(crate) fn forward(&self, xs: &Tensor) -> Tensor {
        xs.conv2d(
            &self.weight,
            self.bias.as_ref(),
            [self.stride],
            [self.padding],
            [1],
            self.groups,
        )
    }
}

/// A fully connected layer, `weight [out, in]`, `bias [out]`.
#[derive(Debug)]
pub(crate) struct Linear {
    weight: Tensor,
    bias: Tensor,
}

impl Linear {
    pub(crate) fn new(path: nn::Path, input: i64, output: i64, init: &mut ParamInit) -> Self {
        let weight = init.he_uniform(&path, &[output, input], input);
        let bias = path.zeros("bias", &[output]);
        Self { weight, bias }
    }

    /// The parameters' element kind (follows `VarStore::double` and friends).
    pub(crate) fn kind(&self) -> tch::Kind {
        self.weight.kind()
    }

    /// A detached copy of the layer with parameters of element kind `kind`.
    pub(crate) fn to_kind(&self, kind: tch::Kind) -> Self {
        Self {
            weight: self.weight.detach().to_kind(kind),
            bias: self.bias.detach().to_kind(kind),
        }
    }

    pub(crate) fn forward(&self, xs: &Tensor) -> Tensor {
        xs.linear(&self.weight, Some(&self.bias))
    }
}

/// Batch normalisation over the channels of `[B, C, H, W]` (momentum 0.1, ε = 1e-5, as torch,
/// unless built [`BatchNorm2d::with_eps`]).
#[derive(Debug)]
pub(crate) struct BatchNorm2d {
    weight: Tensor,
    bias: Tensor,
    running_mean: Tensor,
    running_var: Tensor,
    eps: f64,
    momentum: f64,
}

impl BatchNorm2d {
    pub(crate) fn new(path: nn::Path, channels: i64) -> Self {
        Self::with_eps(path, channels, 1e-5, 0.1)
    }

    /// Another ε and running-statistics momentum (torch's convention: the new batch's weight).
    pub(crate) fn with_eps(path: nn::Path, channels: i64, eps: f64, momentum: f64) -> Self {
        Self {
            weight: path.ones("weight", &[channels]),
            bias: path.zeros("bias", &[channels]),
            running_mean: path.zeros_no_train("running_mean", &[channels]),
            running_var: path.ones_no_train("running_var", &[channels]),
            eps,
            momentum,
        }
    }

    pub(crate) fn forward_t(&self, xs: &Tensor, train: bool) -> Tensor {
        xs.batch_norm(
            Some(&self.weight),
            Some(&self.bias),
            Some(&self.running_mean),
            Some(&self.running_var),
            train,
            self.momentum,
            self.eps,
            false,
        )
    }
}

/// Layer normalisation over the last dimension (ε = 1e-6, as ConvNeXt).
#[derive(Debug)]
pub(crate) struct LayerNorm {
    weight: Tensor,
    bias: Tensor,
    dim: i64,
}

impl LayerNorm {
    pub(crate) fn new(path: nn::Path, dim: i64) -> Self {
        Self {
            weight: path.ones("weight", &[dim]),
            bias: path.zeros("bias", &[dim]),
            dim,
        }
    }

    /// Normalises `[…, C]`.
    pub(crate) fn forward(&self, xs: &Tensor) -> Tensor {
        xs.layer_norm(
            [self.dim],
            Some(&self.weight),
            Some(&self.bias),
            1e-6,
            false,
        )
    }

    /// Normalises the channels of `[B, C, H, W]`.
    pub(crate) fn forward_channels_first(&self, xs: &Tensor) -> Tensor {
        self.forward(&xs.permute([0, 2, 3, 1]))
            .permute([0, 3, 1, 2])
    }
}

/// A constant-initialised trainable tensor (ConvNeXt's layer scale).
pub(crate) fn constant(path: &nn::Path, name: &str, dims: &[i64], value: f64) -> Tensor {
    path.var(name, dims, nn::Init::Const(value))
}

/// Output length of a convolution or pooling along one axis.
pub(crate) const fn conv_output(input: i64, kernel: i64, stride: i64, padding: i64) -> i64 {
    (input + 2 * padding - kernel) / stride + 1
}
