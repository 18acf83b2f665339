//! The network's configuration, shared by the rotation and translation models and stored in
//! every checkpoint.
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::ModelError;
use crate::encoder::EncoderKind;
use crate::rotation::RotationFrame;

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
    /// The frame of a rotation model's rotations (translation models: unused); a checkpoint
    /// that names none is in the camera's.
    #[serde(default, skip_serializing_if = "RotationFrame::is_camera")]
    pub rotation_frame: RotationFrame,
    /// How many of the encoder's first blocks keep their starting (pretrained) weights and
    /// batch-norm statistics: EfficientNet-Lite0's stem and its first N of 16 MBConv blocks
    /// then run without gradients, in inference mode (Hinterstoisser et al. 2018: features
    /// learnt on real images, frozen, carry a model trained on renders to real images). 0, the
    /// default, trains every layer; other encoders take only 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub frozen_blocks: usize,
}

fn is_zero(value: &usize) -> bool {
    *value == 0
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
            rotation_frame: RotationFrame::Camera,
            frozen_blocks: 0,
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
        let blocks = self.encoder.freezable_blocks();
        if self.frozen_blocks > blocks {
            let reason = if blocks == 0 {
                format!(
                    "{} freezes no block (efficientnet-lite0 does)",
                    self.encoder
                )
            } else {
                format!("{} has {blocks} blocks to freeze", self.encoder)
            };
            return Err(ModelError::option(
                "frozen_blocks",
                format!("{}: {reason}", self.frozen_blocks),
            ));
        }
        Ok(())
    }
}

impl ModelConfig {
    /// Fails with [`ModelError::ConfigMismatch`] naming the first field where `found` (read
    /// from the checkpoint at `path`) differs from `self`.
    pub fn check_same(&self, found: &ModelConfig, path: &Path) -> Result<(), ModelError> {
        let fields: [(&'static str, String, String); 7] = [
            (
                "encoder",
                self.encoder.to_string(),
                found.encoder.to_string(),
            ),
            (
                "input_size",
                self.input_size.to_string(),
                found.input_size.to_string(),
            ),
            (
                "fourier_components",
                self.fourier_components.to_string(),
                found.fourier_components.to_string(),
            ),
            (
                "head_sizes",
                format!("{:?}", self.head_sizes),
                format!("{:?}", found.head_sizes),
            ),
            ("seed", self.seed.to_string(), found.seed.to_string()),
            (
                "rotation_frame",
                self.rotation_frame.name().to_string(),
                found.rotation_frame.name().to_string(),
            ),
            (
                "frozen_blocks",
                self.frozen_blocks.to_string(),
                found.frozen_blocks.to_string(),
            ),
        ];
        match fields.into_iter().find(|(_, a, b)| a != b) {
            Some((field, expected, found)) => Err(ModelError::ConfigMismatch {
                path: path.to_path_buf(),
                field,
                expected,
                found,
            }),
            None => Ok(()),
        }
    }
}
