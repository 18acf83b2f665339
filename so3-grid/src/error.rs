/// Errors of the `so3-grid` crate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GridError {
    /// The requested grid level is above what this crate builds.
    #[error("grid level {level} is out of range 0..={max}")]
    LevelOutOfRange {
        /// The level that was asked for.
        level: u8,
        /// The largest supported level ([`crate::MAX_LEVEL`]).
        max: u8,
    },
    /// A cell index is not below the number of cells of its level.
    #[error("cell index {index} is out of range for level {level} ({count} cells)")]
    CellOutOfRange {
        /// The grid level.
        level: u8,
        /// The offending index.
        index: u64,
        /// The number of cells at that level.
        count: u64,
    },
    /// A HEALPix pixel or ψ bin beyond its level's count (`12·4^level`, `6·2^level`).
    #[error("pixel {pixel} or bin {bin} is out of range for level {level}")]
    PartOutOfRange {
        /// The grid level.
        level: u8,
        /// The HEALPix pixel asked for.
        pixel: u64,
        /// The ψ bin asked for.
        bin: u64,
    },
    /// An input rotation or value contains NaN or an infinity.
    #[error("{what} is not finite")]
    NonFinite {
        /// What was not finite, e.g. `"rotation matrix"`.
        what: &'static str,
    },
    /// A 3×3 matrix is not a rotation (not orthonormal, or a reflection).
    #[error(
        "matrix is not a rotation: |RᵀR − I| = {orthogonality_error:.3e}, det = {determinant:.6}"
    )]
    NotARotation {
        /// Largest absolute entry of RᵀR − I.
        orthogonality_error: f64,
        /// The determinant (a rotation has +1).
        determinant: f64,
    },
    /// A rotation axis of zero length.
    #[error("rotation axis has zero length")]
    ZeroAxis,
}
