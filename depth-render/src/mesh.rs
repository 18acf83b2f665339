//! Triangle meshes: validated vertex positions (metres, model frame) and faces.
use nalgebra::{Point3, Vector3};

use crate::RenderError;

/// A triangle mesh with counter-clockwise (outward, seen from outside) winding.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    positions: Vec<Point3<f32>>,
    triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// A mesh from vertex positions (model frame, metres) and triangles (vertex indices).
    ///
    /// Rejects empty meshes, non-finite vertices, out-of-range indices and zero-area triangles.
    pub fn new(positions: Vec<Point3<f32>>, triangles: Vec<[u32; 3]>) -> Result<Self, RenderError> {
        if positions.is_empty() || triangles.is_empty() {
            return Err(RenderError::EmptyMesh {
                vertices: positions.len(),
                triangles: triangles.len(),
            });
        }
        if let Some(vertex) = positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(RenderError::NonFiniteVertex { vertex });
        }
        for (triangle, face) in triangles.iter().enumerate() {
            if let Some(&index) = face.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(RenderError::IndexOutOfRange {
                    triangle,
                    index,
                    vertices: positions.len(),
                });
            }
            let [a, b, c] = face.map(|i| positions[i as usize].cast::<f64>());
            if (b - a).cross(&(c - a)).norm() <= 0.0 {
                return Err(RenderError::DegenerateTriangle { triangle });
            }
        }
        Ok(Self {
            positions,
            triangles,
        })
    }

    /// Vertex positions (model frame, metres).
    pub fn positions(&self) -> &[Point3<f32>] {
        &self.positions
    }

    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The three corners of triangle `index`.
    pub fn corners(&self, index: usize) -> [Point3<f32>; 3] {
        self.triangles[index].map(|i| self.positions[i as usize])
    }

    /// Total surface area (m²).
    pub fn surface_area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| 0.5 * self.face_normal(t).norm())
            .sum()
    }

    /// Enclosed volume (m³) by the divergence theorem: positive for a closed mesh with outward
    /// winding, meaningless for an open one.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t).map(|p| p.coords.cast::<f64>());
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// `(min, max)` corners of the axis-aligned bounding box.
    pub fn bounds(&self) -> (Point3<f32>, Point3<f32>) {
        let mut lo = self.positions[0];
        let mut hi = lo;
        for p in &self.positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }

    /// Unnormalised normal of triangle `index` (length = twice its area).
    fn face_normal(&self, index: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(index).map(|p| p.cast::<f64>());
        (b - a).cross(&(c - a))
    }
}
