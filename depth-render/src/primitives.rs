//! Closed, outward-wound primitive meshes with exact dimensions, centred at the origin
//! (metres). Axes of revolution are the model z-axis.
use nalgebra::{Point3, Vector3};

use crate::{RenderError, TriangleMesh};

/// A box with edge lengths `extents` along x, y, z.
pub fn cuboid(extents: [f64; 3]) -> Result<TriangleMesh, RenderError> {
    for (name, value) in ["extent_x", "extent_y", "extent_z"]
        .into_iter()
        .zip(extents)
    {
        check_dimension(name, value)?;
    }
    // Vertex i has coordinates (bit 0 → x, bit 1 → y, bit 2 → z) of the low/high corner.
    let positions = (0..8)
        .map(|i| {
            Point3::from(std::array::from_fn(|axis| {
                ((i >> axis & 1) as f64 - 0.5) * extents[axis]
            }))
        })
        .collect();
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    mesh(
        positions,
        quads
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .collect(),
    )
}

/// A closed cylinder (a can): `radius`, `height` along z, `segments` around (≥ 3).
pub fn cylinder(radius: f64, height: f64, segments: u32) -> Result<TriangleMesh, RenderError> {
    check_dimension("radius", radius)?;
    check_dimension("height", height)?;
    let (bottom, top) = (-0.5 * height, 0.5 * height);
    revolve(
        &[(0.0, bottom), (radius, bottom), (radius, top), (0.0, top)],
        segments,
    )
}

/// The dimensions of a [`mug`] (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MugShape {
    /// Cup radius.
    pub radius: f64,
    /// Cup height along z.
    pub height: f64,
    /// Wall and floor thickness.
    pub wall: f64,
    /// Radius of the circle the handle's tube follows, centred on the wall.
    pub handle_reach: f64,
    /// Diameter of the handle's tube.
    pub handle_thickness: f64,
    /// Segments around the body.
    pub segments: u32,
}

/// A mug opening towards +z (`shape`): a cylindrical cup of `radius` and `height` whose wall
/// and floor are `wall` thick, with a handle on its +x side, a tube `handle_thickness` across bent along
/// a half circle of radius `handle_reach` in the xz-plane centred on the outer wall (it stands
/// `handle_reach + handle_thickness / 2` out and spans `±handle_reach` in z), capped flat
/// against the wall. Bounding box of the cup centred at the origin; `segments` around the cup,
/// a quarter of them around the tube. No rotation maps it onto itself: the handle breaks the
/// turns about the axis, the open top the half turns that swap its ends.
pub fn mug(shape: &MugShape) -> Result<TriangleMesh, RenderError> {
    let MugShape {
        radius,
        height,
        wall,
        handle_reach,
        handle_thickness,
        segments,
    } = *shape;
    check_dimension("radius", radius)?;
    check_dimension("height", height)?;
    check_dimension("handle_reach", handle_reach)?;
    check_dimension("handle_thickness", handle_thickness)?;
    check_dimension("wall", wall)?;
    if wall >= 0.5 * radius.min(height) {
        return Err(RenderError::InvalidDimension {
            name: "wall",
            value: wall,
        });
    }
    let tube = 0.5 * handle_thickness;
    if handle_reach + tube > 0.5 * height || tube > 0.25 * radius {
        return Err(RenderError::InvalidDimension {
            name: "handle_reach",
            value: handle_reach,
        });
    }
    let (bottom, top) = (-0.5 * height, 0.5 * height);
    let cup = revolve(
        &[
            (0.0, bottom),
            (radius, bottom),
            (radius, top),
            (radius - wall, top),
            (radius - wall, bottom + wall),
            (0.0, bottom + wall),
        ],
        segments,
    )?;
    let mut positions: Vec<Point3<f64>> = cup.positions().iter().map(|p| p.cast()).collect();
    let mut triangles = cup.triangles().to_vec();
    let handle = Handle {
        radius,
        reach: handle_reach,
        tube,
    };
    handle.append_to(&mut positions, &mut triangles, segments);
    mesh(positions, triangles)
}

/// A mug's handle: a tube of radius `tube` bent along a half circle of radius `reach` in the
/// xz-plane, centred on the cup's outer wall at x = `radius`, capped flat against the wall.
struct Handle {
    radius: f64,
    reach: f64,
    tube: f64,
}

impl Handle {
    /// Appends the handle's vertices and triangles: `segments.max(8)` steps along the half
    /// circle, `(segments / 4).max(6)` around the tube.
    fn append_to(
        &self,
        positions: &mut Vec<Point3<f64>>,
        triangles: &mut Vec<[u32; 3]>,
        segments: u32,
    ) {
        let offset = positions.len() as u32;
        let (steps, around) = (segments.max(8), (segments / 4).max(6));
        let centre_line = |i: u32| {
            let theta = std::f64::consts::PI * (f64::from(i) / f64::from(steps) - 0.5);
            let outward = Vector3::new(theta.cos(), 0.0, theta.sin());
            (
                Point3::new(self.radius, 0.0, 0.0) + outward * self.reach,
                outward,
            )
        };
        for i in 0..=steps {
            let (centre, outward) = centre_line(i);
            for j in 0..around {
                let phi = std::f64::consts::TAU * f64::from(j) / f64::from(around);
                positions
                    .push(centre + self.tube * (phi.cos() * outward + phi.sin() * Vector3::y()));
            }
        }
        let ring = |i: u32, j: u32| offset + i * around + j % around;
        for i in 0..steps {
            for j in 0..around {
                let (a, b, c, d) = (
                    ring(i, j),
                    ring(i, j + 1),
                    ring(i + 1, j + 1),
                    ring(i + 1, j),
                );
                triangles.extend([[a, b, c], [a, c, d]]);
            }
        }
        // The caps lie flat against the wall (the plane x = radius, touching it along the tube's
        // middle): facing −z at the lower end, +z at the upper.
        for (i, upper) in [(0, false), (steps, true)] {
            let centre = positions.len() as u32;
            positions.push(centre_line(i).0);
            for j in 0..around {
                let (a, b) = (ring(i, j), ring(i, j + 1));
                triangles.push(if upper {
                    [centre, a, b]
                } else {
                    [centre, b, a]
                });
            }
        }
    }
}

/// A closed cone: base of `radius` at `z = −height/2`, apex at `z = +height/2`.
pub fn cone(radius: f64, height: f64, segments: u32) -> Result<TriangleMesh, RenderError> {
    check_dimension("radius", radius)?;
    check_dimension("height", height)?;
    let (bottom, top) = (-0.5 * height, 0.5 * height);
    revolve(&[(0.0, bottom), (radius, bottom), (0.0, top)], segments)
}

/// A bowl opening towards +z, standing on a flat foot: the outer wall rises from a foot of
/// 40% of the rim `radius` to the rim along a quarter-ellipse, the inner wall follows it
/// `thickness` inside, and a flat rim joins them; `height` overall, bounding box centred at the
/// origin. `segments` around, `rings` along each wall.
pub fn bowl(
    radius: f64,
    height: f64,
    thickness: f64,
    segments: u32,
    rings: u32,
) -> Result<TriangleMesh, RenderError> {
    check_dimension("radius", radius)?;
    check_dimension("height", height)?;
    check_dimension("thickness", thickness)?;
    let foot = 0.4 * radius;
    if thickness >= foot.min(height) {
        return Err(RenderError::InvalidDimension {
            name: "thickness",
            value: thickness,
        });
    }
    if rings < 2 {
        return Err(RenderError::InvalidDimension {
            name: "rings",
            value: f64::from(rings),
        });
    }
    let (bottom, top) = (-0.5 * height, 0.5 * height);
    // A wall from (inner, top − depth) at angle 0 to (outer, top) at angle π/2.
    let wall = |inner: f64, outer: f64, depth: f64, k: u32| {
        let angle = std::f64::consts::FRAC_PI_2 * f64::from(k) / f64::from(rings);
        (
            inner + (outer - inner) * angle.sin(),
            top - depth * angle.cos(),
        )
    };
    let mut profile = vec![(0.0, bottom)];
    profile.extend((0..=rings).map(|k| wall(foot, radius, height, k)));
    profile.extend(
        (0..=rings)
            .rev()
            .map(|k| wall(foot - thickness, radius - thickness, height - thickness, k)),
    );
    profile.push((0.0, bottom + thickness));
    revolve(&profile, segments)
}

/// The closed surface swept by rotating a profile `(radius, z)` about the z-axis. The profile
/// starts and ends on the axis (radius 0) and runs counter-clockwise (outward on the right of
/// the direction of travel in the `(radius, z)` half-plane) with all inner points off the axis.
fn revolve(profile: &[(f64, f64)], segments: u32) -> Result<TriangleMesh, RenderError> {
    if segments < 3 {
        return Err(RenderError::InvalidDimension {
            name: "segments",
            value: f64::from(segments),
        });
    }
    let n = segments;
    let rings = &profile[1..profile.len() - 1];
    let mut positions = vec![Point3::new(0.0, 0.0, profile[0].1)];
    for &(radius, z) in rings {
        for i in 0..n {
            let (s, c) = (std::f64::consts::TAU * f64::from(i) / f64::from(n)).sin_cos();
            positions.push(Point3::new(radius * c, radius * s, z));
        }
    }
    let last_pole = positions.len() as u32;
    positions.push(Point3::new(0.0, 0.0, profile[profile.len() - 1].1));
    let ring = |r: usize, i: u32| 1 + r as u32 * n + i % n;
    let mut triangles = Vec::with_capacity(2 * n as usize * rings.len());
    for i in 0..n {
        triangles.push([0, ring(0, i + 1), ring(0, i)]);
        for r in 0..rings.len() - 1 {
            let (a, b, c, d) = (
                ring(r, i),
                ring(r, i + 1),
                ring(r + 1, i + 1),
                ring(r + 1, i),
            );
            triangles.extend([[a, b, c], [a, c, d]]);
        }
        let r = rings.len() - 1;
        triangles.push([last_pole, ring(r, i), ring(r, i + 1)]);
    }
    mesh(positions, triangles)
}

/// A one-sided `width` × `depth` rectangle in the z = 0 plane, facing +z (a tabletop).
pub fn plane(width: f64, depth: f64) -> Result<TriangleMesh, RenderError> {
    check_dimension("width", width)?;
    check_dimension("depth", depth)?;
    let (x, y) = (0.5 * width, 0.5 * depth);
    let positions = vec![
        Point3::new(-x, -y, 0.0),
        Point3::new(x, -y, 0.0),
        Point3::new(x, y, 0.0),
        Point3::new(-x, y, 0.0),
    ];
    mesh(positions, vec![[0, 1, 2], [0, 2, 3]])
}

/// A regular tetrahedron with vertices at distance `circumradius` from its centre.
pub fn tetrahedron(circumradius: f64) -> Result<TriangleMesh, RenderError> {
    let corners = [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ];
    convex_hull_of_regular(&corners, circumradius, 4)
}

/// A regular octahedron with vertices at distance `circumradius` on the axes.
pub fn octahedron(circumradius: f64) -> Result<TriangleMesh, RenderError> {
    let corners = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    convex_hull_of_regular(&corners, circumradius, 8)
}

/// A regular icosahedron with vertices at distance `circumradius` from its centre.
pub fn icosahedron(circumradius: f64) -> Result<TriangleMesh, RenderError> {
    convex_hull_of_regular(&icosahedron_corners(), circumradius, 20)
}

/// A sphere of `radius`: an icosahedron subdivided `subdivisions` times (each splits every
/// triangle into 4) with vertices on the sphere (`20·4^subdivisions` triangles).
pub fn sphere(radius: f64, subdivisions: u32) -> Result<TriangleMesh, RenderError> {
    check_dimension("radius", radius)?;
    let mut vertices: Vec<Vector3<f64>> = icosahedron_corners()
        .iter()
        .map(|c| Vector3::from(*c).normalize())
        .collect();
    let ico = icosahedron(1.0)?;
    let mut faces: Vec<[u32; 3]> = ico.triangles().to_vec();
    for _ in 0..subdivisions.min(8) {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<Vector3<f64>>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push((vertices[a as usize] + vertices[b as usize]).normalize());
                (vertices.len() - 1) as u32
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    midpoint(a, b, &mut vertices),
                    midpoint(b, c, &mut vertices),
                    midpoint(c, a, &mut vertices),
                );
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
    }
    mesh(
        vertices.iter().map(|v| Point3::from(v * radius)).collect(),
        faces,
    )
}

fn icosahedron_corners() -> Vec<[f64; 3]> {
    let phi = 0.5 * (1.0 + 5f64.sqrt());
    let mut corners = Vec::with_capacity(12);
    for (a, b) in [(1.0, phi), (1.0, -phi), (-1.0, phi), (-1.0, -phi)] {
        corners.extend([[0.0, a, b], [a, b, 0.0], [b, 0.0, a]]);
    }
    corners
}

/// The faces of a regular polyhedron whose corners (any scale) are given: the vertex triples
/// whose pairwise distances equal the shortest edge, wound outwards.
fn convex_hull_of_regular(
    corners: &[[f64; 3]],
    circumradius: f64,
    faces: usize,
) -> Result<TriangleMesh, RenderError> {
    check_dimension("circumradius", circumradius)?;
    let points: Vec<Vector3<f64>> = corners
        .iter()
        .map(|c| Vector3::from(*c).normalize() * circumradius)
        .collect();
    let edge = (1..points.len())
        .map(|j| (points[j] - points[0]).norm())
        .fold(f64::INFINITY, f64::min);
    let is_edge =
        |i: usize, j: usize| ((points[i] - points[j]).norm() - edge).abs() < 1e-9 * circumradius;
    let n = points.len() as u32;
    let mut triangles = Vec::with_capacity(faces);
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                let (i, j, k) = (a as usize, b as usize, c as usize);
                if is_edge(i, j) && is_edge(j, k) && is_edge(i, k) {
                    let normal = (points[j] - points[i]).cross(&(points[k] - points[i]));
                    let outward = normal.dot(&(points[i] + points[j] + points[k])) > 0.0;
                    triangles.push(if outward { [a, b, c] } else { [a, c, b] });
                }
            }
        }
    }
    debug_assert_eq!(triangles.len(), faces);
    mesh(points.iter().map(|p| Point3::from(*p)).collect(), triangles)
}

fn mesh(
    positions: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
) -> Result<TriangleMesh, RenderError> {
    TriangleMesh::new(
        positions.iter().map(|p| p.cast::<f32>()).collect(),
        triangles,
    )
}

fn check_dimension(name: &'static str, value: f64) -> Result<(), RenderError> {
    if !(value.is_finite() && value > 0.0) {
        return Err(RenderError::InvalidDimension { name, value });
    }
    Ok(())
}
