//! The crate's one error type.

/// Everything that can go wrong in this crate: bad input clouds, bad options, singular solves.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RegistrationError {
    /// A cloud with no points where points are needed.
    #[error("the {cloud} cloud is empty")]
    EmptyCloud {
        /// Which cloud (`"source"`, `"target"`, `"input"`).
        cloud: &'static str,
    },
    /// Fewer points than a stage needs (a neighbourhood, a tuple, a pose).
    #[error("{stage} needs at least {needed} points, got {got}")]
    TooFewPoints {
        /// The stage that needs them.
        stage: &'static str,
        /// How many it needs.
        needed: usize,
        /// How many there are.
        got: usize,
    },
    /// A NaN or infinite coordinate.
    #[error("{field}[{index}] is not finite")]
    NonFinite {
        /// `"points"` or `"normals"`.
        field: &'static str,
        /// Index of the offending entry.
        index: usize,
    },
    /// Normals given for a different number of points.
    #[error("{normals} normals for {points} points")]
    NormalCount {
        /// Number of points.
        points: usize,
        /// Number of normals.
        normals: usize,
    },
    /// A stage that needs normals got a cloud without them.
    #[error("{stage} needs normals; estimate them first")]
    MissingNormals {
        /// The stage.
        stage: &'static str,
    },
    /// An option outside its valid range.
    #[error("option {name} = {value} is invalid: {reason}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        reason: &'static str,
    },
    /// All points (nearly) on a line or a plane: normals or the pose are not unique.
    #[error("the {cloud} cloud is degenerate: its points are {shape}, so the pose is not unique")]
    Degenerate {
        /// Which cloud.
        cloud: &'static str,
        /// `"collinear"` or `"coplanar"`.
        shape: &'static str,
    },
    /// Feature matching or ICP found too few correspondences to solve for a pose.
    #[error("{stage} found {found} correspondences, needs at least {needed}")]
    NoCorrespondences {
        /// `"feature matching"`, `"tuple test"` or `"ICP"`.
        stage: &'static str,
        /// How many it found.
        found: usize,
        /// How many it needs.
        needed: usize,
    },
    /// The normal equations of a pose update were singular or not finite.
    #[error("{stage}: the pose update is not unique (singular normal equations)")]
    SingularSystem {
        /// The stage.
        stage: &'static str,
    },
}

/// `value` if it is a positive, finite length in metres; else `InvalidOption` naming `name`.
pub(crate) fn positive_metres(name: &'static str, value: f32) -> Result<f32, RegistrationError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(RegistrationError::InvalidOption {
            name,
            value: f64::from(value),
            reason: "must be a positive number of metres",
        })
    }
}

/// `count` if it is at least 1; else `InvalidOption` naming `name`.
pub(crate) fn at_least_one(
    name: &'static str,
    count: usize,
) -> Result<std::num::NonZeroUsize, RegistrationError> {
    std::num::NonZeroUsize::new(count).ok_or(RegistrationError::InvalidOption {
        name,
        value: 0.0,
        reason: "must be at least 1",
    })
}
