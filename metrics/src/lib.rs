//! Scores of SO(3) distributions against sets of ground-truth rotations, exactly as defined by
//! Implicit-PDF (Murphy et al., 2021) and the pseudo-label paper built on it:
//!
//! - [`llh`]: mean log-density at the ground-truth rotations;
//! - [`maad`]: expected distance of a sample to the nearest ground-truth rotation (degrees);
//! - [`recall_maad`]: mean distance of each ground-truth rotation to the nearest predicted
//!   (high-probability) rotation (degrees).
//!
//! A [`Distribution`] is probability mass on cells of `so3-grid` grids, all of one level or of
//! mixed levels after hierarchical refinement; both are scored by the same code. A
//! [`SymmetryGroup`] (BOP `models_info.json` form) expands one pose into its full symmetry set.
//!
//! ```
//! use metrics::{llh, maad, recall_maad, Distribution, SymmetryGroup, RECALL_THRESHOLD};
//! use nalgebra::{UnitQuaternion, Vector3};
//! use so3_grid::Grid;
//!
//! let grid = Grid::new(3)?;
//! let uniform = Distribution::uniform(&grid);
//! let pose = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
//! assert!((llh(&uniform, &[pose])? + std::f64::consts::PI.powi(2).ln()).abs() < 1e-9);
//! assert!((maad(&uniform, &[pose])? - 126.5).abs() < 0.5);
//!
//! // A box-like object: 4 symmetries (2-fold about z and x). All mass on those 4 cells.
//! let mut group = SymmetryGroup::cyclic(&Vector3::z(), 2)?;
//! group.discrete.extend(SymmetryGroup::cyclic(&Vector3::x(), 2)?.discrete);
//! group.discrete.push(group.discrete[0] * group.discrete[1]);
//! let gt_set = group.expand(&pose);
//! let mut masses = vec![0.0; grid.len() as usize];
//! for q in &gt_set {
//!     masses[grid.locate(q)? as usize] += 0.25;
//! }
//! let peaked = Distribution::dense(&grid, masses)?;
//! assert!(maad(&peaked, &gt_set)? < 5.0);
//! assert!(recall_maad(&peaked, &gt_set, RECALL_THRESHOLD)? < 5.0);
//! # Ok::<(), metrics::MetricsError>(())
//! ```

mod distribution;
mod error;
mod nearest;
mod score;
mod symmetry;

pub use distribution::{Distribution, GridCell, MASS_SUM_TOLERANCE};
pub use error::MetricsError;
pub use nearest::{REFINE_BELOW, nearest_distances};
pub use score::{
    RECALL_REFERENCE_LEVEL, RECALL_THRESHOLD, llh, maad, recall_maad, recall_min_log_density,
};
pub use symmetry::{CONTINUOUS_STEPS, ContinuousSymmetry, SymmetryGroup};
