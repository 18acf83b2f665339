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
//! use ipdf_metrics::{llh, maad, recall_maad, Distribution, SymmetryGroup, RECALL_THRESHOLD};
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
//! # Ok::<(), ipdf_metrics::MetricsError>(())
//! ```
//!
//! Poses of objects are scored in BOP's conventions (model → camera, `x_cam = R·x + t`, mm) by
//! [`translation_error`], [`add`] (ADD) and [`add_s`] (ADD-S, for symmetric objects) over
//! [`ModelPoints`], and a list of such errors by [`auc`], the area under the
//! accuracy–threshold curve:
//!
//! ```
//! use ipdf_metrics::{ModelPoints, add, add_s, auc, translation_error};
//! use nalgebra::{Isometry3, Point3, Vector3};
//!
//! // The 8 corners of a 20 mm cube; it is symmetric under quarter turns about z.
//! let corners: Vec<Point3<f64>> = (0..8)
//!     .map(|k| Point3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1).cast::<f64>() * 20.0
//!         - Vector3::repeat(10.0))
//!     .collect();
//! let cube = ModelPoints::new(&corners)?;
//! assert!((cube.diameter() - 20.0 * 3f64.sqrt()).abs() < 1e-9);
//!
//! let truth = Isometry3::translation(0.0, 0.0, 500.0);
//! let turned = truth * Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_2);
//! assert!((add(&cube, &turned, &truth) - 20.0).abs() < 1e-9); // each corner moves one side
//! assert!(add_s(&cube, &turned, &truth) < 1e-9); // ...onto another corner
//!
//! let shifted = Isometry3::translation(3.0, 4.0, 500.0);
//! assert!((translation_error(&shifted.translation.vector, &truth.translation.vector) - 5.0).abs() < 1e-12);
//! assert!((add(&cube, &shifted, &truth) - 5.0).abs() < 1e-9);
//!
//! // ADD-S AUC up to 10 % of the diameter (3.46 mm): errors 0 and 5 mm score 1 and 0.
//! let errors = [add_s(&cube, &turned, &truth), add_s(&cube, &shifted, &truth)];
//! assert!((auc(&errors, 0.1 * cube.diameter())? - 0.5).abs() < 1e-6);
//! # Ok::<(), ipdf_metrics::MetricsError>(())
//! ```

mod distribution;
mod error;
mod label_set;
mod nearest;
mod pose_error;
mod score;
mod symmetry;

pub use distribution::{Distribution, GridCell, MASS_SUM_TOLERANCE};
pub use error::MetricsError;
pub use label_set::{completeness, precision, share_within};
pub use nearest::{REFINE_BELOW, nearest_distances};
pub use pose_error::{ModelPoints, add, add_s, auc, translation_error};
pub use score::{
    RECALL_REFERENCE_LEVEL, RECALL_THRESHOLD, llh, maad, recall_maad, recall_min_log_density,
};
pub use symmetry::{CONTINUOUS_STEPS, ContinuousSymmetry, SymmetryGroup};
