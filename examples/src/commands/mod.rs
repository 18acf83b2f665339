//! One module per `ipdf` subcommand.
pub mod grid;
pub mod label;
pub mod register;
pub mod render;
pub mod synth;
