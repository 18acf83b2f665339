//! One module per `ipdf` subcommand.
pub mod grid;
pub mod register;
pub mod render;
