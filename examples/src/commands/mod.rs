//! One module per `ipdf` subcommand.
pub mod grid;
pub mod render;
