//! The three scores of Implicit-PDF and of the pseudo-label paper, on a [`Distribution`].
use nalgebra::UnitQuaternion;
use so3_grid::cell_volume;

use crate::nearest::nearest_distances;
use crate::{Distribution, MetricsError};

/// Default probability-mass threshold of [`recall_maad`] (per level-4 cell).
pub const RECALL_THRESHOLD: f64 = 1e-3;

/// The level whose cell volume [`recall_maad`] rescales masses to.
pub const RECALL_REFERENCE_LEVEL: u8 = 4;

/// Log-likelihood: the mean over `gt_rotations` of `ln(mass / volume)` of the cell containing
/// each rotation, the log of the distribution's density there. A uniform distribution scores
/// `−ln π² ≈ −2.29`; a cell with zero mass scores `−∞`.
pub fn llh(dist: &Distribution, gt_rotations: &[UnitQuaternion<f64>]) -> Result<f64, MetricsError> {
    if gt_rotations.is_empty() {
        return Err(MetricsError::EmptyGroundTruth);
    }
    let mut total = 0.0;
    for (position, rotation) in gt_rotations.iter().enumerate() {
        let cell = dist
            .containing(rotation)?
            .ok_or(MetricsError::NotCovered { position })?;
        total += (dist.masses()[cell] / dist.volume(cell)).ln();
    }
    Ok(total / gt_rotations.len() as f64)
}

/// Mean absolute angular deviation, in degrees: `Σ_cells mass · min_{g ∈ gt_set} d(cell, g)`,
/// the expected distance of a sample from the distribution to the nearest ground-truth
/// rotation (Murphy et al. 2021, §5). 0 for all mass on the set; ≈ 126.5° for a uniform
/// distribution against one rotation.
pub fn maad(dist: &Distribution, gt_set: &[UnitQuaternion<f64>]) -> Result<f64, MetricsError> {
    if gt_set.is_empty() {
        return Err(MetricsError::EmptyGroundTruth);
    }
    let distances = nearest_distances(dist.rotations(), gt_set);
    let total: f64 = distances
        .iter()
        .zip(dist.masses())
        .map(|(d, m)| d * m)
        .sum();
    Ok(total.to_degrees())
}

/// The log density (`ln(mass / volume)`, as [`llh`] measures it) a cell needs to enter
/// [`recall_maad`]'s predicted set at `threshold`: `ln(threshold / V₄)`. At the default 1e-3 it
/// is ≈ 3.40, 295× the uniform density, so a Recall MAAD of a few degrees needs about that
/// density along the whole ground-truth set.
pub fn recall_min_log_density(threshold: f64) -> f64 {
    (threshold / cell_volume(RECALL_REFERENCE_LEVEL)).ln()
}

/// Recall MAAD, in degrees: the mean over `gt_set` of the distance from each ground-truth
/// rotation to the nearest *predicted* rotation, where the predicted set is every cell whose
/// mass, rescaled to the volume of a level-4 cell (`mass · V₄ / V_cell`, so that refining a
/// cell does not change it), exceeds `threshold`. When no cell does, the predicted set is the
/// single most probable cell.
pub fn recall_maad(
    dist: &Distribution,
    gt_set: &[UnitQuaternion<f64>],
    threshold: f64,
) -> Result<f64, MetricsError> {
    if gt_set.is_empty() {
        return Err(MetricsError::EmptyGroundTruth);
    }
    let reference = cell_volume(RECALL_REFERENCE_LEVEL);
    let mut predicted: Vec<UnitQuaternion<f64>> = (0..dist.len())
        .filter(|&i| dist.masses()[i] * reference / dist.volume(i) > threshold)
        .map(|i| dist.rotations()[i])
        .collect();
    if predicted.is_empty() {
        let densest = (0..dist.len())
            .max_by(|&a, &b| {
                let density = |i: usize| dist.masses()[i] / dist.volume(i);
                density(a).total_cmp(&density(b))
            })
            .ok_or(MetricsError::Empty)?;
        predicted.push(dist.rotations()[densest]);
    }
    let distances = nearest_distances(gt_set, &predicted);
    Ok((distances.iter().sum::<f64>() / gt_set.len() as f64).to_degrees())
}
