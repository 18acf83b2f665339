//! The reference labeller: slow and exhaustive, the yardstick of a label set's completeness and
//! precision (`ipdf label --reference`). It finds an instance's ambiguity set A, every pose the
//! labeller's own acceptance rule accepts, by brute force instead of by trials:
//!
//! 1. **Search**: ICP from every rotation of a coarse SO(3) grid (level 1: 576 rotations,
//!    about 30° apart), each placed on the observed centroid ([`align_from`]), and the
//!    render-and-compare score of each pose found. The best pose sets the acceptance rule, as in
//!    the labeller: a score under `max_score` and within `score_margin` of the best, and no
//!    part of the object misplaced against the best
//!    ([`crate::Comparison::told_apart_from`]).
//! 2. **Flood fill**: from the cells of a fine grid (level 4: 294,912 cells, about 3.75° apart)
//!    that hold an accepted pose, every cell is tried: its centre rotation, with the translation
//!    that keeps the object's centre where the neighbour it was reached from put it, the
//!    translation refined by ICP (the rotation stays the cell's) and scored; where that is
//!    refused, the start is refined by ICP in the directions the points constrain (a turn the
//!    view cannot tell is left where it is) and scored, and counts if it stays within a cell
//!    spacing of the centre. A cell whose pose is accepted belongs to A, and its six neighbours
//!    (a spacing's turn either way about each model axis) are tried next. Every connected region
//!    of accepted rotations that the search reached is so sampled whole, at the fine grid's
//!    spacing.
//!
//! Last, as in the labeller, poses whose colours match the image clearly worse than the best
//! matching one are dropped ([`crate::appearance_match`], `LabelOptions::appearance_margin`).
//!
//! A holds the accepted poses of the search (ICP's optimum, which a cell's centre may miss by
//! enough to be refused where the score rises steeply) and one pose per accepted cell: a
//! discrete symmetry is the cells around its pose that the depth cannot tell from it (a few on
//! clean renders, a ball 10° across on noisy real frames), a continuous ambiguity (a can's
//! axis, a mug's turns with the handle hidden) a tube of cells along it. The rotation is kept
//! first: a cell where a mug's handle begins to show is accepted as it is, which ICP would turn
//! back towards the truth. The refinement is the fallback for a centre a little off an arc that
//! clean depth tells apart from it (a mug tilted by 2°). Cells are tried in waves, in parallel,
//! and taken in cell order, so that A does not depend on the number of threads.
use std::collections::HashSet;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use so3_grid::{Grid, geodesic_distance};

use crate::appearance::keep_by_appearance;
use crate::instance::{Candidate, LabelFailure, grid_alignments, prepare_view};
use crate::placement::place_rotation;
use crate::score::Acceptance;
use crate::{LabelError, LabelOptions, ObjectModel, Observation};
use bop_dataset::PseudoLabel;

/// Options of [`reference_set`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReferenceOptions {
    /// Level of the grid whose every rotation starts a global alignment.
    pub search_level: u8,
    /// Level of the grid A is sampled on.
    pub level: u8,
    /// At most this many fine cells are tried per instance (A is then cut short, and says so).
    pub max_cells: usize,
}

impl Default for ReferenceOptions {
    /// Search level 1 (576 starts, about 30° apart), sampling level 4 (cells about 3.75°
    /// apart), at most 60,000 cells tried.
    fn default() -> Self {
        Self {
            search_level: 1,
            level: 4,
            max_cells: 60_000,
        }
    }
}

impl ReferenceOptions {
    /// Refuses levels beyond the grid's (or a search level finer than the sampling level) and
    /// a zero cell budget, naming the option.
    pub fn validate(&self) -> Result<(), LabelError> {
        if self.level > so3_grid::MAX_LEVEL {
            return Err(LabelError::option(
                "reference_level",
                format!("{}: at most {}", self.level, so3_grid::MAX_LEVEL),
            ));
        }
        if self.search_level > self.level {
            return Err(LabelError::option(
                "reference_search_level",
                format!(
                    "{}: at most the reference level {}",
                    self.search_level, self.level
                ),
            ));
        }
        if self.max_cells == 0 {
            return Err(LabelError::option(
                "reference_max_cells",
                "must be at least 1",
            ));
        }
        Ok(())
    }

    /// The fine grid's spacing (radians): 60° at level 0, halved at each level.
    pub fn spacing(&self) -> f64 {
        60f64.to_radians() / f64::from(1u32 << self.level)
    }
}

/// The ambiguity set A of one instance.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceSet {
    /// The accepted poses of the search and one pose per accepted cell, best score first.
    pub poses: Vec<PseudoLabel>,
    /// Global alignments run (the search grid's size).
    pub starts: usize,
    /// Fine cells tried.
    pub cells: usize,
    /// Whether the cell budget ran out before the flood fill ended.
    pub truncated: bool,
}

/// A pose and its score.
type Scored = (Isometry3<f64>, f64);

/// The ambiguity set A of the instance seen in `observation` (see the module docs), under the
/// acceptance rule of `options` (the same noise estimate and thresholds as
/// [`crate::label_instance`]).
pub fn reference_set(
    model: &ObjectModel,
    observation: &Observation,
    options: &LabelOptions,
    reference: &ReferenceOptions,
) -> Result<ReferenceSet, LabelFailure> {
    let (view, options) = prepare_view(model, observation, options)?;
    let search = Grid::new(reference.search_level).map_err(grid_failure)?;
    // Each start's pose with its comparison (none where nothing can be compared), rendered
    // once: the score sets the bar, the pixels are what the best tells poses apart by.
    let found = grid_alignments(model, &view, observation, &options, &search);
    let best = found
        .iter()
        .min_by(|a, b| a.score().total_cmp(&b.score()))
        .cloned()
        .ok_or_else(|| LabelFailure::Registration("no start aligned".into()))?;
    let (best_pose, best_score, best) = (best.pose, best.score(), best.comparison);
    if best_score > options.max_score {
        return Err(LabelFailure::NoPoseAccepted {
            best: best_score,
            threshold: options.max_score,
            best_pose,
        });
    }
    let acceptance = Acceptance {
        score: options.accepted_score(best_score),
        best,
    };
    // The accepted poses of the search, no two within half a spacing of each other.
    let mut seeds: Vec<Scored> = Vec::new();
    for Candidate { pose, comparison } in found {
        let Some(comparison) = comparison.filter(|c| acceptance.accepts(c)) else {
            continue;
        };
        if seeds
            .iter()
            .all(|s| geodesic_distance(&s.0.rotation, &pose.rotation) > 0.5 * reference.spacing())
        {
            seeds.push((pose, f64::from(comparison.score)));
        }
    }
    let grid = Grid::new(reference.level).map_err(grid_failure)?;
    let model_centre = model.cloud.cloud.centroid().unwrap_or_else(Point3::origin);
    let fill = Flood {
        model,
        view: &view,
        observation,
        options: &options,
        grid: &grid,
        spacing: reference.spacing(),
        model_centre: model_centre.coords,
    };
    let (accepted, cells, truncated) = fill.run(&seeds, &acceptance, reference.max_cells)?;
    let best_score = accepted.iter().fold(best_score, |b, c| b.min(c.1));
    let accepted: Vec<Scored> = seeds
        .into_iter()
        .chain(accepted)
        .filter(|c| c.1 <= options.accepted_score(best_score))
        .collect();
    let mut poses: Vec<PseudoLabel> =
        keep_by_appearance(model, observation, accepted, options.appearance_margin)
            .into_iter()
            .map(|(pose, score)| PseudoLabel { pose, score })
            .collect();
    poses.sort_by(|a, b| a.score.total_cmp(&b.score));
    Ok(ReferenceSet {
        poses,
        starts: search.len() as usize,
        cells,
        truncated,
    })
}

/// A grid the options asked for that cannot be built or searched.
fn grid_failure(error: so3_grid::GridError) -> LabelFailure {
    LabelFailure::Input(format!("reference grid: {error}"))
}

/// The flood fill of accepted cells on the fine grid.
struct Flood<'a> {
    model: &'a ObjectModel,
    view: &'a registration::PreparedCloud,
    observation: &'a Observation<'a>,
    options: &'a LabelOptions,
    grid: &'a Grid,
    spacing: f64,
    model_centre: Vector3<f64>,
}

impl Flood<'_> {
    /// The poses `acceptance` accepts of the cells connected to the cells of the poses of
    /// `seeds`, the cells tried, and whether `max_cells` cut the fill short.
    fn run(
        &self,
        seeds: &[Scored],
        acceptance: &Acceptance,
        max_cells: usize,
    ) -> Result<(Vec<Scored>, usize, bool), LabelFailure> {
        let locate =
            |rotation: &UnitQuaternion<f64>| self.grid.locate(rotation).map_err(grid_failure);
        let mut visited: HashSet<u64> = HashSet::new();
        let mut queue: Vec<(u64, Isometry3<f64>)> = Vec::new();
        for (seed, _) in seeds {
            let cell = locate(&seed.rotation)?;
            if visited.insert(cell) {
                queue.push((cell, *seed));
            }
        }
        let (mut accepted, mut tried) = (Vec::new(), 0);
        while !queue.is_empty() && tried < max_cells {
            queue.sort_by_key(|c| c.0);
            queue.truncate(max_cells - tried);
            tried += queue.len();
            let wave: Vec<(u64, Option<Scored>)> = queue
                .par_iter()
                .map(|(cell, from)| (*cell, self.try_cell(*cell, from, acceptance)))
                .collect();
            queue.clear();
            for (cell, outcome) in wave {
                let Some(found) = outcome else { continue };
                accepted.push(found);
                let centre = self.grid.rotation(cell).map_err(grid_failure)?;
                for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
                    for sign in [-1.0, 1.0] {
                        let turn = UnitQuaternion::from_scaled_axis(axis * sign * self.spacing);
                        let next = locate(&(centre * turn))?;
                        if visited.insert(next) {
                            queue.push((next, found.0));
                        }
                    }
                }
            }
        }
        Ok((accepted, tried, !queue.is_empty()))
    }

    /// Cell `cell` reached from the accepted pose `from`: its centre rotation with the object's
    /// centre where `from` puts it, the shift refined and scored; when `acceptance` refuses
    /// that, the same start refined in the directions the points constrain, if it stays within
    /// a spacing of the centre. `None` unless one of the two is accepted.
    fn try_cell(
        &self,
        cell: u64,
        from: &Isometry3<f64>,
        acceptance: &Acceptance,
    ) -> Option<Scored> {
        let rotation = self.grid.rotation(cell).ok()?;
        let centre = from * Point3::from(self.model_centre);
        let start = Isometry3::from_parts(
            Translation3::from(centre.coords - rotation * self.model_centre),
            rotation,
        );
        place_rotation(
            self.model,
            self.view,
            self.observation,
            self.options,
            acceptance,
            &start,
            self.spacing,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_options_out_of_range_are_refused_by_name() {
        for (name, options) in [
            (
                "reference_level",
                ReferenceOptions {
                    level: so3_grid::MAX_LEVEL + 1,
                    ..ReferenceOptions::default()
                },
            ),
            (
                "reference_search_level",
                ReferenceOptions {
                    search_level: 5,
                    ..ReferenceOptions::default()
                },
            ),
            (
                "reference_max_cells",
                ReferenceOptions {
                    max_cells: 0,
                    ..ReferenceOptions::default()
                },
            ),
        ] {
            let error = options.validate().unwrap_err().to_string();
            assert!(error.starts_with(name), "{name}: {error}");
        }
        assert!(ReferenceOptions::default().validate().is_ok());
    }
}
