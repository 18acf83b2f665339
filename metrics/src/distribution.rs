//! A probability distribution over SO(3) given as grid cells (one level, or mixed levels).
use std::collections::HashMap;

use nalgebra::UnitQuaternion;
use so3_grid::{Grid, cell_volume, locate};

use crate::MetricsError;

/// How far the masses may sum from 1 before they are rejected (they are then renormalised).
/// Generous enough for a float32 softmax over millions of cells.
pub const MASS_SUM_TOLERANCE: f64 = 1e-3;

/// One cell of an `so3-grid` grid: its level and index at that level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GridCell {
    /// Grid level (`72·8^level` cells).
    pub level: u8,
    /// Index of the cell at that level.
    pub index: u64,
}

/// Probability masses on cells that partition SO(3): all cells of one grid level (dense), or
/// cells of several levels as left by hierarchical refinement. Each cell has a centre rotation
/// and a volume (`π² / 72·8^level`); its density is `mass / volume`.
#[derive(Debug, Clone)]
pub struct Distribution {
    cells: Vec<GridCell>,
    rotations: Vec<UnitQuaternion<f64>>,
    masses: Vec<f64>,
    lookup: Lookup,
}

#[derive(Debug, Clone)]
enum Lookup {
    /// Cell `i` of the level is at position `i`.
    Dense(u8),
    /// Levels present (coarse first) and the position of every cell.
    Mixed(Vec<u8>, HashMap<GridCell, usize>),
}

impl Distribution {
    /// All cells of `grid`, in cell order, with these masses.
    pub fn dense(grid: &Grid, masses: Vec<f64>) -> Result<Self, MetricsError> {
        if masses.len() as u64 != grid.len() {
            return Err(MetricsError::LengthMismatch {
                cells: grid.len() as usize,
                masses: masses.len(),
            });
        }
        Ok(Self::on_grid(grid, normalised(masses)?))
    }

    /// The uniform distribution on `grid` (density `1/π²` everywhere).
    pub fn uniform(grid: &Grid) -> Self {
        let n = grid.len() as usize;
        Self::on_grid(grid, vec![1.0 / n as f64; n])
    }

    /// All cells of `grid` with masses already checked to be one per cell and normalised.
    fn on_grid(grid: &Grid, masses: Vec<f64>) -> Self {
        let level = grid.level();
        Self {
            cells: (0..grid.len())
                .map(|index| GridCell { level, index })
                .collect(),
            rotations: grid.rotations(),
            masses,
            lookup: Lookup::Dense(level),
        }
    }

    /// Cells of any levels that together partition SO(3), with their masses.
    ///
    /// Rejects duplicate cells and cells whose volumes do not add up to π² (which catches gaps
    /// and a cell listed together with its own descendants).
    pub fn from_cells(cells: Vec<GridCell>, masses: Vec<f64>) -> Result<Self, MetricsError> {
        if cells.len() != masses.len() {
            return Err(MetricsError::LengthMismatch {
                cells: cells.len(),
                masses: masses.len(),
            });
        }
        let masses = normalised(masses)?;
        let mut levels: Vec<u8> = cells.iter().map(|c| c.level).collect();
        levels.sort_unstable();
        levels.dedup();
        let grids = levels
            .iter()
            .map(|&level| Ok((level, Grid::new(level)?)))
            .collect::<Result<HashMap<_, _>, so3_grid::GridError>>()?;
        let mut positions = HashMap::with_capacity(cells.len());
        let mut rotations = Vec::with_capacity(cells.len());
        let mut volume = 0.0;
        for (position, cell) in cells.iter().enumerate() {
            rotations.push(grids[&cell.level].rotation(cell.index)?);
            if positions.insert(*cell, position).is_some() {
                return Err(MetricsError::DuplicateCell {
                    level: cell.level,
                    index: cell.index,
                });
            }
            volume += cell_volume(cell.level);
        }
        let full = std::f64::consts::PI.powi(2);
        if (volume - full).abs() > 1e-9 * full {
            return Err(MetricsError::NotAPartition { volume });
        }
        Ok(Self {
            cells,
            rotations,
            masses,
            lookup: Lookup::Mixed(levels, positions),
        })
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Always false: construction rejects empty distributions.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The cells, in the order they were given.
    pub fn cells(&self) -> &[GridCell] {
        &self.cells
    }

    /// Centre rotation of each cell.
    pub fn rotations(&self) -> &[UnitQuaternion<f64>] {
        &self.rotations
    }

    /// Probability mass of each cell (sums to 1).
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Volume of the cell at `position` (radians³, SO(3) has volume π²).
    pub fn volume(&self, position: usize) -> f64 {
        cell_volume(self.cells[position].level)
    }

    /// Position of the cell that contains `rotation`.
    pub fn containing(
        &self,
        rotation: &UnitQuaternion<f64>,
    ) -> Result<Option<usize>, MetricsError> {
        match &self.lookup {
            Lookup::Dense(level) => Ok(Some(locate(*level, rotation)? as usize)),
            Lookup::Mixed(levels, positions) => {
                for &level in levels {
                    let cell = GridCell {
                        level,
                        index: locate(level, rotation)?,
                    };
                    if let Some(&position) = positions.get(&cell) {
                        return Ok(Some(position));
                    }
                }
                Ok(None)
            }
        }
    }
}

fn normalised(mut masses: Vec<f64>) -> Result<Vec<f64>, MetricsError> {
    if masses.is_empty() {
        return Err(MetricsError::Empty);
    }
    if let Some((position, &value)) = masses
        .iter()
        .enumerate()
        .find(|(_, m)| !m.is_finite() || **m < 0.0)
    {
        return Err(MetricsError::InvalidMass { position, value });
    }
    let sum: f64 = masses.iter().sum();
    if (sum - 1.0).abs() > MASS_SUM_TOLERANCE {
        return Err(MetricsError::MassSum { sum });
    }
    masses.iter_mut().for_each(|m| *m /= sum);
    Ok(masses)
}
