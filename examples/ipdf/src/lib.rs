//! The `ipdf` command line's library, for programs of your own: training data from BOP datasets
//! ([`training_data`]), training runs ([`training`]), scores of rotation models, translation
//! models and 6D poses side by side ([`eval`]), a pose's translation fitted to a depth image
//! ([`depth_fit`]), the record of a training run ([`run_info`]),
//! the whole pipeline of `ipdf pipeline` ([`pipeline`]), figures ([`plots`]), `.npy` output
//! ([`npy`]), point-cloud files ([`cloud_file`]), progress bars and the process allocator.
//! Datasets, synthetic data and labelling are crates of their own (`bop-dataset`, `synth-data`, `pseudo-label`, none of which
//! links libtorch); the commands live in `src/commands/` and map flags onto these functions.
//!
//! ```
//! use ipdf::pipeline::Preset;
//! use ipdf::plots::plot_training_curves;
//! use ipdf::training::Target;
//!
//! // The quick preset, shortened: what `ipdf pipeline --epochs 2` runs.
//! let plan = ipdf::pipeline::Plan { epochs: 2, translation_epochs: 2, ..Preset::Quick.plan() };
//! assert_eq!(plan.total_steps(Target::Rotation), 100);
//! assert_eq!(plan.total_steps(Target::Translation), 100);
//! // A run's training curves from its `train_log.csv`.
//! let log = "epoch,step,loss,learning_rate,validation_llh,seconds,images_per_second\n\
//!            1,50,3.1,4e-3,-1.2,30,26\n2,100,2.2,2e-3,0.7,30,26\n";
//! let figure = plot_training_curves(log, "train_log.csv".as_ref())?;
//! assert_eq!(figure.dimensions(), (1200, 480));
//! # Ok::<(), ipdf::Error>(())
//! ```
pub mod allocator;
pub mod cloud_file;
pub mod depth_fit;
mod error;
pub mod eval;
pub mod median;
pub mod npy;
pub mod pipeline;
pub mod plots;
pub mod progress;
pub mod run_info;
pub mod training;
pub mod training_data;

pub use error::Error;

/// The README's Rust example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeExample;
