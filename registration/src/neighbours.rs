//! Neighbour search: an immutable k-d tree (kiddo) over 3-D points, and for a cloud that ICP
//! aligns to again and again, a grid of cells that answers its nearest-point queries.
//!
//! `kiddo` was measured against parry3d's BVH on this crate's workload (radius queries of
//! FPFH and normals, 5 mm voxels), and the grid against `kiddo` on ICP's queries: see
//! `benches/benches/registration.rs`, group `neighbours`.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

use crate::cell_grid::{CellGrid, GridAnswer};

/// One neighbour: its index in the indexed slice and its squared distance to the query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index into the indexed points.
    pub index: u32,
    /// Squared Euclidean distance to the query.
    pub distance_squared: f32,
}

/// A k-d tree over 3-D points (f32, metres), with a grid for nearest-point queries where
/// built by [`PointIndex::with_nearest_grid`].
pub struct PointIndex {
    tree: Option<ImmutableKdTree<f32, 3>>,
    /// With [`PointIndex::with_nearest_grid`]: answers nearest-point queries near the points.
    grid: Option<CellGrid>,
}

impl std::fmt::Debug for PointIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointIndex").finish_non_exhaustive()
    }
}

impl PointIndex {
    /// Indexes `entries` (x, y, z); an empty slice gives an index that finds nothing.
    pub fn new(entries: &[[f32; 3]]) -> Self {
        let tree = if entries.is_empty() {
            None
        } else {
            ImmutableKdTree::new_from_slice(entries).ok()
        };
        Self { tree, grid: None }
    }

    /// Indexes 3-D points.
    pub fn from_points(points: &[Point3<f32>]) -> Self {
        let entries: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        Self::new(&entries)
    }

    /// Indexes 3-D points, and builds the grid that answers nearest-point queries near them
    /// ([`PointIndex::nearest`], [`PointIndex::nearest_within_radius`]) with a few distances
    /// each: 2.6× faster than the tree on ICP's queries (`cargo bench -p benches --bench
    /// registration -- neighbours/nearest`), the same answers but among points at the very
    /// same distance, where the grid gives the first. Its cells, about the points' spacing
    /// wide, take tens of milliseconds for a few thousand points: for a cloud that many
    /// ICP runs align to (a model), not for one aligned once.
    pub fn with_nearest_grid(points: &[Point3<f32>]) -> Self {
        let mut index = Self::from_points(points);
        index.add_nearest_grid(points);
        index
    }

    /// Builds the grid of [`PointIndex::with_nearest_grid`] for an index of `points` (the
    /// very points it was built from), without building its tree again.
    pub(crate) fn add_nearest_grid(&mut self, points: &[Point3<f32>]) {
        let entries: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        self.grid = self
            .tree
            .as_ref()
            .and_then(|tree| CellGrid::new(&entries, tree));
    }

    /// The nearest entry to `query`, or `None` for an empty index.
    pub fn nearest(&self, query: &[f32; 3]) -> Option<Neighbour> {
        self.nearest_within_radius(query, f32::INFINITY)
    }

    /// The nearest entry within `radius` of `query` (inclusive), if any.
    ///
    /// The grid's answer where it has one. Otherwise kiddo's search bounded by the radius
    /// (`nearest_n(1).within(r²)`), which prunes every branch farther than the radius; or its
    /// nearest-one search, which is faster where a point does lie within the radius: where the
    /// radius is infinite, or where the grid shows such a point (the query's distance to a
    /// cell's centre, plus that centre's nearest distance, is within the radius: ICP's wide
    /// first radii, a model's self-symmetry search).
    ///
    /// ICP's queries that reach the tree are often far from every point: points of the model
    /// turned away from the camera, aligned to a view; a grid's queries more than a few cells
    /// from the model. Against kiddo's nearest-one search, then the radius, the bounded search
    /// took point-to-plane ICP of a model onto a view from 33.3 to 14.7 ms and `register` from
    /// 55.3 to 39.3 ms, and cut a tenth off the demo's label stage, with the same labels
    /// (`cargo bench -p benches --bench registration --
    /// 'icp_point_to_plane|register/|nearest_within'`). On queries all 2.5 mm from the points,
    /// with a radius of 7.5 mm, it is 2.7× slower (243 against 91 ns per query): a grid answers
    /// those where there is one. Where the grid shows a point within the radius, the
    /// nearest-one search took about a tenth off the can's model preparation (`cargo bench -p
    /// benches --bench labelling -- model/`) and 2–4% off labelling a YCB mug scan's renders.
    pub fn nearest_within_radius(&self, query: &[f32; 3], radius: f32) -> Option<Neighbour> {
        if let Some(grid) = &self.grid
            && let GridAnswer::Found(found) = grid.nearest(query, radius)
        {
            return found.map(|(index, distance_squared)| Neighbour {
                index,
                distance_squared,
            });
        }
        let tree = self.tree.as_ref()?;
        // Where the grid shows a point within the radius, the nearest-one search is faster.
        let surely_found = self
            .grid
            .as_ref()
            .is_some_and(|grid| grid.nearest_bound(query) <= radius);
        if radius.is_finite() && !surely_found {
            return nearest_n_within(tree, query, radius, NonZeroUsize::MIN).next();
        }
        let found = tree
            .query(query)
            .nearest_one::<SquaredEuclidean<f32>>()
            .execute();
        (found.distance <= radius * radius).then_some(Neighbour {
            index: found.item,
            distance_squared: found.distance,
        })
    }

    /// The nearest of the `max_neighbours` nearest entries within `radius` of `query` whose
    /// index `agrees` accepts, if any: ICP's correspondence under a normal test. `scratch` is
    /// working space. The grid answers where it can show that its cell's candidates hold every
    /// point that near (the same answers but among points at the very same distance), the
    /// tree ([`PointIndex::nearest_within`]) otherwise: on a view's points with one in four
    /// agreeing, 1.6× faster than the tree alone (`cargo bench -p benches --bench
    /// registration -- neighbours/nearest_agreeing`).
    pub fn nearest_agreeing(
        &self,
        query: &[f32; 3],
        radius: f32,
        max_neighbours: NonZeroUsize,
        agrees: impl Fn(u32) -> bool,
        scratch: &mut AgreeingScratch,
    ) -> Option<Neighbour> {
        if let Some(grid) = &self.grid
            && let GridAnswer::Found(found) = grid.nearest_agreeing(
                query,
                radius,
                max_neighbours.get(),
                &agrees,
                &mut scratch.candidates,
            )
        {
            return found.map(|(index, distance_squared)| Neighbour {
                index,
                distance_squared,
            });
        }
        self.nearest_within(query, radius, max_neighbours, &mut scratch.neighbours);
        scratch.neighbours.iter().find(|n| agrees(n.index)).copied()
    }

    /// Up to `max_neighbours` nearest entries within `radius` of `query` (the query itself
    /// included when indexed), nearest first, written into `out` (cleared first). This is
    /// Open3D's "hybrid" search.
    pub fn nearest_within(
        &self,
        query: &[f32; 3],
        radius: f32,
        max_neighbours: NonZeroUsize,
        out: &mut Vec<Neighbour>,
    ) {
        out.clear();
        let Some(tree) = self.tree.as_ref() else {
            return;
        };
        out.extend(nearest_n_within(tree, query, radius, max_neighbours));
    }
}

/// kiddo's search for the `max_neighbours` nearest entries within `radius` of `query`, bounded
/// by the radius, nearest first.
fn nearest_n_within(
    tree: &ImmutableKdTree<f32, 3>,
    query: &[f32; 3],
    radius: f32,
    max_neighbours: NonZeroUsize,
) -> impl Iterator<Item = Neighbour> {
    tree.query(query)
        .nearest_n::<SquaredEuclidean<f32>>(max_neighbours)
        .within(radius * radius)
        .execute()
        .into_iter()
        .map(|n| Neighbour {
            index: n.item,
            distance_squared: n.distance,
        })
}

/// Working space of [`PointIndex::nearest_agreeing`], kept between queries.
#[derive(Debug, Default)]
pub struct AgreeingScratch {
    candidates: Vec<(f32, u32)>,
    neighbours: Vec<Neighbour>,
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn brute_force(points: &[[f32; 3]], query: &[f32; 3], radius: f32, max: usize) -> Vec<u32> {
        let mut all: Vec<(f32, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                (
                    (0..3).map(|k| (p[k] - query[k]).powi(2)).sum::<f32>(),
                    i as u32,
                )
            })
            .filter(|(d, _)| *d <= radius * radius)
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all.into_iter().take(max).map(|(_, i)| i).collect()
    }

    #[test]
    fn matches_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let points: Vec<[f32; 3]> = (0..2000)
            .map(|_| [rng.random(), rng.random(), rng.random()])
            .collect();
        let index = PointIndex::new(&points);
        let mut out = Vec::new();
        for query in points.iter().step_by(97) {
            index.nearest_within(query, 0.08, NonZeroUsize::new(10).unwrap(), &mut out);
            let mut expected = brute_force(&points, query, 0.08, 10);
            let mut got: Vec<u32> = out.iter().map(|n| n.index).collect();
            // Ties at the boundary distance may come in either order.
            expected.sort_unstable();
            got.sort_unstable();
            assert_eq!(got, expected);
            let within = index.nearest_within_radius(query, 0.08).map(|n| n.index);
            assert_eq!(
                within,
                brute_force(&points, query, 0.08, 1).first().copied()
            );
            let far = [query[0] + 2.0, query[1], query[2]];
            assert!(index.nearest_within_radius(&far, 0.5).is_none());
            let nearest = index
                .nearest(&[query[0] + 1e-4, query[1], query[2]])
                .unwrap();
            assert_eq!(
                nearest.index,
                brute_force(&points, &[query[0] + 1e-4, query[1], query[2]], 1.0, 1)[0]
            );
        }
    }

    /// Half the extents of the box of [`box_surface`] and [`box_normal`]: 6 × 4 × 2 cm.
    const BOX_HALF: [f32; 3] = [0.03, 0.02, 0.01];

    /// Points on the surface of a 6 × 4 × 2 cm box (ICP's model clouds are surfaces), with a
    /// few exact duplicates, whose distances tie.
    fn box_surface(rng: &mut ChaCha8Rng, count: usize) -> Vec<Point3<f32>> {
        let mut points: Vec<Point3<f32>> = (0..count)
            .map(|_| {
                let mut p: [f32; 3] =
                    std::array::from_fn(|k| rng.random_range(-BOX_HALF[k]..BOX_HALF[k]));
                let face = rng.random_range(0..3usize);
                p[face] = if rng.random() {
                    BOX_HALF[face]
                } else {
                    -BOX_HALF[face]
                };
                Point3::from(p)
            })
            .collect();
        for i in 0..count / 50 {
            points.push(points[i * 7]);
        }
        points
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

        /// The grid's answers are the k-d tree's and a brute force's: the same distance to a
        /// point at that distance, none exactly where no point lies within the radius; for
        /// queries on the surface, near it, inside the box and far away. So is ICP's
        /// correspondence under a normal test, the nearest of the 8 nearest within the radius
        /// whose normal agrees with the query's (the normal of one face, at random: agreeing
        /// with the nearest face or not).
        #[test]
        fn grid_matches_brute_force(
            seed in 0u64..1_000_000,
            count in 64usize..3000,
            spread in proptest::sample::select(vec![0.0005f32, 0.003, 0.02, 0.2]),
            radius in proptest::sample::select(vec![0.002f32, 0.008, 0.05, f32::INFINITY]),
        ) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let points = box_surface(&mut rng, count);
            let entries: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
            let normals: Vec<[f32; 3]> = points.iter().map(box_normal).collect();
            let grid = PointIndex::with_nearest_grid(&points);
            proptest::prop_assert!(grid.grid.is_some());
            let tree = PointIndex::from_points(&points);
            let eight = NonZeroUsize::new(8).expect("not zero");
            let mut scratch = AgreeingScratch::default();
            for _ in 0..200 {
                let base = points[rng.random_range(0..points.len())];
                let query = [0, 1, 2].map(|k| base[k] + rng.random_range(-spread..spread));
                let found = grid.nearest_within_radius(&query, radius);
                let distance = |i: u32| {
                    let p = entries[i as usize];
                    (0..3).map(|k| (p[k] - query[k]).powi(2)).sum::<f32>()
                };
                let truth = brute_force(&entries, &query, radius, 1);
                // The same distance, to a point at that distance (of duplicates, any).
                proptest::prop_assert_eq!(
                    found.map(|n| n.distance_squared),
                    truth.first().map(|&i| distance(i))
                );
                if let Some(n) = found {
                    proptest::prop_assert_eq!(distance(n.index), n.distance_squared);
                }
                let from_tree = tree.nearest_within_radius(&query, radius);
                proptest::prop_assert_eq!(
                    found.map(|n| n.distance_squared),
                    from_tree.map(|n| n.distance_squared)
                );

                let axis = rng.random_range(0..3usize);
                let sign = if rng.random() { 1.0f32 } else { -1.0 };
                let agrees = |i: u32| normals[i as usize][axis] * sign > 0.5;
                let truth = brute_force(&entries, &query, radius, 8)
                    .into_iter()
                    .find(|&i| agrees(i))
                    .map(distance);
                for index in [&grid, &tree] {
                    let found = index.nearest_agreeing(&query, radius, eight, agrees, &mut scratch);
                    proptest::prop_assert_eq!(found.map(|n| n.distance_squared), truth);
                    if let Some(n) = found {
                        proptest::prop_assert!(agrees(n.index));
                        proptest::prop_assert_eq!(distance(n.index), n.distance_squared);
                    }
                }
            }
        }
    }

    /// The normal of a point of [`box_surface`]: that of the face it lies on.
    fn box_normal(p: &Point3<f32>) -> [f32; 3] {
        let face = (0..3)
            .min_by(|&a, &b| (BOX_HALF[a] - p[a].abs()).total_cmp(&(BOX_HALF[b] - p[b].abs())))
            .expect("three axes");
        std::array::from_fn(|k| if k == face { p[k].signum() } else { 0.0 })
    }

    #[test]
    fn empty_index_finds_nothing() {
        let index = PointIndex::from_points(&[]);
        assert!(index.nearest(&[0.0; 3]).is_none());
        let mut out = vec![Neighbour {
            index: 0,
            distance_squared: 0.0,
        }];
        index.nearest_within(&[0.0; 3], 1.0, NonZeroUsize::MIN, &mut out);
        assert!(out.is_empty());
    }
}
