//! The pieces of the `ipdf` command line that other programs can reuse: `.npy` export of
//! rotations and atomic file writes. The commands themselves live in `src/commands/`.

pub mod atomic;
pub mod npy;
