//! Repairing what scanned and exported meshes commonly get slightly wrong, so that they render:
//! zero-area triangles (repeated or collinear corners) are dropped, vertices no triangle uses
//! are dropped, and per-vertex normals of zero length or not finite are recomputed from the
//! triangles around the vertex. [`MeshRepairs`] counts what was done.
use std::fmt;

use nalgebra::{Point3, Vector3};

/// What loading a mesh repaired ([`crate::load_mesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct MeshRepairs {
    /// Zero-area triangles dropped (repeated or collinear corners).
    pub degenerate_triangles: usize,
    /// Vertices no triangle used, dropped.
    pub unreferenced_vertices: usize,
    /// Normals of zero length or not finite, recomputed from the adjacent triangles.
    pub normals: usize,
}

impl MeshRepairs {
    /// Whether nothing needed repair.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

impl fmt::Display for MeshRepairs {
    /// "dropped 2 zero-area triangles, dropped 5 unreferenced vertices, recomputed 1 normal".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let counts = [
            (
                self.degenerate_triangles,
                "dropped",
                "zero-area triangle",
                "zero-area triangles",
            ),
            (
                self.unreferenced_vertices,
                "dropped",
                "unreferenced vertex",
                "unreferenced vertices",
            ),
            (self.normals, "recomputed", "normal", "normals"),
        ];
        let parts: Vec<String> = counts
            .iter()
            .filter(|(n, ..)| *n > 0)
            .map(|(n, verb, one, many)| format!("{verb} {n} {}", if *n == 1 { one } else { many }))
            .collect();
        if parts.is_empty() {
            f.write_str("nothing repaired")
        } else {
            f.write_str(&parts.join(", "))
        }
    }
}

/// A mesh's arrays before [`crate::TriangleMesh`] checks them; indices are in range.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct MeshParts {
    pub positions: Vec<Point3<f32>>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Option<Vec<Vector3<f32>>>,
    pub colors: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
}

/// Twice the area vector of `triangle`, in f64 as [`crate::TriangleMesh::new`] measures it.
fn area_vector(positions: &[Point3<f32>], triangle: &[u32; 3]) -> Vector3<f64> {
    let [a, b, c] = triangle.map(|i| positions[i as usize].cast::<f64>());
    (b - a).cross(&(c - a))
}

/// The values of the vertices that `new_index` keeps (not `u32::MAX`), in order.
fn kept_only<T>(values: Vec<T>, new_index: &[u32]) -> Vec<T> {
    values
        .into_iter()
        .zip(new_index)
        .filter(|(_, index)| **index != u32::MAX)
        .map(|(value, _)| value)
        .collect()
}

/// `parts` repaired (see the module docs), what was done, and the index in `parts` of each
/// vertex kept (so that errors can name the file's vertex).
pub(crate) fn repair(parts: MeshParts) -> (MeshParts, MeshRepairs, Vec<usize>) {
    let mut repairs = MeshRepairs::default();
    let MeshParts {
        positions,
        triangles,
        normals,
        colors,
        uvs,
    } = parts;
    // Zero-area triangles.
    let before = triangles.len();
    let triangles: Vec<[u32; 3]> = triangles
        .into_iter()
        .filter(|triangle| area_vector(&positions, triangle).norm() > 0.0)
        .collect();
    repairs.degenerate_triangles = before - triangles.len();
    // Unreferenced vertices, renumbered in their order.
    let mut new_index = vec![u32::MAX; positions.len()];
    for triangle in &triangles {
        for &i in triangle {
            new_index[i as usize] = 0;
        }
    }
    let mut kept = 0u32;
    for slot in new_index.iter_mut().filter(|slot| **slot == 0) {
        *slot = kept;
        kept += 1;
    }
    repairs.unreferenced_vertices = positions.len() - kept as usize;
    let original: Vec<usize> = kept_only((0..positions.len()).collect(), &new_index);
    let triangles: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| t.map(|i| new_index[i as usize]))
        .collect();
    let positions: Vec<Point3<f32>> = kept_only(positions, &new_index);
    let normals = normals.map(|n| kept_only(n, &new_index));
    let colors = colors.map(|c| kept_only(c, &new_index));
    let uvs = uvs.map(|u| kept_only(u, &new_index));
    // Normals that cannot be used: the area-weighted mean of the adjacent triangles' normals.
    let normals = normals.map(|mut normals| {
        let bad: Vec<bool> = normals
            .iter()
            .map(|n| !(n.iter().all(|c| c.is_finite()) && n.norm() > 0.0))
            .collect();
        repairs.normals = bad.iter().filter(|b| **b).count();
        if repairs.normals > 0 {
            let mut sums = vec![Vector3::<f64>::zeros(); positions.len()];
            for triangle in &triangles {
                let area = area_vector(&positions, triangle);
                for &i in triangle {
                    sums[i as usize] += area;
                }
            }
            for (k, normal) in normals.iter_mut().enumerate() {
                if bad[k] {
                    // A vertex whose faces cancel out (a fold) keeps any unit vector.
                    *normal = sums[k]
                        .try_normalize(0.0)
                        .unwrap_or_else(Vector3::z)
                        .cast::<f32>();
                }
            }
        }
        normals
    });
    (
        MeshParts {
            positions,
            triangles,
            normals,
            colors,
            uvs,
        },
        repairs,
        original,
    )
}
