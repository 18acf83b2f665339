//! The pieces of the `ipdf` command line that other programs can reuse: BOP datasets
//! ([`dataset`], [`bop`], [`images`]), synthetic RGB-D data ([`synth`]), pseudo ground-truth
//! labelling ([`label`]), training data and scores of Implicit-PDF models
//! ([`training_data`], [`evaluation`], [`run_info`]), figures ([`plots`]), `.npy` output and
//! atomic file writes. The commands themselves live in `src/commands/`.

pub mod allocator;
pub mod atomic;
pub mod bop;
pub mod dataset;
mod error;
pub mod evaluation;
mod file_error;
pub mod images;
pub mod label;
pub mod npy;
pub mod plots;
pub mod progress;
pub mod run_info;
pub mod synth;
pub mod training_data;
pub mod trials;

pub use error::PipelineError;
pub use file_error::FileError;
