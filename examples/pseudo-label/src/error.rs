//! The error of the labelling.
use bop_dataset::FileError;

/// Why labelling could not run (per-instance failures are not errors: they are recorded in the
/// output as an `"error"` of the instance, see [`crate::LabelFailure`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LabelError {
    /// A file that cannot be read or written, or whose content is invalid.
    #[error(transparent)]
    File(#[from] FileError),
    /// Meshes, cameras or rendering.
    #[error(transparent)]
    Render(#[from] depth_render::RenderError),
    /// Point-cloud registration.
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

impl LabelError {
    /// A [`LabelError::InvalidOption`].
    pub fn option(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidOption {
            name,
            reason: reason.into(),
        }
    }
}
