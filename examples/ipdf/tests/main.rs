//! The crate's integration tests, one module per file, in one test binary: the binary
//! links the crate and its dependencies once instead of once per file.
mod cli_determinism;
mod cli_ensemble;
mod cli_grid;
mod cli_killed;
mod cli_label;
mod cli_newcomer;
mod cli_pipeline;
mod cli_pipeline_mesh;
mod cli_pose;
mod cli_register;
mod cli_render;
mod cli_rerun;
mod common;
mod readme_walk;
mod real_frame_benchmark;
mod real_frame_scores;
mod rotation_frame;
mod tless_layout;
mod ycbv_real;
