//! The crate's integration tests, one module per file, in one test binary: the binary
//! links the crate and its dependencies once instead of once per file.
mod checkpoint;
mod common;
mod kernels;
mod learning;
mod model;
mod translation;
