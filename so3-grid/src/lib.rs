//! Equivolumetric, hierarchical grids on the rotation group SO(3).
//!
//! The grid of Yershova et al. (2010), "Generating uniform incremental grids on SO(3) using the
//! Hopf fibration", as Implicit-PDF (Murphy et al., 2021) uses it: HEALPix pixel centres
//! (nested scheme, nside = 2^L) for the direction of the rotated z-axis, times `6·2^L` bin
//! centres of the rotation about it. The fibre angle is measured from the shortest-arc rotation
//! to each direction (from +ẑ for the northern and equatorial HEALPix base pixels, from −ẑ for
//! the southern ones), so every cell is compact (Euler-angle grids are not, at the poles) and
//! a rotation is never far from the centre of the cell containing it. Level L has `72·8^L` cells of equal volume `π²/72·8^L`
//! (level 2: 4,608; level 4: 294,912; level 5: 2,359,296).
//!
//! - [`Grid`]: the cell centres of one level, [`Grid::locate`] (the cell containing a
//!   rotation, O(1)) and [`Grid::nearest`] (exact nearest centre, branch and bound).
//! - Cells are numbered so that the 8 children of cell `i` are `8i..8i+8` at the next level
//!   ([`children`], [`parent`]): hierarchical refinement is index arithmetic.
//! - [`random_rotations`]: uniform random rotations, reproducible from a seed under rayon.
//! - [`geodesic_distance`] and checked conversions between matrices, axis-angle and
//!   quaternions (nalgebra types).
//!
//! ```
//! use so3_grid::{geodesic_distance, random_rotations, Grid};
//!
//! let grid = Grid::new(2)?;
//! assert_eq!(grid.len(), 4_608);
//! let rotations = grid.rotations();
//! let query = random_rotations(1, 7)[0];
//! let (cell, distance) = grid.nearest(&query)?;
//! assert!((geodesic_distance(&rotations[cell as usize], &query) - distance).abs() < 1e-9);
//! // The cell containing a rotation is one of the 8 children of the parent's containing cell.
//! let fine = Grid::new(3)?.locate(&query)?;
//! assert!(grid.children(grid.locate(&query)?)?.contains(&fine));
//! # Ok::<(), so3_grid::GridError>(())
//! ```

mod cell;
mod convert;
mod error;
mod grid;
mod hopf;
mod nearest;
mod random;

pub use cell::{MAX_LEVEL, cell_count, cell_index, cell_parts, cell_volume, children, parent};
pub use convert::{
    ORTHONORMALITY_TOLERANCE, PUBLISHED_ROTATION_TOLERANCE, geodesic_distance, orthogonality_error,
    rotation_from_axis_angle, rotation_from_matrix, rotation_from_wxyz, rotation_to_matrix,
    rotation_to_wxyz,
};
pub use error::GridError;
pub use grid::{Grid, locate};
pub use random::{random_rotation, random_rotations};
