//! Normals by local PCA, oriented towards a viewpoint or by consistent propagation.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::num::NonZeroUsize;

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use crate::error::{at_least_one, positive_metres};
use crate::neighbours::{Neighbour, PointIndex};
use crate::{PointCloud, RegistrationError};

/// How the sign of each normal is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalOrientation {
    /// Every normal points towards this point (the camera centre of a depth view, in the
    /// cloud's frame).
    TowardsViewpoint(Point3<f32>),
    /// Signs agree between neighbours (Hoppe et al. 1992): a minimum spanning tree over the
    /// `neighbours`-nearest graph, weighted 1 − |nᵢ·nⱼ|, is walked from the highest point of each
    /// connected part, whose normal is turned to +z.
    Consistent {
        /// Neighbours per point in the propagation graph.
        neighbours: usize,
    },
}

/// Options of [`estimate_normals`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalOptions {
    /// Neighbourhood radius in metres (Open3D's tutorial: 2 × voxel size).
    pub radius: f32,
    /// At most this many nearest neighbours within `radius` (Open3D's tutorial: 30).
    pub max_neighbours: usize,
    /// Sign convention.
    pub orientation: NormalOrientation,
}

impl Default for NormalOptions {
    /// 1 cm radius, 30 neighbours, oriented towards the origin (a camera at the origin).
    fn default() -> Self {
        Self {
            radius: 0.01,
            max_neighbours: 30,
            orientation: NormalOrientation::TowardsViewpoint(Point3::origin()),
        }
    }
}

/// Estimates one unit normal per point: the eigenvector of the smallest eigenvalue of the
/// covariance of the point's neighbourhood (`index` must index `cloud`'s points).
///
/// A point whose neighbourhood has fewer than 3 points or is collinear has no defined normal;
/// it gets the direction to the viewpoint (or +z before consistent propagation). If no point at
/// all has a defined normal, the error is [`RegistrationError::TooFewPoints`] (no neighbourhood
/// holds 3 points) or [`RegistrationError::Degenerate`] (collinear).
pub fn estimate_normals(
    cloud: &PointCloud,
    index: &PointIndex,
    options: &NormalOptions,
) -> Result<PointCloud, RegistrationError> {
    if cloud.is_empty() {
        return Err(RegistrationError::EmptyCloud { cloud: "input" });
    }
    positive_metres("radius", options.radius)?;
    let max_neighbours = at_least_one("max_neighbours", options.max_neighbours)?;
    let points = cloud.points();
    let (fitted, sizes): (Vec<Option<Vector3<f32>>>, Vec<usize>) = points
        .par_iter()
        .map_init(Vec::new, |scratch: &mut Vec<Neighbour>, p| {
            index.nearest_within(&[p.x, p.y, p.z], options.radius, max_neighbours, scratch);
            (plane_normal(points, scratch), scratch.len())
        })
        .unzip();
    if fitted.iter().all(Option::is_none) {
        let largest = sizes.iter().copied().max().unwrap_or(0);
        return Err(if largest < 3 {
            RegistrationError::TooFewPoints {
                stage: "normal estimation (within its radius)",
                needed: 3,
                got: largest,
            }
        } else {
            RegistrationError::Degenerate {
                cloud: "input",
                shape: "collinear",
            }
        });
    }
    let normals = match options.orientation {
        NormalOrientation::TowardsViewpoint(viewpoint) => points
            .iter()
            .zip(&fitted)
            .map(|(p, n)| {
                let towards = viewpoint - p;
                let n = n
                    .or_else(|| towards.try_normalize(0.0))
                    .unwrap_or_else(Vector3::z);
                if n.dot(&towards) < 0.0 { -n } else { n }
            })
            .collect(),
        NormalOrientation::Consistent { neighbours } => {
            let mut normals: Vec<_> = fitted
                .iter()
                .map(|n| n.unwrap_or_else(Vector3::z))
                .collect();
            propagate_orientation(points, index, neighbours.max(2), &mut normals);
            normals
        }
    };
    Ok(PointCloud::from_valid(points.to_vec(), Some(normals)))
}

/// Smallest-variance direction of the neighbourhood, or `None` when it is not unique.
fn plane_normal(points: &[Point3<f32>], neighbourhood: &[Neighbour]) -> Option<Vector3<f32>> {
    if neighbourhood.len() < 3 {
        return None;
    }
    let at = |n: &Neighbour| points[n.index as usize].coords.cast::<f64>();
    let mean = neighbourhood.iter().map(at).sum::<Vector3<f64>>() / neighbourhood.len() as f64;
    let covariance = neighbourhood.iter().fold(Matrix3::zeros(), |c, n| {
        let d = at(n) - mean;
        c + d * d.transpose()
    });
    let eigen = SymmetricEigen::new(covariance);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let [smallest, middle, largest] = order.map(|i| eigen.eigenvalues[i]);
    // Collinear (or coincident) neighbourhood: the normal can turn freely about the line.
    if largest.is_nan() || largest <= 0.0 || middle <= largest * 1e-8 {
        return None;
    }
    debug_assert!(smallest <= middle);
    Some(
        eigen
            .eigenvectors
            .column(order[0])
            .into_owned()
            .cast::<f32>()
            .normalize(),
    )
}

/// Flips normals so that neighbours agree, walking a minimum spanning tree (Prim) of the kNN
/// graph from the highest point of each connected part.
fn propagate_orientation(
    points: &[Point3<f32>],
    index: &PointIndex,
    neighbours: usize,
    normals: &mut [Vector3<f32>],
) {
    let count = NonZeroUsize::new(neighbours + 1).unwrap_or(NonZeroUsize::MIN);
    let graph: Vec<Vec<Neighbour>> = points
        .par_iter()
        .map(|p| {
            let mut out = Vec::new();
            index.nearest_within(&[p.x, p.y, p.z], f32::INFINITY, count, &mut out);
            out
        })
        .collect();
    let mut visited = vec![false; points.len()];
    let mut by_height: Vec<usize> = (0..points.len()).collect();
    by_height.sort_by(|&a, &b| points[b].z.total_cmp(&points[a].z).then(a.cmp(&b)));
    // Edge weights as integers so the heap order (and the result) is exact and deterministic.
    let weight =
        |a: &Vector3<f32>, b: &Vector3<f32>| ((1.0 - a.dot(b).abs()).max(0.0) * 1e6) as u32;
    let mut heap = BinaryHeap::new();
    for &root in &by_height {
        if visited[root] {
            continue;
        }
        if normals[root].z < 0.0 {
            normals[root] = -normals[root];
        }
        visited[root] = true;
        heap.push(Reverse((0u32, root, root)));
        while let Some(Reverse((_, node, parent))) = heap.pop() {
            if node != parent {
                if visited[node] {
                    continue;
                }
                visited[node] = true;
                if normals[node].dot(&normals[parent]) < 0.0 {
                    normals[node] = -normals[node];
                }
            }
            // Edges both ways: the kNN relation is not symmetric, but a point is reached from
            // any of its neighbours' lists as well as from its own.
            for next in &graph[node] {
                let next = next.index as usize;
                if !visited[next] {
                    heap.push(Reverse((
                        weight(&normals[node], &normals[next]),
                        next,
                        node,
                    )));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a sphere of radius 0.1 around (0, 0, 1), outward normals known.
    fn sphere() -> Vec<Point3<f32>> {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        (0..2000)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 2000.0;
                let r = (1.0 - z * z).sqrt();
                let a = golden * i as f32;
                Point3::new(0.1 * r * a.cos(), 0.1 * r * a.sin(), 1.0 + 0.1 * z)
            })
            .collect()
    }

    /// The sphere's points and the normals `orientation` gives them (2 cm neighbourhoods).
    fn sphere_normals(orientation: NormalOrientation) -> (Vec<Point3<f32>>, Vec<Vector3<f32>>) {
        let points = sphere();
        let cloud = PointCloud::new(points.clone()).unwrap();
        let index = PointIndex::from_points(&points);
        let options = NormalOptions {
            radius: 0.02,
            max_neighbours: 30,
            orientation,
        };
        let with = estimate_normals(&cloud, &index, &options).unwrap();
        let normals = with.normals().unwrap().to_vec();
        (points, normals)
    }

    #[test]
    fn sphere_normals_are_radial_and_face_the_viewpoint() {
        let (points, normals) =
            sphere_normals(NormalOrientation::TowardsViewpoint(Point3::origin()));
        let centre = Point3::new(0.0, 0.0, 1.0);
        for (p, n) in points.iter().zip(&normals) {
            let radial = (p - centre).normalize();
            assert!(n.dot(&radial).abs() > 0.99, "normal {n} at {p}");
            assert!(n.dot(&(Point3::origin() - p)) >= 0.0);
        }
    }

    #[test]
    fn propagation_makes_sphere_normals_all_outward() {
        let (points, normals) = sphere_normals(NormalOrientation::Consistent { neighbours: 8 });
        let centre = Point3::new(0.0, 0.0, 1.0);
        for (p, n) in points.iter().zip(&normals) {
            assert!(
                n.dot(&(p - centre)) > 0.0,
                "normal {n} at {p} points inward"
            );
        }
    }

    #[test]
    fn collinear_cloud_is_degenerate() {
        let points: Vec<_> = (0..50)
            .map(|i| Point3::new(0.001 * i as f32, 0.0, 0.0))
            .collect();
        let cloud = PointCloud::new(points.clone()).unwrap();
        let index = PointIndex::from_points(&points);
        let err = estimate_normals(&cloud, &index, &NormalOptions::default());
        assert!(matches!(
            err,
            Err(RegistrationError::Degenerate {
                shape: "collinear",
                ..
            })
        ));
    }
}
