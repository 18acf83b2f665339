//! One module per `ipdf` subcommand.
mod choice;
pub mod eval;
pub mod grid;
pub mod label;
pub mod pipeline;
pub mod predict;
pub mod register;
pub mod render;
pub mod synth;
pub mod train;
pub mod viz;
