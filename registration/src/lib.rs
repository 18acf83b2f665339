//! Point-cloud registration: voxel downsampling, PCA normals, FPFH features (Rusu et al. 2009),
//! Fast Global Registration (Zhou, Park, Koltun 2016) and ICP (point-to-point, point-to-plane).
//!
//! - [`PointCloud`]: positions (metres, f32) and optional unit normals (files are read and
//!   written by `depth_render::load_vertices` / `write_ply`, or by your own code).
//! - Stages, each usable alone: [`downsample_voxel`], [`PointIndex`] (k-d tree), [`estimate_normals`],
//!   [`compute_fpfh`], [`align_fgr`], [`refine_icp`].
//! - [`prepare_cloud`] runs the first stages once per cloud into a [`PreparedCloud`], so a
//!   model is described once and registered against many observed clouds with [`register`]
//!   (global hypotheses from FGR, the best by overlap refined by ICP).
//!
//! Poses are `Isometry3<f64>` mapping source coordinates into the target frame. Everything is
//! deterministic for given options (seeds included), whatever the rayon thread count.
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Vector3};
//! use registration::{PointCloud, PrepareOptions, RegisterOptions, prepare_cloud, register};
//!
//! // A bumpy surface patch 0.5 m in front of a camera, and the same patch moved.
//! let patch: Vec<Point3<f32>> = (0..4096)
//!     .map(|i| {
//!         let (x, y) = ((i % 64) as f32 * 0.002, (i / 64) as f32 * 0.002);
//!         Point3::new(x, y, 0.5 + 0.01 * (40.0 * x).sin() * (25.0 * y).cos() + 0.3 * x * y)
//!     })
//!     .collect();
//! let truth = Isometry3::new(Vector3::new(0.01, -0.02, 0.005), Vector3::new(0.05, 0.0, 0.2));
//! let source = PointCloud::new(patch)?;
//! let target = source.transformed(&truth);
//!
//! let options = PrepareOptions::for_voxel(0.004);
//! let model = prepare_cloud(&source, &options)?; // once per model
//! let observed = prepare_cloud(&target, &options)?;
//! let found = register(&model, &observed, &Isometry3::identity(), &RegisterOptions::for_voxel(0.004))?;
//! let error = found.alignment.pose.inverse() * truth;
//! assert!(error.translation.vector.norm() < 0.002 && error.rotation.angle() < 0.02);
//! # Ok::<(), registration::RegistrationError>(())
//! ```

mod cell_grid;
mod cloud;
mod error;
mod fgr;
mod fpfh;
mod icp;
mod matching;
mod neighbours;
mod normals;
mod prepare;
mod register;
mod twist;
mod voxel;

pub use cloud::PointCloud;
pub use error::RegistrationError;
pub use fgr::{FeatureCorrespondences, FgrAlignment, FgrOptions, align_fgr};
pub use fpfh::{FPFH_LEN, Fpfh, FpfhOptions, compute_fpfh};
pub use icp::{
    Alignment, IcpMethod, IcpOptions, RobustKernel, WeakTurn, overlap, refine_icp, weak_turns,
};
pub use neighbours::{AgreeingScratch, Neighbour, PointIndex};
pub use normals::{NormalOptions, NormalOrientation, estimate_normals};
pub use prepare::{PrepareOptions, PreparedCloud, prepare_cloud};
pub use register::{RegisterOptions, Registration, register};
pub use twist::kabsch;
pub use voxel::downsample_voxel;
