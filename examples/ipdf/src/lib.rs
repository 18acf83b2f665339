//! The pieces of the `ipdf` command line that other programs can reuse: training data from BOP
//! datasets ([`training_data`]), training runs ([`training`]), scores of Implicit-PDF models ([`evaluation`]), the record of a
//! training run ([`run_info`]), figures ([`plots`]), `.npy` output ([`npy`]), progress bars and
//! point-cloud files ([`cloud_file`]) and the process allocator, and the whole
//! pipeline of `ipdf pipeline` ([`pipeline`]). Datasets, synthetic data and labelling are crates of their own
//! (`bop-dataset`, `synth-data`, `pseudo-label`); the commands live in `src/commands/`.
//!
//! ```no_run
//! use bop_dataset::BopDataset;
//! use ipdf::training_data::{ExampleOptions, load_examples};
//!
//! // The validation crops of object 1 of a dataset written by `ipdf synth`, with each
//! // instance's ground-truth symmetry set, ready for `ipdf_model` at 48 pixels.
//! let dataset = BopDataset::new("runs/demo/data/uniform".as_ref());
//! let examples = load_examples(&dataset, &ExampleOptions::evaluation("val", 1, 48))?;
//! println!("{} images", examples.instances.len());
//! # Ok::<(), ipdf::PipelineError>(())
//! ```
pub mod allocator;
pub mod cloud_file;
mod error;
pub mod evaluation;
pub mod npy;
pub mod pipeline;
pub mod plots;
pub mod progress;
pub mod run_info;
pub mod training;
pub mod training_data;

pub use error::PipelineError;
