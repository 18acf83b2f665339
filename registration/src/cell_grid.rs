//! Exact nearest-point search through a grid of cells, each listing the points that can be
//! nearest to a query inside it.
//!
//! ICP asks the model's index for the nearest point of each observed point, hundreds of
//! thousands of times per instance, and those queries lie near the model's surface. For a cell
//! of centre `c` and half-diagonal `h` whose nearest point lies at `d*`, the nearest point of any
//! query in the cell lies within `d* + 2h` of `c`: those points are the cell's candidates, a
//! handful near the surface, and a query costs one cell lookup and that handful of distances
//! where the k-d tree descends and backtracks. Cells farther than a few cells from every point
//! keep no candidates, only `d*`, which still answers a query whose radius is smaller than the
//! distance to the cell; the k-d tree answers the rest.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Cells whose nearest point lies farther than this many cell edges keep no candidates.
const FAR_CELLS: f32 = 3.0;

/// Cells at most (the grid is left out beyond).
const MAX_CELLS: usize = 1 << 20;

/// The points, their candidate lists by cell (compressed rows: the candidates of cell `i` are
/// `candidates[starts[i]..starts[i + 1]]`, indices into `points`).
pub(crate) struct CellGrid {
    /// Corner of cell (0, 0, 0).
    origin: [f32; 3],
    /// Edge of a cell.
    cell: f32,
    /// Cells along x, y, z.
    dims: [usize; 3],
    starts: Vec<u32>,
    candidates: Vec<u32>,
    /// Per cell, a lower bound on the distance from any of its queries to the nearest point.
    clearance: Vec<f32>,
    points: Vec<[f32; 3]>,
}

/// The outcome of a grid search.
pub(crate) enum GridAnswer {
    /// The nearest point (index, squared distance), or `None` when no point lies within the
    /// radius asked for.
    Found(Option<(u32, f32)>),
    /// The grid cannot tell: the query lies outside it, or far from every point with a
    /// radius that reaches the points.
    Undecided,
}

/// Squared Euclidean distance, summed in kiddo's order, so that both give the same bits.
fn distance_squared(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])
}

impl CellGrid {
    /// The grid over `points`, indexed by `tree` (the same points), with cells of the points'
    /// median spacing; `None` for fewer than 64 points or where it would take too many cells.
    pub(crate) fn new(points: &[[f32; 3]], tree: &ImmutableKdTree<f32, 3>) -> Option<Self> {
        if points.len() < 64 {
            return None;
        }
        let two = std::num::NonZeroUsize::new(2).expect("not zero");
        let mut spacing: Vec<f32> = points
            .iter()
            .map(|p| {
                let found = tree
                    .query(p)
                    .nearest_n::<SquaredEuclidean<f32>>(two)
                    .execute();
                found.last().map_or(0.0, |n| n.distance.sqrt())
            })
            .collect();
        let middle = spacing.len() / 2;
        let cell = *spacing.select_nth_unstable_by(middle, f32::total_cmp).1;
        if !(cell.is_finite() && cell > 0.0) {
            return None;
        }
        let margin = FAR_CELLS * cell;
        let mut origin = [f32::INFINITY; 3];
        let mut far = [f32::NEG_INFINITY; 3];
        for p in points {
            for k in 0..3 {
                origin[k] = origin[k].min(p[k] - margin);
                far[k] = far[k].max(p[k] + margin);
            }
        }
        let dims = std::array::from_fn(|k| ((far[k] - origin[k]) / cell).ceil() as usize + 1);
        let count = dims
            .iter()
            .try_fold(1usize, |n: usize, &d| n.checked_mul(d))?;
        if count > MAX_CELLS {
            return None;
        }
        let half_diagonal = 0.5 * 3f32.sqrt() * cell;
        // A sliver more than the bounds, for rounding.
        let slack = 1e-3 * cell;
        let mut grid = Self {
            origin,
            cell,
            dims,
            starts: Vec::with_capacity(count + 1),
            candidates: Vec::new(),
            clearance: Vec::with_capacity(count),
            points: points.to_vec(),
        };
        grid.starts.push(0);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let centre = [x, y, z].map(|i| i as f32 + 0.5);
                    let centre: [f32; 3] = std::array::from_fn(|k| origin[k] + centre[k] * cell);
                    let nearest = tree
                        .query(&centre)
                        .nearest_one::<SquaredEuclidean<f32>>()
                        .execute();
                    let closest = nearest.distance.sqrt();
                    grid.clearance.push(closest - half_diagonal - slack);
                    if closest <= margin {
                        let reach = closest + 2.0 * half_diagonal + slack;
                        let mut found: Vec<u32> = tree
                            .query(&centre)
                            .within::<SquaredEuclidean<f32>>(reach * reach)
                            .unsorted()
                            .execute()
                            .into_iter()
                            .map(|n| n.item)
                            .collect();
                        found.sort_unstable();
                        grid.candidates.extend(found);
                    }
                    grid.starts.push(u32::try_from(grid.candidates.len()).ok()?);
                }
            }
        }
        Some(grid)
    }

    /// The nearest point to `query` within `radius` (`f32::INFINITY`: any), ties to the lower
    /// index.
    pub(crate) fn nearest(&self, query: &[f32; 3], radius: f32) -> GridAnswer {
        let (_, candidates) = match self.candidates_near(query, radius) {
            Ok(found) => found,
            Err(answer) => return answer,
        };
        let mut best: Option<(u32, f32)> = None;
        // Candidates come in increasing index: the first of equal distances stays.
        for &id in candidates {
            let d = distance_squared(&self.points[id as usize], query);
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((id, d));
            }
        }
        GridAnswer::Found(best.filter(|&(_, d)| d <= radius * radius))
    }

    /// The nearest of the `max_neighbours` nearest points within `radius` of `query` for which
    /// `agrees` holds (`None`: none of them), ties in distance to the lower index; `scratch`
    /// holds the cell's candidates within the radius, nearest first. Undecided where the cell's
    /// candidates cannot be shown to hold every point that near: a candidate list holds every
    /// point within the cell's clearance plus its diagonal of any query in the cell.
    pub(crate) fn nearest_agreeing(
        &self,
        query: &[f32; 3],
        radius: f32,
        max_neighbours: usize,
        agrees: impl Fn(u32) -> bool,
        scratch: &mut Vec<(f32, u32)>,
    ) -> GridAnswer {
        let (i, candidates) = match self.candidates_near(query, radius) {
            Ok(found) => found,
            Err(answer) => return answer,
        };
        // Every point nearer than this to the query is a candidate of its cell.
        let complete = self.clearance[i] + 3f32.sqrt() * self.cell;
        let complete_squared = complete * complete;
        scratch.clear();
        scratch.extend(
            candidates
                .iter()
                .map(|&id| (distance_squared(&self.points[id as usize], query), id))
                .filter(|&(d, _)| d <= radius * radius),
        );
        scratch.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(d, id) in scratch.iter().take(max_neighbours) {
            if d > complete_squared {
                return GridAnswer::Undecided;
            }
            if agrees(id) {
                return GridAnswer::Found(Some((id, d)));
            }
        }
        if scratch.len() >= max_neighbours || radius <= complete {
            GridAnswer::Found(None)
        } else {
            GridAnswer::Undecided
        }
    }

    /// The cell holding `query` and its candidates, or the answer where it has none: no point
    /// within `radius` where the grid shows there is none, else undecided.
    fn candidates_near(
        &self,
        query: &[f32; 3],
        radius: f32,
    ) -> Result<(usize, &[u32]), GridAnswer> {
        let Some(i) = self.cell_of(query) else {
            // Outside the grid, which reaches `FAR_CELLS` cells past every point.
            return Err(if radius < (FAR_CELLS - 0.01) * self.cell {
                GridAnswer::Found(None)
            } else {
                GridAnswer::Undecided
            });
        };
        let (from, to) = (self.starts[i] as usize, self.starts[i + 1] as usize);
        if from == to {
            return Err(if self.clearance[i] > radius {
                GridAnswer::Found(None)
            } else {
                GridAnswer::Undecided
            });
        }
        Ok((i, &self.candidates[from..to]))
    }

    /// An upper bound on the distance from `query` to its nearest point, anywhere (inside the
    /// grid or out): its distance to the centre of the grid's cell nearest to it, plus that
    /// centre's distance to its nearest point. NaN for a query with a NaN coordinate.
    pub(crate) fn nearest_bound(&self, query: &[f32; 3]) -> f32 {
        let at: [usize; 3] = std::array::from_fn(|k| {
            let c = ((query[k] - self.origin[k]) / self.cell).floor();
            // A NaN casts to 0; the bound below is NaN all the same.
            c.clamp(0.0, (self.dims[k] - 1) as f32) as usize
        });
        let centre: [f32; 3] =
            std::array::from_fn(|k| self.origin[k] + (at[k] as f32 + 0.5) * self.cell);
        let i = (at[2] * self.dims[1] + at[1]) * self.dims[0] + at[0];
        // `clearance` is the centre's nearest distance less the half-diagonal and a sliver.
        let closest = self.clearance[i] + (0.5 * 3f32.sqrt() + 2e-3) * self.cell;
        distance_squared(query, &centre).sqrt() + closest
    }

    /// The index of the cell holding `query`, `None` outside the grid.
    fn cell_of(&self, query: &[f32; 3]) -> Option<usize> {
        let mut at = [0usize; 3];
        for k in 0..3 {
            let c = (query[k] - self.origin[k]) / self.cell;
            if !(c >= 0.0 && c < self.dims[k] as f32) {
                return None;
            }
            // Truncation: the floor of a number that is not negative.
            at[k] = c as usize;
        }
        Some((at[2] * self.dims[1] + at[1]) * self.dims[0] + at[0])
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

        /// `nearest_bound` is at least the distance to the nearest point (a brute force's), for
        /// queries near the points, in the grid's margin and far outside it; inside the grid at
        /// most that distance plus the cell's diagonal (the triangle inequality through the
        /// cell's centre).
        #[test]
        fn nearest_bound_holds(
            seed in 0u64..1_000_000,
            count in 64usize..2000,
            spread in proptest::sample::select(vec![0.001f32, 0.01, 0.1, 1.0]),
        ) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            // Points on a sphere of 5 cm: a surface, as ICP's clouds are.
            let points: Vec<[f32; 3]> = (0..count)
                .map(|_| {
                    let v: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.0f32..1.0));
                    let norm = distance_squared(&v, &[0.0; 3]).sqrt().max(1e-6);
                    v.map(|x| 0.05 * x / norm)
                })
                .collect();
            let tree = ImmutableKdTree::new_from_slice(&points).expect("points");
            let grid = CellGrid::new(&points, &tree).expect("a grid");
            for _ in 0..200 {
                let base = points[rng.random_range(0..points.len())];
                let query = base.map(|x| x + rng.random_range(-spread..spread));
                let truth = points
                    .iter()
                    .map(|p| distance_squared(p, &query))
                    .fold(f32::INFINITY, f32::min)
                    .sqrt();
                let bound = grid.nearest_bound(&query);
                proptest::prop_assert!(bound >= truth, "bound {bound} under {truth}");
                if grid.cell_of(&query).is_some() {
                    let most = truth + (3f32.sqrt() + 0.01) * grid.cell;
                    proptest::prop_assert!(bound <= most, "bound {bound} over {most}");
                }
            }
        }
    }
}
