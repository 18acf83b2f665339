//! The crate's error type.
use std::path::PathBuf;

/// Everything that can go wrong building, training, saving or querying a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// An image buffer or tensor has the wrong size, channel count or layout.
    #[error("{field}: expected {expected}, got {got}")]
    ImageShape {
        /// Which input (`rgb`, `mask`, `images`).
        field: &'static str,
        /// The expected size or shape, in words.
        expected: String,
        /// What was given.
        got: String,
    },
    /// An object mask selects no pixel.
    #[error("the object mask is empty (no non-zero pixel)")]
    EmptyMask,
    /// A label set is empty or holds a matrix that is not a rotation.
    #[error("label set {image}: {reason}")]
    LabelSet {
        /// Position of the image (and its label set) in the batch or dataset.
        image: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A translation (a label, or a query that must lie in the model's working volume) outside
    /// the working volume.
    #[error("translation {translation:?} mm lies outside the working volume {min:?} to {max:?} mm")]
    OutsideVolume {
        /// The translation, mm.
        translation: [f64; 3],
        /// The volume's lowest corner, mm.
        min: [f64; 3],
        /// The volume's highest corner, mm.
        max: [f64; 3],
    },
    /// A crop box or camera intrinsics that cannot be used (not finite, a focal length ≤ 0, a
    /// crop centre outside the image).
    #[error("crop geometry of image {image}: {reason}")]
    CropGeometry {
        /// Position of the image in the batch or dataset.
        image: usize,
        /// What is wrong.
        reason: String,
    },
    /// An option is out of its range.
    #[error("invalid option {name}: {reason}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// Why it was rejected.
        reason: String,
    },
    /// A checkpoint or weights file could not be read, is truncated, or does not match.
    #[error("{}: {reason}", path.display())]
    Checkpoint {
        /// The file.
        path: PathBuf,
        /// What went wrong (names the tensor or the JSON key).
        reason: String,
    },
    /// A checkpoint was written for another model configuration.
    #[error(
        "{}: the checkpoint has {field} = {found}, this run asks for {expected}",
        path.display()
    )]
    ConfigMismatch {
        /// The checkpoint's configuration file.
        path: PathBuf,
        /// The differing configuration field.
        field: &'static str,
        /// This model's value.
        expected: String,
        /// The checkpoint's value.
        found: String,
    },
    /// The loss came out NaN or infinite (the step was not applied).
    #[error("non-finite loss at step {step}")]
    NonFiniteLoss {
        /// The step (0-based).
        step: u64,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A grid operation failed (bad level or index).
    #[error(transparent)]
    Grid(#[from] so3_grid::GridError),
    /// libtorch reported an error.
    #[error(transparent)]
    Torch(#[from] tch::TchError),
}

impl ModelError {
    /// An [`ModelError::InvalidOption`].
    pub(crate) fn option(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidOption {
            name,
            reason: reason.into(),
        }
    }

    /// A [`ModelError::Checkpoint`].
    pub(crate) fn checkpoint(path: &std::path::Path, reason: impl Into<String>) -> Self {
        Self::Checkpoint {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }
}
