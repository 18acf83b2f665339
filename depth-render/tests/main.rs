//! The crate's integration tests, one module per file, in one test binary: the binary
//! links the crate and its dependencies once instead of once per file.
mod colour_camera;
mod compare;
mod mesh_io;
mod mesh_repair;
mod real_scans;
mod render;
mod sensor;
mod shapes;
mod surface;
