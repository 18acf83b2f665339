//! The crate's integration tests, one module per file, in one test binary: the binary
//! links the crate and its dependencies once instead of once per file.
mod appearance;
mod common;
mod further_trials;
mod hypotheses_real;
mod real_frames;
mod reference;
mod tless_layout;
mod told_apart;
