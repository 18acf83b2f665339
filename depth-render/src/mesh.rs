//! Triangle meshes: validated vertex positions (metres, model frame) and faces, with optional
//! per-vertex normals, colours and texture coordinates.
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::RenderError;

/// `(min, max)` corners of the axis-aligned bounding box of `points`, `None` when empty.
pub fn bounding_box(points: &[Point3<f32>]) -> Option<(Point3<f32>, Point3<f32>)> {
    let first = *points.first()?;
    Some(
        points
            .iter()
            .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
    )
}

/// The largest distance between two of `points` (0 for fewer than two), in parallel.
pub fn max_distance(points: &[Point3<f32>]) -> f32 {
    points
        .par_iter()
        .enumerate()
        .map(|(i, a)| {
            points[i + 1..]
                .iter()
                .map(|b| (a - b).norm())
                .fold(0.0f32, f32::max)
        })
        .reduce(|| 0.0, f32::max)
}

/// A triangle mesh with counter-clockwise (outward, seen from outside) winding.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    positions: Vec<Point3<f32>>,
    triangles: Vec<[u32; 3]>,
    normals: Option<Vec<Vector3<f32>>>,
    colors: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
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
            normals: None,
            colors: None,
            uvs: None,
        })
    }

    /// The mesh with per-vertex unit normals (used for smooth shading); they are normalised,
    /// and must be finite, non-zero and one per vertex.
    pub fn with_normals(mut self, normals: Vec<Vector3<f32>>) -> Result<Self, RenderError> {
        self.check_attribute(
            "normals",
            normals.len(),
            normals.iter().map(|n| n.as_slice()),
        )?;
        if let Some(vertex) = normals.iter().position(|n| n.norm() == 0.0) {
            return Err(RenderError::InvalidAttribute {
                attribute: "normals",
                vertex,
                reason: "zero length".into(),
            });
        }
        self.normals = Some(normals.iter().map(|n| n.normalize()).collect());
        Ok(self)
    }

    /// The mesh with per-vertex linear RGB colours in `[0, 1]`, one per vertex.
    pub fn with_colors(mut self, colors: Vec<[f32; 3]>) -> Result<Self, RenderError> {
        self.check_attribute("colors", colors.len(), colors.iter().map(|c| c.as_slice()))?;
        if let Some(vertex) = colors
            .iter()
            .position(|c| c.iter().any(|v| !(0.0..=1.0).contains(v)))
        {
            return Err(RenderError::InvalidAttribute {
                attribute: "colors",
                vertex,
                reason: "outside [0, 1]".into(),
            });
        }
        self.colors = Some(colors);
        Ok(self)
    }

    /// The mesh with per-vertex texture coordinates `(u, v)`, one per vertex.
    pub fn with_uvs(mut self, uvs: Vec<[f32; 2]>) -> Result<Self, RenderError> {
        self.check_attribute("uvs", uvs.len(), uvs.iter().map(|c| c.as_slice()))?;
        self.uvs = Some(uvs);
        Ok(self)
    }

    fn check_attribute<'a>(
        &self,
        attribute: &'static str,
        len: usize,
        mut values: impl Iterator<Item = &'a [f32]>,
    ) -> Result<(), RenderError> {
        if len != self.positions.len() {
            return Err(RenderError::InvalidAttribute {
                attribute,
                vertex: len.min(self.positions.len()),
                reason: format!("{len} values for {} vertices", self.positions.len()),
            });
        }
        match values.position(|v| v.iter().any(|c| !c.is_finite())) {
            Some(vertex) => Err(RenderError::InvalidAttribute {
                attribute,
                vertex,
                reason: "not finite".into(),
            }),
            None => Ok(()),
        }
    }

    /// Per-vertex unit normals, when the mesh has them.
    pub fn normals(&self) -> Option<&[Vector3<f32>]> {
        self.normals.as_deref()
    }

    /// Per-vertex RGB colours in `[0, 1]`, when the mesh has them.
    pub fn colors(&self) -> Option<&[[f32; 3]]> {
        self.colors.as_deref()
    }

    /// Per-vertex texture coordinates, when the mesh has them.
    pub fn uvs(&self) -> Option<&[[f32; 2]]> {
        self.uvs.as_deref()
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

    /// The largest distance between two vertices (metres), as BOP's `diameter`.
    pub fn diameter(&self) -> f64 {
        max_distance(&self.positions).into()
    }

    /// `(min, max)` corners of the axis-aligned bounding box.
    pub fn bounds(&self) -> (Point3<f32>, Point3<f32>) {
        // A mesh has at least one vertex (see `new`).
        let origin = Point3::origin();
        bounding_box(&self.positions).unwrap_or((origin, origin))
    }

    /// Unit outward normal of triangle `index` (model frame).
    pub fn triangle_normal(&self, index: usize) -> Vector3<f64> {
        self.face_normal(index).normalize()
    }

    /// Unnormalised normal of triangle `index` (length = twice its area).
    fn face_normal(&self, index: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(index).map(|p| p.cast::<f64>());
        (b - a).cross(&(c - a))
    }
}
