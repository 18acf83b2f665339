//! The error of the `ipdf` library: training data, training, evaluation, the pipeline and
//! figures.
use bop_dataset::FileError;

/// Why a function of the `ipdf` library (a stage of the pipeline, a command) could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
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
    Metrics(#[from] ipdf_metrics::MetricsError),
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

impl Error {
    /// A [`Error::InvalidOption`].
    pub fn option(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidOption {
            name,
            reason: reason.into(),
        }
    }
}
