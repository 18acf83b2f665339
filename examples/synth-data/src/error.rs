//! The error of dataset synthesis.
use bop_dataset::FileError;

/// Why a synthetic dataset could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SynthError {
    /// A file that cannot be read or written, or whose content is invalid.
    #[error(transparent)]
    File(#[from] FileError),
    /// Meshes, cameras or rendering.
    #[error(transparent)]
    Render(#[from] depth_render::RenderError),
    /// Point clouds of the registration trials.
    #[error(transparent)]
    Registration(#[from] registration::RegistrationError),
    /// An option out of its range.
    #[error("{name}: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

impl SynthError {
    /// A [`SynthError::InvalidOption`].
    pub fn option(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidOption {
            name,
            reason: reason.into(),
        }
    }
}
