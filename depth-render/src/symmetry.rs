//! Primitive shapes described by their dimensions, with their analytic symmetries (so synthetic
//! data comes with exact ground-truth symmetry sets; `ipdf_metrics::SymmetryGroup::about_origin`
//! turns them into the scoring crate's groups).
use nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};

use crate::primitives::{self, MugShape};
use crate::{RenderError, TriangleMesh};

/// The proper symmetries of a shape about its origin: it looks the same turned by any of them.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeSymmetry {
    /// Rotations other than the identity that map the shape onto itself.
    pub discrete: Vec<UnitQuaternion<f64>>,
    /// Axes of revolution through the origin, combined with every discrete rotation.
    pub continuous: Vec<Unit<Vector3<f64>>>,
}

/// A primitive shape (metres, centred at the origin, axis of revolution z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// A box (a cube when the extents are equal).
    Cuboid {
        /// Edge lengths along x, y, z.
        extents: [f64; 3],
    },
    /// A closed cylinder (a can).
    Cylinder {
        /// Radius.
        radius: f64,
        /// Height along z.
        height: f64,
        /// Segments around.
        segments: u32,
    },
    /// A closed cone, apex towards +z.
    Cone {
        /// Base radius.
        radius: f64,
        /// Height along z.
        height: f64,
        /// Segments around.
        segments: u32,
    },
    /// A bowl opening towards +z.
    Bowl {
        /// Rim radius.
        radius: f64,
        /// Total height.
        height: f64,
        /// Wall and floor thickness.
        thickness: f64,
        /// Segments around.
        segments: u32,
        /// Rings along each quarter-ellipse of the profile.
        rings: u32,
    },
    /// A mug: a cup opening towards +z with a handle on its +x side ([`primitives::mug`]).
    Mug(MugShape),
    /// A subdivided icosahedron.
    Sphere {
        /// Radius.
        radius: f64,
        /// Subdivisions (`20·4^s` triangles).
        subdivisions: u32,
    },
    /// A regular tetrahedron.
    Tetrahedron {
        /// Distance of the vertices from the centre.
        circumradius: f64,
    },
    /// A regular octahedron.
    Octahedron {
        /// Distance of the vertices from the centre.
        circumradius: f64,
    },
    /// A regular icosahedron.
    Icosahedron {
        /// Distance of the vertices from the centre.
        circumradius: f64,
    },
    /// A one-sided rectangle facing +z (a tabletop).
    Plane {
        /// Extent along x.
        width: f64,
        /// Extent along y.
        depth: f64,
    },
}

impl Primitive {
    /// The closed, outward-wound mesh (see [`primitives`]).
    pub fn mesh(&self) -> Result<TriangleMesh, RenderError> {
        match *self {
            Self::Cuboid { extents } => primitives::cuboid(extents),
            Self::Cylinder {
                radius,
                height,
                segments,
            } => primitives::cylinder(radius, height, segments),
            Self::Cone {
                radius,
                height,
                segments,
            } => primitives::cone(radius, height, segments),
            Self::Bowl {
                radius,
                height,
                thickness,
                segments,
                rings,
            } => primitives::bowl(radius, height, thickness, segments, rings),
            Self::Mug(shape) => primitives::mug(&shape),
            Self::Sphere {
                radius,
                subdivisions,
            } => primitives::sphere(radius, subdivisions),
            Self::Tetrahedron { circumradius } => primitives::tetrahedron(circumradius),
            Self::Octahedron { circumradius } => primitives::octahedron(circumradius),
            Self::Icosahedron { circumradius } => primitives::icosahedron(circumradius),
            Self::Plane { width, depth } => primitives::plane(width, depth),
        }
    }

    /// The proper symmetries of the ideal shape: the rotations of a polyhedron that map its
    /// vertices onto themselves (3 for a box with distinct edges, 7 more for a square prism, 23
    /// for a cube, 11 for the tetrahedron, 59 for the icosahedron, all without the identity),
    /// and for solids of revolution the z-axis plus, for the cylinder, the half-turn that swaps
    /// its caps; none for a mug (its handle and open top break the cylinder's). A sphere's symmetry (all of SO(3)) has no such form: an error.
    pub fn symmetry(&self) -> Result<ShapeSymmetry, RenderError> {
        let revolution = |flip: bool| ShapeSymmetry {
            discrete: if flip {
                vec![UnitQuaternion::from_scaled_axis(
                    Vector3::x() * std::f64::consts::PI,
                )]
            } else {
                Vec::new()
            },
            continuous: vec![Vector3::z_axis()],
        };
        let polyhedron = |mesh: TriangleMesh, one_sided: bool| {
            let points: Vec<Vector3<f64>> =
                mesh.positions().iter().map(|p| p.coords.cast()).collect();
            let discrete = vertex_symmetries(&points)
                .into_iter()
                .filter(|r| !one_sided || (r * Vector3::z()).z > 0.5)
                .collect();
            ShapeSymmetry {
                discrete,
                continuous: Vec::new(),
            }
        };
        Ok(match self {
            Self::Cylinder { .. } => revolution(true),
            Self::Cone { .. } | Self::Bowl { .. } => revolution(false),
            Self::Mug(_) => ShapeSymmetry {
                discrete: Vec::new(),
                continuous: Vec::new(),
            },
            Self::Sphere { .. } => {
                return Err(RenderError::SymmetryNotRepresentable { shape: "sphere" });
            }
            Self::Plane { .. } => polyhedron(self.mesh()?, true),
            _ => polyhedron(self.mesh()?, false),
        })
    }
}

/// The rotations other than the identity that map the point set onto itself (within 1e-6 of
/// its size): every rotation taking a reference pair of points onto another pair at the same
/// distances, kept when it permutes all points.
fn vertex_symmetries(points: &[Vector3<f64>]) -> Vec<UnitQuaternion<f64>> {
    let scale = points.iter().map(|p| p.norm()).fold(0.0, f64::max);
    let tolerance = 1e-6 * scale;
    let Some((a, b)) = reference_pair(points, tolerance) else {
        return Vec::new();
    };
    let frame = |p: &Vector3<f64>, q: &Vector3<f64>| {
        let x = p.normalize();
        let z = p.cross(q).normalize();
        Matrix3::from_columns(&[x, z.cross(&x), z])
    };
    let reference = frame(&points[a], &points[b]);
    let close = |x: f64, y: f64| (x - y).abs() < tolerance;
    let mut out: Vec<UnitQuaternion<f64>> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        for (j, q) in points.iter().enumerate() {
            let candidate = i != j
                && close(p.norm(), points[a].norm())
                && close(q.norm(), points[b].norm())
                && close((p - q).norm(), (points[a] - points[b]).norm())
                && p.cross(q).norm() > tolerance;
            if !candidate {
                continue;
            }
            let rotation = frame(p, q) * reference.transpose();
            let permutes = points
                .iter()
                .all(|x| points.iter().any(|y| (rotation * x - y).norm() < tolerance));
            let rotation =
                UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
            if permutes
                && rotation.angle() > 1e-9
                && out.iter().all(|r| r.angle_to(&rotation) > 1e-9)
            {
                out.push(rotation);
            }
        }
    }
    out
}

/// Point `a` farthest from the origin and its nearest neighbour `b` not collinear with it
/// through the origin.
fn reference_pair(points: &[Vector3<f64>], tolerance: f64) -> Option<(usize, usize)> {
    let a = (0..points.len()).max_by(|&i, &j| points[i].norm().total_cmp(&points[j].norm()))?;
    let b = (0..points.len())
        .filter(|&j| points[a].cross(&points[j]).norm() > tolerance)
        .min_by(|&i, &j| {
            (points[i] - points[a])
                .norm()
                .total_cmp(&(points[j] - points[a]).norm())
        })?;
    Some((a, b))
}
