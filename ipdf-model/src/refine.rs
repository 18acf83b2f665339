//! Hierarchical evaluation of a density on the `so3-grid` hierarchy: evaluate a coarse level,
//! keep the cells holding most of the mass, evaluate only their children, and so on.
use so3_grid::{MAX_LEVEL, cell_count, cell_volume, children};

use crate::ModelError;

/// Probability masses on grid cells of one or several levels that together partition SO(3).
#[derive(Debug, Clone, PartialEq)]
pub struct CellMasses {
    /// `(level, index)` of each cell.
    pub cells: Vec<(u8, u64)>,
    /// The probability mass of each cell; they sum to 1.
    pub masses: Vec<f64>,
    /// How many rotations the density was evaluated at.
    pub queries: usize,
}

impl CellMasses {
    /// Positions of the `count` cells of highest density (mass / volume), densest first.
    pub fn densest(&self, count: usize) -> Vec<usize> {
        let density = |i: usize| self.masses[i] / cell_volume(self.cells[i].0);
        let mut order: Vec<usize> = (0..self.cells.len()).collect();
        order.sort_by(|&a, &b| density(b).total_cmp(&density(a)));
        order.truncate(count);
        order
    }
}

/// Options of [`refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// The level evaluated densely first (2: 4,608 cells).
    pub start_level: u8,
    /// The finest level.
    pub level: u8,
    /// Refine the densest cells that together hold this fraction of the mass (1: all)…
    pub keep_mass: f64,
    /// …but at most this many cells per level (each refined cell costs 8 queries).
    pub max_cells: usize,
}

impl Default for RefineOptions {
    /// Level 2 to level 4, refining up to 576 cells per level holding 99.99% of the mass: at
    /// most 4,608 + 2 · 4,608 = 13,824 queries, 21× fewer than the 294,912 of dense level 4.
    fn default() -> Self {
        Self {
            start_level: 2,
            level: 4,
            keep_mass: 0.9999,
            max_cells: 576,
        }
    }
}

impl RefineOptions {
    /// Checks levels and budgets.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.start_level > self.level || self.level > MAX_LEVEL {
            return Err(ModelError::option(
                "level",
                format!(
                    "start level {} to level {}: need start ≤ level ≤ {MAX_LEVEL}",
                    self.start_level, self.level
                ),
            ));
        }
        if self.start_level > 4 {
            return Err(ModelError::option(
                "start_level",
                format!("{}: the dense start goes up to level 4", self.start_level),
            ));
        }
        if !(self.keep_mass > 0.0 && self.keep_mass <= 1.0) || self.max_cells == 0 {
            return Err(ModelError::option(
                "keep_mass",
                format!(
                    "keep_mass {} and max_cells {}: need (0, 1] and ≥ 1",
                    self.keep_mass, self.max_cells
                ),
            ));
        }
        Ok(())
    }
}

/// The distribution of an unnormalised log-density `log_density(level, cells) → F` (one value
/// per cell centre), refined from `options.start_level` to `options.level`. Unrefined cells keep
/// their coarse mass `exp F · volume`; all masses are normalised together at the end. When every
/// cell holding mass is refined this equals the dense evaluation at `options.level`.
pub fn refine<F>(mut log_density: F, options: &RefineOptions) -> Result<CellMasses, ModelError>
where
    F: FnMut(u8, &[u64]) -> Result<Vec<f64>, ModelError>,
{
    options.validate()?;
    let mut level = options.start_level;
    let mut active: Vec<u64> = (0..cell_count(level)).collect();
    let mut scores = log_density(level, &active)?;
    let mut queries = active.len();
    // Frozen cells: (level, index, log mass).
    let mut frozen: Vec<(u8, u64, f64)> = Vec::new();
    while level < options.level {
        let log_volume = cell_volume(level).ln();
        let mut order: Vec<usize> = (0..active.len()).collect();
        order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
        let log_masses: Vec<f64> = order.iter().map(|&i| scores[i] + log_volume).collect();
        let frozen_log_masses = frozen.iter().map(|c| c.2);
        let log_total = log_sum_exp(log_masses.iter().copied().chain(frozen_log_masses));
        let mut kept = 0;
        let mut cumulative = 0.0;
        while kept < order.len().min(options.max_cells)
            && (kept == 0 || options.keep_mass >= 1.0 || cumulative < options.keep_mass)
        {
            cumulative += (log_masses[kept] - log_total).exp();
            kept += 1;
        }
        frozen.extend(
            order[kept..]
                .iter()
                .zip(&log_masses[kept..])
                .map(|(&i, &m)| (level, active[i], m)),
        );
        let mut next = Vec::with_capacity(8 * kept);
        for &i in &order[..kept] {
            next.extend(children(level, active[i])?);
        }
        next.sort_unstable();
        level += 1;
        scores = log_density(level, &next)?;
        queries += next.len();
        active = next;
    }
    let log_volume = cell_volume(level).ln();
    frozen.extend(
        active
            .iter()
            .zip(&scores)
            .map(|(&index, &score)| (level, index, score + log_volume)),
    );
    let log_total = log_sum_exp(frozen.iter().map(|c| c.2));
    Ok(CellMasses {
        cells: frozen.iter().map(|c| (c.0, c.1)).collect(),
        masses: frozen.iter().map(|c| (c.2 - log_total).exp()).collect(),
        queries,
    })
}

/// `ln Σ exp(x)`, stable; `−∞` for no terms.
pub(crate) fn log_sum_exp(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let max = values.clone().fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return max;
    }
    max + values.map(|v| (v - max).exp()).sum::<f64>().ln()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;
    use so3_grid::{Grid, geodesic_distance};

    fn peaked(level: u8, cells: &[u64], centre: &UnitQuaternion<f64>) -> Vec<f64> {
        let grid = Grid::new(level).unwrap();
        cells
            .iter()
            .map(|&i| -20.0 * geodesic_distance(&grid.rotation(i).unwrap(), centre).powi(2))
            .collect()
    }

    #[test]
    fn refining_everything_equals_the_dense_level() {
        let centre = UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1);
        let options = RefineOptions {
            start_level: 0,
            level: 1,
            keep_mass: 1.0,
            max_cells: usize::MAX,
        };
        let refined = refine(|l, c| Ok(peaked(l, c, &centre)), &options).unwrap();
        let dense = peaked(1, &(0..576).collect::<Vec<_>>(), &centre);
        let total = log_sum_exp(dense.iter().copied());
        assert_eq!(refined.cells.len(), 576);
        for ((level, index), mass) in refined.cells.iter().zip(&refined.masses) {
            assert_eq!(*level, 1);
            assert!((mass - (dense[*index as usize] - total).exp()).abs() < 1e-12);
        }
    }

    #[test]
    fn budget_bounds_the_queries_and_masses_sum_to_one() {
        let centre = UnitQuaternion::identity();
        let options = RefineOptions {
            start_level: 1,
            level: 3,
            keep_mass: 0.99,
            max_cells: 10,
        };
        let refined = refine(|l, c| Ok(peaked(l, c, &centre)), &options).unwrap();
        assert!(refined.queries <= 576 + 2 * 80);
        assert!((refined.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let densest = refined.densest(1)[0];
        assert_eq!(refined.cells[densest].0, 3);
    }
}
