//! The pieces of the `ipdf` command line that other programs can reuse: BOP JSON conventions,
//! PNG and `.npy` output, atomic file writes. The commands themselves live in `src/commands/`.

pub mod atomic;
pub mod bop;
mod file_error;
pub mod npy;
pub mod png;
pub mod trials;

pub use file_error::FileError;
