//! The error of training data, evaluation and figures.
use bop_dataset::FileError;

/// Why a stage of the `ipdf` pipeline could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// A file that cannot be read or written, or whose content is invalid.
    #[error(transparent)]
    File(#[from] FileError),
    /// Meshes, cameras or rendering.
    #[error(transparent)]
    Render(#[from] depth_render::RenderError),
    /// Point-cloud registration.
    #[error(transparent)]
    Registration(#[from] registration::RegistrationError),
    /// Synthetic data.
    #[error(transparent)]
    Synth(#[from] synth_data::SynthError),
    /// Pseudo-labelling.
    #[error(transparent)]
    Label(#[from] pseudo_label::LabelError),
    /// The Implicit-PDF model: its configuration, checkpoints, training or inference.
    #[error(transparent)]
    Model(#[from] ipdf_model::ModelError),
    /// Scores of distributions.
    #[error(transparent)]
    Metrics(#[from] metrics::MetricsError),
    /// A figure that could not be drawn.
    #[error("figure: {0}")]
    Figure(String),
    /// An option out of its range.
    #[error("{name}: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

impl PipelineError {
    /// A [`PipelineError::InvalidOption`].
    pub fn option(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidOption {
            name,
            reason: reason.into(),
        }
    }
}
