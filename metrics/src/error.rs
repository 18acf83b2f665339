use so3_grid::GridError;

/// Errors of the `ipdf-metrics` crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MetricsError {
    /// `cells` and `masses` have different lengths.
    #[error("{cells} cells but {masses} masses")]
    LengthMismatch {
        /// Number of cells.
        cells: usize,
        /// Number of masses.
        masses: usize,
    },
    /// A distribution with no cells.
    #[error("distribution has no cells")]
    Empty,
    /// A probability mass that is negative, NaN or infinite.
    #[error("mass of cell {position} is {value} (must be finite and ≥ 0)")]
    InvalidMass {
        /// Position of the cell in the distribution.
        position: usize,
        /// The offending value.
        value: f64,
    },
    /// Masses that do not sum to 1 (within [`crate::MASS_SUM_TOLERANCE`]).
    #[error("masses sum to {sum}, not 1")]
    MassSum {
        /// The sum of the masses.
        sum: f64,
    },
    /// The same cell twice in a mixed-level distribution.
    #[error("cell {index} of level {level} appears twice")]
    DuplicateCell {
        /// Grid level of the cell.
        level: u8,
        /// Cell index at that level.
        index: u64,
    },
    /// Mixed-level cells whose volumes do not add up to all of SO(3) (π²).
    #[error("cells cover a volume of {volume}, not π² ≈ 9.8696: they do not partition SO(3)")]
    NotAPartition {
        /// Total volume of the cells.
        volume: f64,
    },
    /// No cell contains a rotation (only for cells that do not partition SO(3)).
    #[error("no cell of the distribution contains ground-truth rotation {position}")]
    NotCovered {
        /// Position of the rotation in the ground-truth list.
        position: usize,
    },
    /// An empty set of ground-truth rotations.
    #[error("the ground-truth set is empty")]
    EmptyGroundTruth,
    /// A malformed symmetry entry (BOP `models_info.json` form).
    #[error("{field}: {reason}")]
    InvalidSymmetry {
        /// JSON path of the entry, e.g. `symmetries_discrete[2]`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A set of model points with no point.
    #[error("the model has no points")]
    NoModelPoints,
    /// A model point with a NaN or infinite coordinate.
    #[error("model point {position} is {coordinates:?} (coordinates must be finite)")]
    InvalidModelPoint {
        /// Position of the point in the given slice.
        position: usize,
        /// Its coordinates (x, y, z).
        coordinates: [f64; 3],
    },
    /// The k-d tree over the model points could not be built (more than 2³² points).
    #[error("cannot index the model points: {reason}")]
    ModelPointIndex {
        /// What the k-d tree reported.
        reason: String,
    },
    /// An empty list of pose errors.
    #[error("the list of pose errors is empty")]
    NoPoseErrors,
    /// A pose error that is negative, NaN or infinite.
    #[error("pose error {position} is {value} (must be finite and ≥ 0)")]
    InvalidPoseError {
        /// Position of the error in the list.
        position: usize,
        /// The offending value.
        value: f64,
    },
    /// An accuracy threshold that is not finite and positive.
    #[error("threshold is {value} (must be finite and > 0)")]
    InvalidThreshold {
        /// The offending value.
        value: f64,
    },
    /// A grid level, cell or rotation rejected by `so3-grid`.
    #[error(transparent)]
    Grid(#[from] GridError),
}
