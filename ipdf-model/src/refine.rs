//! Hierarchical evaluation of a density on a hierarchy of cells (the `so3-grid` hierarchy of
//! SO(3), or the octree of a translation volume): evaluate a coarse level, keep the cells
//! holding most of the mass, evaluate only their children, and so on.
use std::collections::HashMap;
use std::sync::OnceLock;

use nalgebra::{Matrix4, UnitQuaternion, Vector3, Vector4};
use so3_grid::{Grid, MAX_LEVEL, cell_count, cell_volume, geodesic_distance};

use crate::ModelError;

/// A hierarchy of cells that [`refine_on`] refines: level `l` has `cell_count(l)` cells of
/// equal volume, and cell `i` of level `l` has the 8 children `8i..8i + 8` at level `l + 1`.
pub trait CellHierarchy {
    /// The finest level.
    fn max_level(&self) -> u8;
    /// The finest level [`refine_on`] may evaluate densely as its start.
    fn max_dense_level(&self) -> u8;
    /// The number of cells of `level`.
    fn cell_count(&self, level: u8) -> u64;
    /// The volume of one cell of `level` (SO(3): of π² in all; a translation volume: mm³).
    fn cell_volume(&self, level: u8) -> f64;
    /// The radius of the ball holding one cell's volume, in the coordinates of
    /// [`CellHierarchy::sibling_offsets`].
    fn ball_radius(&self, level: u8) -> f64;
    /// The centres of cells `first..first + 8` of `level` (siblings) relative to the first,
    /// in local Euclidean coordinates (SO(3): rotation vectors, radians; translations: mm).
    fn sibling_offsets(&self, level: u8, first: u64) -> Result<[Vector3<f64>; 8], ModelError>;
}

/// The `so3-grid` hierarchy of SO(3) (level 0: 72 cells).
#[derive(Debug, Clone, Copy, Default)]
pub struct So3Cells;

impl CellHierarchy for So3Cells {
    fn max_level(&self) -> u8 {
        MAX_LEVEL
    }

    /// Level 4 (294,912 cells).
    fn max_dense_level(&self) -> u8 {
        4
    }

    fn cell_count(&self, level: u8) -> u64 {
        cell_count(level)
    }

    fn cell_volume(&self, level: u8) -> f64 {
        cell_volume(level)
    }

    /// SO(3)'s volume element is `d³ω / 8` near a point, so the ball of rotation vectors holding
    /// a cell's volume `V` has radius `(6V / π)^⅓`.
    fn ball_radius(&self, level: u8) -> f64 {
        (6.0 * cell_volume(level) / std::f64::consts::PI).cbrt()
    }

    fn sibling_offsets(&self, level: u8, first: u64) -> Result<[Vector3<f64>; 8], ModelError> {
        let grid = cached_grid(level)?;
        let origin = grid.rotation(first)?.inverse();
        let mut offsets = [Vector3::zeros(); 8];
        for (k, offset) in offsets.iter_mut().enumerate() {
            *offset = (origin * grid.rotation(first + k as u64)?).scaled_axis();
        }
        Ok(offsets)
    }
}

/// Probability masses on grid cells of one or several levels that together partition SO(3).
#[derive(Debug, Clone, PartialEq)]
pub struct CellMasses {
    /// `(level, index)` of each cell.
    pub cells: Vec<(u8, u64)>,
    /// The probability mass of each cell; they sum to 1.
    pub masses: Vec<f64>,
    /// How many rotations the density was evaluated at.
    pub queries: usize,
    /// `ln Z`, `Z ≈ ∫ exp(F)` over SO(3): the normaliser of `F`, so that the density at any
    /// rotation `R` is `exp(F(R) − ln Z)` (see `Predictor::log_densities`). Refined cells count
    /// `exp F · volume` (the dense grid's midpoint rule); cells left coarse count it corrected
    /// for the slope of `F` across them (see [`refine`]).
    pub log_normaliser: f64,
}

impl CellMasses {
    /// Positions of the `count` cells of highest density (mass / volume) on SO(3), densest
    /// first.
    pub fn densest(&self, count: usize) -> Vec<usize> {
        self.densest_in(&So3Cells, count)
    }

    /// Up to `count` rotations these masses (of SO(3) cells) make likely, spread apart: `first`
    /// (the most likely rotation), then the centres of the densest cells, densest first, each
    /// at least `min_angle` radians from every rotation chosen before it. The starts of a pose
    /// search that the image narrows and another cue (the frame's depth) decides.
    pub fn rotation_hypotheses(
        &self,
        first: UnitQuaternion<f64>,
        count: usize,
        min_angle: f64,
    ) -> Result<Vec<UnitQuaternion<f64>>, ModelError> {
        let mut chosen = Vec::with_capacity(count);
        if count == 0 {
            return Ok(chosen);
        }
        chosen.push(first);
        for position in self.densest(self.cells.len()) {
            if chosen.len() == count {
                break;
            }
            let (level, index) = self.cells[position];
            let rotation = cached_grid(level)?.rotation(index)?;
            if chosen
                .iter()
                .all(|c| geodesic_distance(c, &rotation) >= min_angle)
            {
                chosen.push(rotation);
            }
        }
        Ok(chosen)
    }

    /// The rotation whose ball of `radius` radians holds the most of these masses (of SO(3)
    /// cells): among the centres of the `candidates` densest cells, the one whose ball holds the
    /// most mass, each cell counted whole where its centre lies within the ball. Where the
    /// rotation is judged right within an angle (Acc@15°), the centre of the heaviest ball of
    /// that angle is the estimate most likely right (the Bayes estimate for that loss); the
    /// argmax is where one narrow peak rises highest, which on an uncertain image may hold
    /// less mass than a wider one beside it.
    pub fn heaviest_ball(
        &self,
        radius: f64,
        candidates: usize,
    ) -> Result<HeaviestBall, ModelError> {
        if !(radius > 0.0 && radius <= std::f64::consts::PI) || candidates == 0 {
            let reason = format!(
                "a ball of {radius} rad among {candidates} candidates: need a radius in (0, π] \
                 and at least one candidate"
            );
            return Err(ModelError::option("radius", reason));
        }
        let mut centres = Vec::with_capacity(self.cells.len());
        for &(level, index) in &self.cells {
            centres.push(cached_grid(level)?.rotation(index)?);
        }
        // Within the ball: angle ≤ radius, i.e. |q·c| ≥ cos(radius / 2).
        let cos_half = (radius / 2.0).cos();
        let mut best: Option<HeaviestBall> = None;
        for position in self.densest(candidates) {
            let centre = centres[position];
            let mass: f64 = centres
                .iter()
                .zip(&self.masses)
                .filter(|(q, _)| q.coords.dot(&centre.coords).abs() >= cos_half)
                .map(|(_, m)| m)
                .sum();
            if best.as_ref().is_none_or(|b| mass > b.mass) {
                best = Some(HeaviestBall {
                    rotation: centre,
                    mass,
                });
            }
        }
        best.ok_or_else(|| ModelError::option("masses", "no cells to choose from"))
    }

    /// Positions of the `count` cells of highest density (mass / volume) in `hierarchy`,
    /// densest first.
    pub fn densest_in(&self, hierarchy: &impl CellHierarchy, count: usize) -> Vec<usize> {
        let density = |i: usize| self.masses[i] / hierarchy.cell_volume(self.cells[i].0);
        let mut order: Vec<usize> = (0..self.cells.len()).collect();
        order.sort_by(|&a, &b| density(b).total_cmp(&density(a)));
        order.truncate(count);
        order
    }
}

/// The rotation [`CellMasses::heaviest_ball`] picks and the mass of its ball.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeaviestBall {
    /// The ball's centre: the centre of one of the densest cells.
    pub rotation: UnitQuaternion<f64>,
    /// The probability mass of the cells whose centres lie within the ball.
    pub mass: f64,
}

/// Options of [`refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// The level evaluated densely first (2: 4,608 cells).
    pub start_level: u8,
    /// The finest level.
    pub level: u8,
    /// Refinement stops once the cells coarser than `level` hold less than `1 − keep_mass` of
    /// the mass (1: refine everything down to `level`)…
    pub keep_mass: f64,
    /// …or when refining another cell (8 queries) would exceed this many queries in all.
    pub max_queries: usize,
}

impl Default for RefineOptions {
    /// Level 2 to level 4 until 99.99% of the mass is at level 4, in at most 14,336 queries
    /// (4,608 for level 2, then 1,216 refined cells): 20.6× fewer than the 294,912 of dense
    /// level 4. The same as [`RefineOptions::to_level`]`(4)`.
    fn default() -> Self {
        Self::to_level(4)
    }
}

impl RefineOptions {
    /// Level 2 refined down to `level` until 99.99% of the mass is there, in at most
    /// `4,608 + 4,864 · (level − 2)` queries (608 refined cells per level below 2: the mass of
    /// a trained model sits in about as many cells at every level). Levels 0–2 are evaluated
    /// densely.
    ///
    /// ```
    /// use ipdf_model::RefineOptions;
    /// assert_eq!(RefineOptions::to_level(4).max_queries, 14_336);
    /// assert_eq!(RefineOptions::to_level(5).max_queries, 19_200);
    /// ```
    pub fn to_level(level: u8) -> Self {
        let start_level = level.min(2);
        Self {
            start_level,
            level,
            keep_mass: 0.9999,
            max_queries: cell_count(start_level) as usize
                + 4_864 * usize::from(level - start_level),
        }
    }

    /// Every cell of the `level` grid (dense up to level 4; from level 4 down for finer ones):
    /// the reference the hierarchical evaluation approximates.
    pub fn dense(level: u8) -> Self {
        Self {
            start_level: level.min(4),
            level,
            keep_mass: 1.0,
            max_queries: usize::MAX,
        }
    }

    /// Checks levels and budgets on SO(3).
    pub fn validate(&self) -> Result<(), ModelError> {
        self.validate_for(&So3Cells)
    }

    /// Checks levels and budgets on `hierarchy`.
    pub fn validate_for(&self, hierarchy: &impl CellHierarchy) -> Result<(), ModelError> {
        let max = hierarchy.max_level();
        if self.start_level > self.level || self.level > max {
            return Err(ModelError::option(
                "level",
                format!(
                    "start level {} to level {}: need start ≤ level ≤ {max}",
                    self.start_level, self.level
                ),
            ));
        }
        let dense = hierarchy.max_dense_level();
        if self.start_level > dense {
            return Err(ModelError::option(
                "start_level",
                format!(
                    "{}: the dense start goes up to level {dense}",
                    self.start_level
                ),
            ));
        }
        if !(self.keep_mass > 0.0 && self.keep_mass <= 1.0) {
            return Err(ModelError::option(
                "keep_mass",
                format!("{}: need a fraction in (0, 1]", self.keep_mass),
            ));
        }
        let start_cells = hierarchy.cell_count(self.start_level) as usize;
        if self.max_queries < start_cells {
            return Err(ModelError::option(
                "max_queries",
                format!(
                    "{}: the dense start alone takes {start_cells}",
                    self.max_queries
                ),
            ));
        }
        Ok(())
    }
}

/// The fewest cells refined per round (512 queries); a round refines half of what the
/// remaining budget affords when that is more, so that a budget takes a few large rounds.
const MIN_ROUND: usize = 64;

/// A cell of the current partition: `(level, index, ln(exp F · volume))`.
type Leaf = (u8, u64, f64);

/// [`refine_on`] the SO(3) hierarchy of `so3-grid`.
pub fn refine<F>(log_density: F, options: &RefineOptions) -> Result<CellMasses, ModelError>
where
    F: FnMut(u8, &[u64]) -> Result<Vec<f64>, ModelError>,
{
    refine_on(&So3Cells, log_density, options)
}

/// The distribution of an unnormalised log-density `log_density(level, cells) → F` (one value
/// per cell centre) on the cells of `hierarchy`, refined best-first from a dense `options.start_level` grid: each round
/// replaces the heaviest cells coarser than `options.level` (see `MIN_ROUND`) by their 8
/// children,
/// until those coarse cells hold less than `1 − keep_mass` of the mass or the query budget is
/// spent. Unrefined cells keep their coarse mass `exp F · volume`; all masses are normalised
/// together at the end. When every cell is refined this equals the dense evaluation at
/// `options.level`.
///
/// The normaliser corrects what the centre value misses on a cell left coarse: `exp` is convex,
/// so where `F` slopes across a cell its mean exceeds `exp F(centre)` (on the demo's can models
/// this undercounted `Z` by up to 3%, against dense level 4). See `slope_factor`.
pub fn refine_on<H, F>(
    hierarchy: &H,
    mut log_density: F,
    options: &RefineOptions,
) -> Result<CellMasses, ModelError>
where
    H: CellHierarchy,
    F: FnMut(u8, &[u64]) -> Result<Vec<f64>, ModelError>,
{
    options.validate_for(hierarchy)?;
    let mut state = Refinement::default();
    let start = options.start_level;
    let cells: Vec<u64> = (0..hierarchy.cell_count(start)).collect();
    state.evaluate(hierarchy, &mut log_density, start, cells)?;
    while let Some(heaviest) = cells_to_split(&state.leaves, options, state.queries) {
        for (level, cells) in split(&mut state.leaves, heaviest) {
            state.evaluate(hierarchy, &mut log_density, level, cells)?;
        }
    }
    let Refinement {
        leaves,
        evaluated,
        queries,
    } = state;
    let log_total = log_sum_exp(leaves.iter().map(|leaf| leaf.2));
    let log_factors = coarse_log_factors(hierarchy, &leaves, &evaluated, options.level, log_total)?;
    let log_normaliser = log_sum_exp(
        leaves
            .iter()
            .zip(&log_factors)
            .map(|(leaf, factor)| leaf.2 + factor),
    );
    Ok(CellMasses {
        cells: leaves.iter().map(|leaf| (leaf.0, leaf.1)).collect(),
        masses: leaves
            .iter()
            .map(|leaf| (leaf.2 - log_total).exp())
            .collect(),
        queries,
        log_normaliser,
    })
}

/// What [`refine_on`] has evaluated so far: the leaves (cells not split) with their log-mass,
/// `F` at every cell evaluated, and the number of queries.
#[derive(Default)]
struct Refinement {
    leaves: Vec<Leaf>,
    evaluated: HashMap<(u8, u64), f64>,
    queries: usize,
}

impl Refinement {
    /// Evaluates `cells` of `level` and adds them as leaves.
    fn evaluate<H, F>(
        &mut self,
        hierarchy: &H,
        log_density: &mut F,
        level: u8,
        cells: Vec<u64>,
    ) -> Result<(), ModelError>
    where
        H: CellHierarchy,
        F: FnMut(u8, &[u64]) -> Result<Vec<f64>, ModelError>,
    {
        let scores = log_density(level, &cells)?;
        let log_volume = hierarchy.cell_volume(level).ln();
        self.queries += cells.len();
        self.evaluated
            .extend(cells.iter().zip(&scores).map(|(&c, &f)| ((level, c), f)));
        self.leaves.extend(
            cells
                .iter()
                .zip(&scores)
                .map(|(&index, &score)| (level, index, score + log_volume)),
        );
        Ok(())
    }
}

/// The positions in `leaves` of the next round's cells to split, in increasing order: the
/// heaviest leaves coarser than `options.level`, as many as half the queries left afford (at
/// least `MIN_ROUND`); `None` when none is left, the budget is spent, or the coarse leaves
/// hold less than `1 − keep_mass` of the mass.
fn cells_to_split(leaves: &[Leaf], options: &RefineOptions, queries: usize) -> Option<Vec<usize>> {
    let log_total = log_sum_exp(leaves.iter().map(|leaf| leaf.2));
    let mut coarse: Vec<usize> = (0..leaves.len())
        .filter(|&i| leaves[i].0 < options.level)
        .collect();
    let coarse_mass: f64 = coarse
        .iter()
        .map(|&i| (leaves[i].2 - log_total).exp())
        .sum();
    let affordable = (options.max_queries - queries) / 8;
    if coarse.is_empty() || affordable == 0 || coarse_mass < 1.0 - options.keep_mass {
        return None;
    }
    let round = (affordable / 2).max(MIN_ROUND).min(affordable);
    if round < coarse.len() {
        coarse.select_nth_unstable_by(round, |&a, &b| {
            leaves[b].2.total_cmp(&leaves[a].2).then(a.cmp(&b))
        });
        coarse.truncate(round);
    }
    coarse.sort_unstable();
    Some(coarse)
}

/// Removes the leaves at `positions` (increasing) and returns their children, grouped by level
/// and sorted within each group, in the order the groups were first met from the end.
fn split(leaves: &mut Vec<Leaf>, positions: Vec<usize>) -> Vec<(u8, Vec<u64>)> {
    let mut by_level: Vec<(u8, Vec<u64>)> = Vec::new();
    for &i in positions.iter().rev() {
        let (level, index, _) = leaves.swap_remove(i);
        let children = index * 8..index * 8 + 8;
        match by_level.iter_mut().find(|(l, _)| *l == level + 1) {
            Some((_, cells)) => cells.extend(children),
            None => by_level.push((level + 1, children.collect())),
        }
    }
    for (_, cells) in &mut by_level {
        cells.sort_unstable();
    }
    by_level
}

/// `ln` of [`slope_factor`] for each leaf coarser than `level` (0 for the others, for cells of
/// level 0, which have no parent, and for groups of siblings too light to matter: at most
/// `e^-30` of the total `e^log_total` even at their highest value).
fn coarse_log_factors(
    hierarchy: &impl CellHierarchy,
    leaves: &[Leaf],
    evaluated: &HashMap<(u8, u64), f64>,
    level: u8,
    log_total: f64,
) -> Result<Vec<f64>, ModelError> {
    // Per group of siblings (level, first index): its slope and highest `F`.
    let mut groups: HashMap<(u8, u64), Option<(f64, f64)>> = HashMap::new();
    let mut factors = Vec::with_capacity(leaves.len());
    for &(cell_level, index, log_mass) in leaves {
        if cell_level >= level || cell_level == 0 {
            factors.push(0.0);
            continue;
        }
        let first = index / 8 * 8;
        let group = match groups.get(&(cell_level, first)) {
            Some(&group) => group,
            None => {
                let own = evaluated[&(cell_level, index)];
                let highest = (first..first + 8)
                    .filter_map(|sibling| evaluated.get(&(cell_level, sibling)))
                    .fold(own, |max, &f| max.max(f));
                let negligible = log_mass + (highest - own) < log_total - 30.0;
                let group = if negligible {
                    None
                } else {
                    sibling_slope(hierarchy, cell_level, first, evaluated)?
                        .map(|slope| (slope, highest))
                };
                groups.insert((cell_level, first), group);
                group
            }
        };
        let factor = match group {
            Some((slope, highest)) => {
                let own = evaluated[&(cell_level, index)];
                slope_factor(slope, hierarchy.ball_radius(cell_level), highest - own)
            }
            None => 1.0,
        };
        factors.push(factor.ln());
    }
    Ok(factors)
}

/// The grid of `level`, built once per process (levels up to 4 take under a millisecond and
/// 100 kB; the refinement asks only for levels coarser than its target).
fn cached_grid(level: u8) -> Result<&'static Grid, ModelError> {
    static GRIDS: [OnceLock<Grid>; MAX_LEVEL as usize + 1] =
        [const { OnceLock::new() }; MAX_LEVEL as usize + 1];
    let slot = &GRIDS[usize::from(level.min(MAX_LEVEL))];
    if let Some(grid) = slot.get() {
        return Ok(grid);
    }
    let grid = Grid::new(level)?;
    Ok(slot.get_or_init(|| grid))
}

/// `|∇F|` (per unit of the hierarchy's local coordinates) of the least-squares plane
/// `F ≈ a + g · x` through the 8 cells `first..first + 8` of `level` (siblings: the children of
/// one parent), `x` a cell's offset from the first (SO(3): rotation vectors); `None` unless all 8
/// were evaluated.
fn sibling_slope(
    hierarchy: &impl CellHierarchy,
    level: u8,
    first: u64,
    evaluated: &HashMap<(u8, u64), f64>,
) -> Result<Option<f64>, ModelError> {
    let mut values = [0.0; 8];
    for (k, value) in values.iter_mut().enumerate() {
        let Some(&f) = evaluated.get(&(level, first + k as u64)) else {
            return Ok(None);
        };
        *value = f;
    }
    let offsets = hierarchy.sibling_offsets(level, first)?;
    let (mut normal, mut rhs) = (Matrix4::<f64>::zeros(), Vector4::<f64>::zeros());
    for (offset, f) in offsets.iter().zip(values) {
        let row = Vector4::new(1.0, offset.x, offset.y, offset.z);
        normal += row * row.transpose();
        rhs += row * f;
    }
    Ok(normal
        .try_inverse()
        .map(|inverse| (inverse * rhs).fixed_rows::<3>(1).norm()))
}

/// The mean of `exp F` over a cell relative to `exp F(centre)` when `F` rises with slope `slope`
/// across it: `1 + |g|² ρ² / 10` (the second-order term of the mean over a ball of radius `ρ`
/// holding the cell's volume, [`CellHierarchy::ball_radius`]), capped at `exp(rise)`, the
/// highest value among the cell's siblings, so that a steep slope in the tail far from any mass
/// cannot inflate the cell past what its neighbourhood holds.
/// On the quick pipeline's trained models this takes the gap between this normaliser and
/// dense level 4's from 0.0004–0.028 nats to 0.0002–0.0044 (`examples/ipdf/examples/refine_accuracy.rs`).
fn slope_factor(slope: f64, radius: f64, rise: f64) -> f64 {
    let second_order = 1.0 + (slope * radius).powi(2) / 10.0;
    second_order.min(rise.exp().max(1.0))
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
    use proptest::prelude::*;

    /// Masses on every cell of `level` in proportion to `weights` (one per cell).
    fn masses_on(level: u8, weights: &[f64]) -> CellMasses {
        let total: f64 = weights.iter().sum::<f64>() + 1e-9;
        CellMasses {
            cells: (0..weights.len() as u64).map(|i| (level, i)).collect(),
            masses: weights.iter().map(|w| w / total).collect(),
            queries: weights.len(),
            log_normaliser: 0.0,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// The hypotheses start at the given rotation, lie at least the angle apart, and leave
        /// no cell centre farther than the angle from all of them unless `count` were chosen;
        /// the second is the densest cell beyond the angle from the first (found by scanning
        /// every cell).
        #[test]
        fn hypotheses_are_spread_and_densest_first(
            weights in proptest::collection::vec(0.0..1.0f64, 576),
            first_cell in 0u64..576,
            count in 1usize..10,
            degrees in 10.0..90.0f64,
        ) {
            let grid = Grid::new(1).unwrap();
            let masses = masses_on(1, &weights);
            let first = grid.rotation(first_cell).unwrap();
            let angle = degrees.to_radians();
            let found = masses.rotation_hypotheses(first, count, angle).unwrap();
            prop_assert_eq!(found[0], first);
            prop_assert!(found.len() <= count);
            for (i, a) in found.iter().enumerate() {
                for b in &found[i + 1..] {
                    prop_assert!(geodesic_distance(a, b) >= angle);
                }
            }
            let far = |r: &UnitQuaternion<f64>| found.iter().all(|c| geodesic_distance(c, r) >= angle);
            if found.len() < count {
                prop_assert!((0..576).all(|i| !far(&grid.rotation(i).unwrap())));
            }
            let second = (0..576u64)
                .filter(|&i| geodesic_distance(&first, &grid.rotation(i).unwrap()) >= angle)
                .max_by(|&a, &b| weights[a as usize].total_cmp(&weights[b as usize]));
            if let (Some(cell), Some(found_second)) = (second, found.get(1)) {
                prop_assert_eq!(*found_second, grid.rotation(cell).unwrap());
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// With every cell a candidate, the ball picked holds as much mass as the heaviest ball
        /// about any cell centre (found by scanning every centre with the geodesic distance);
        /// with fewer, at least the densest cell's ball; its mass is the scanned mass about it.
        #[test]
        fn the_heaviest_ball_holds_the_most_mass(
            weights in proptest::collection::vec(0.0..1.0f64, 576),
            degrees in 5.0..90.0f64,
            candidates in 1usize..64,
        ) {
            let grid = Grid::new(1).unwrap();
            let masses = masses_on(1, &weights);
            let radius = degrees.to_radians();
            let centres: Vec<_> = (0..576).map(|i| grid.rotation(i).unwrap()).collect();
            let ball_mass = |c: &UnitQuaternion<f64>| -> f64 {
                centres
                    .iter()
                    .zip(&masses.masses)
                    .filter(|(q, _)| geodesic_distance(q, c) <= radius + 1e-12)
                    .map(|(_, m)| m)
                    .sum()
            };
            let heaviest = centres.iter().map(ball_mass).fold(0.0, f64::max);
            let all = masses.heaviest_ball(radius, 576).unwrap();
            prop_assert!((all.mass - heaviest).abs() < 1e-9);
            prop_assert!((ball_mass(&all.rotation) - all.mass).abs() < 1e-9);
            let some = masses.heaviest_ball(radius, candidates).unwrap();
            let densest = centres[masses.densest(1)[0]];
            prop_assert!(some.mass >= ball_mass(&densest) - 1e-9);
            prop_assert!(some.mass <= heaviest + 1e-9);
        }
    }

    /// A narrow spike beside a wider mode holding more mass: the densest cell is the spike's,
    /// the heaviest 15° ball the wide mode's.
    #[test]
    fn the_heaviest_ball_prefers_a_wide_mode_to_a_narrow_spike() {
        let grid = Grid::new(3).unwrap();
        let n = cell_count(3);
        let spike = UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1);
        let wide = spike * UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0);
        let nearest = |r: &UnitQuaternion<f64>| {
            (0..n)
                .min_by(|&a, &b| {
                    let d = |i| geodesic_distance(&grid.rotation(i).unwrap(), r);
                    d(a).total_cmp(&d(b))
                })
                .unwrap()
        };
        let spike_cell = nearest(&spike);
        let mode: Vec<u64> = (0..n)
            .filter(|&i| geodesic_distance(&grid.rotation(i).unwrap(), &wide) < 12f64.to_radians())
            .collect();
        assert!(mode.len() >= 4, "{} cells in the wide mode", mode.len());
        let mut weights = vec![1e-6; n as usize];
        weights[spike_cell as usize] = 0.2;
        for &i in &mode {
            weights[i as usize] = 0.6 / mode.len() as f64;
        }
        let masses = masses_on(3, &weights);
        assert_eq!(masses.densest(1), vec![spike_cell as usize]);
        let ball = masses.heaviest_ball(15f64.to_radians(), 64).unwrap();
        assert!(geodesic_distance(&ball.rotation, &wide) < 12f64.to_radians());
        assert!(ball.mass > 0.5, "{}", ball.mass);
        for (radius, candidates) in [(0.0, 8), (f64::NAN, 8), (4.0, 8), (0.2, 0)] {
            assert!(masses.heaviest_ball(radius, candidates).is_err());
        }
    }

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
            max_queries: usize::MAX,
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
    fn cells_left_coarse_count_their_slope_in_the_normaliser() {
        // A peak of width 1/√8 rad (≈ 20°) is wider than a level-2 cell, so F slopes across the
        // cells a small budget leaves at level 2 and their centres undercount them.
        let centre = UnitQuaternion::from_euler_angles(0.4, -0.2, 0.7);
        let wide = |level: u8, cells: &[u64]| -> Vec<f64> {
            peaked(level, cells, &centre)
                .iter()
                .map(|f| f / 5.0)
                .collect()
        };
        let options = RefineOptions {
            start_level: 2,
            level: 3,
            keep_mass: 1.0,
            max_queries: 4_608 + 8 * 150,
        };
        let budgeted = refine(|l, c| Ok(wide(l, c)), &options).unwrap();
        let dense = wide(3, &(0..cell_count(3)).collect::<Vec<_>>());
        let dense_log_z = log_sum_exp(dense.iter().map(|f| f + cell_volume(3).ln()));
        let midpoint_log_z = log_sum_exp(
            budgeted
                .cells
                .iter()
                .map(|&(level, index)| wide(level, &[index])[0] + cell_volume(level).ln()),
        );
        let corrected = (budgeted.log_normaliser - dense_log_z).abs();
        let midpoint = (midpoint_log_z - dense_log_z).abs();
        assert!(budgeted.cells.iter().any(|cell| cell.0 == 2));
        assert!(
            corrected < midpoint / 3.0,
            "corrected {corrected}, midpoint {midpoint}"
        );
    }

    proptest! {
        #[test]
        fn slope_factor_is_at_least_one_and_at_most_the_siblings_rise(
            slope in 0.0f64..200.0,
            level in 1u8..6,
            rise in 0.0f64..30.0,
        ) {
            let radius = So3Cells.ball_radius(level);
            let factor = slope_factor(slope, radius, rise);
            prop_assert!(factor >= 1.0);
            prop_assert!(factor <= rise.exp() * (1.0 + 1e-12));
            prop_assert!(slope_factor(slope * 1.5, radius, rise) >= factor);
        }

        #[test]
        fn sibling_slope_recovers_a_plane(
            gx in -20.0f64..20.0,
            gy in -20.0f64..20.0,
            gz in -20.0f64..20.0,
            group in 0u64..576,
        ) {
            let grid = Grid::new(2).unwrap();
            let first = group * 8;
            let origin = grid.rotation(first).unwrap().inverse();
            let gradient = nalgebra::Vector3::new(gx, gy, gz);
            let evaluated: HashMap<(u8, u64), f64> = (first..first + 8)
                .map(|i| {
                    let omega = (origin * grid.rotation(i).unwrap()).scaled_axis();
                    ((2, i), 1.5 + gradient.dot(&omega))
                })
                .collect();
            let slope = sibling_slope(&So3Cells, 2, first, &evaluated).unwrap().unwrap();
            prop_assert!((slope - gradient.norm()).abs() < 1e-6 * (1.0 + gradient.norm()));
            let mut missing = evaluated.clone();
            missing.remove(&(2, first + 3));
            prop_assert_eq!(sibling_slope(&So3Cells, 2, first, &missing).unwrap(), None);
        }
    }

    #[test]
    fn budget_bounds_the_queries_and_masses_sum_to_one() {
        let centre = UnitQuaternion::identity();
        let options = RefineOptions {
            start_level: 1,
            level: 3,
            keep_mass: 0.99,
            max_queries: 576 + 160,
        };
        let refined = refine(|l, c| Ok(peaked(l, c, &centre)), &options).unwrap();
        assert!(refined.queries <= 576 + 160);
        assert!((refined.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        // Unbudgeted, the normaliser of this peak of width 1/√40 rad matches the integral: near
        // the identity the volume element is d³ω / 8 (SO(3) has volume π²), so
        // ∫ exp(−20 |ω|²) ≈ (π/20)^{3/2} / 8.
        let unbudgeted = RefineOptions {
            max_queries: usize::MAX,
            ..options
        };
        let full = refine(|l, c| Ok(peaked(l, c, &centre)), &unbudgeted).unwrap();
        let expected = ((std::f64::consts::PI / 20.0).powf(1.5) / 8.0).ln();
        assert!(
            (full.log_normaliser - expected).abs() < 0.05,
            "{}",
            full.log_normaliser
        );
        // The budgeted refinement found the peak: its densest cell is refined and holds it.
        let densest = refined.densest(1)[0];
        let (level, index) = refined.cells[densest];
        assert!(level >= 2, "{level}");
        assert_eq!(Grid::new(level).unwrap().locate(&centre).unwrap(), index);
        let densest = full.densest(1)[0];
        assert_eq!(full.cells[densest].0, 3);
    }
}
