//! Physically plausible resting poses on a horizontal table: the faces of the convex hull on
//! which the object stands still, i.e. whose plane holds the projection of the centre of mass
//! strictly inside the face.
use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::{RenderError, TriangleMesh};

/// One way the object can rest on a table: a face of its convex hull down.
#[derive(Debug, Clone, PartialEq)]
pub struct RestingPose {
    /// Outward unit normal of the supporting face (model frame): it points into the table.
    pub normal: Unit<Vector3<f64>>,
    /// Distance from the model origin to the face's plane (`normal · p = offset` on the face).
    pub offset: f64,
    /// Chance of coming to rest on this face from a random orientation: the solid angle the face
    /// subtends at the centre of mass, renormalised over the stable faces.
    pub probability: f64,
}

impl RestingPose {
    /// The table-from-model pose (table frame: z up, the table is the plane z = 0) with the face
    /// on the table, turned by `yaw` about the vertical, the model origin above `(x, y)`.
    pub fn on_table(&self, yaw: f64, x: f64, y: f64) -> Isometry3<f64> {
        let down = -Vector3::z();
        let align = UnitQuaternion::rotation_between(&self.normal, &down).unwrap_or_else(|| {
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * align;
        Isometry3::from_parts(Translation3::new(x, y, self.offset), rotation)
    }
}

/// The stable resting poses of `mesh` (uniform density), most probable first.
///
/// Fails for meshes whose convex hull is flat or degenerate.
pub fn resting_poses(mesh: &TriangleMesh) -> Result<Vec<RestingPose>, RenderError> {
    // parry3d's own vector type (its glam), so that no glam of ours has to match its version.
    let points: Vec<parry3d::math::Vector> = mesh
        .positions()
        .iter()
        .map(|p| parry3d::math::Vector::new(p.x, p.y, p.z))
        .collect();
    let (hull_points, hull_triangles) =
        parry3d::transformation::try_convex_hull(&points).map_err(|e| {
            RenderError::NoRestingPose {
                reason: format!("convex hull failed: {e:?}"),
            }
        })?;
    let hull: Vec<Point3<f64>> = hull_points
        .iter()
        .map(|p| Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
        .collect();
    let scale = hull.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
    let centre =
        centre_of_mass(mesh, &hull, &hull_triangles).ok_or_else(|| RenderError::NoRestingPose {
            reason: "the mesh encloses no volume".into(),
        })?;
    let faces = coplanar_faces(&hull, &hull_triangles, scale);
    let mut poses: Vec<RestingPose> = faces
        .iter()
        .filter(|face| face.holds(&hull, &centre, 1e-6 * scale))
        .map(|face| RestingPose {
            normal: face.normal,
            offset: face.offset,
            probability: face
                .triangles
                .iter()
                .map(|t| solid_angle(&t.map(|i| hull[i as usize] - centre)))
                .sum(),
        })
        .collect();
    let total: f64 = poses.iter().map(|p| p.probability).sum();
    if poses.is_empty() || total <= 0.0 {
        return Err(RenderError::NoRestingPose {
            reason: "no hull face holds the centre of mass".into(),
        });
    }
    for pose in &mut poses {
        pose.probability /= total;
    }
    poses.sort_by(|a, b| {
        b.probability.total_cmp(&a.probability).then_with(|| {
            a.normal
                .iter()
                .partial_cmp(b.normal.iter())
                .unwrap_or(std::cmp::Ordering::Equal)
        })
    });
    Ok(poses)
}

/// Groups resting poses that a symmetry of the object maps onto each other: indices into
/// `poses`, groups in order of their first member. `rotations` are the object's symmetry
/// rotations, continuous axes sampled finely (every degree: `SymmetryGroup::rotations(360)` of
/// the `metrics` crate).
pub fn group_by_symmetry(
    poses: &[RestingPose],
    rotations: &[UnitQuaternion<f64>],
) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        let same = |j: usize| {
            let other = &poses[j];
            (pose.offset - other.offset).abs() < 1e-6 * pose.offset.abs().max(1e-3)
                && rotations.iter().any(|s| {
                    (s * other.normal.into_inner() - pose.normal.into_inner()).norm() < 1e-2
                })
        };
        match groups.iter_mut().find(|g| same(g[0])) {
            Some(group) => group.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// Centre of mass of the solid mesh, or of its convex hull when the mesh is open or flat.
fn centre_of_mass(
    mesh: &TriangleMesh,
    hull: &[Point3<f64>],
    hull_triangles: &[[u32; 3]],
) -> Option<Point3<f64>> {
    let solid = |corners: &mut dyn Iterator<Item = [Vector3<f64>; 3]>| {
        let (mut volume, mut moment) = (0.0, Vector3::zeros());
        for [a, b, c] in corners {
            let v = a.dot(&b.cross(&c)) / 6.0;
            volume += v;
            moment += (a + b + c) * (v / 4.0);
        }
        (volume, moment)
    };
    let (hull_volume, hull_moment) = solid(
        &mut hull_triangles
            .iter()
            .map(|t| t.map(|i| hull[i as usize].coords)),
    );
    if hull_volume.is_nan() || hull_volume <= 0.0 {
        return None;
    }
    let (volume, moment) =
        solid(&mut (0..mesh.triangles().len()).map(|t| mesh.corners(t).map(|p| p.coords.cast())));
    Some(Point3::from(if volume > 1e-3 * hull_volume {
        moment / volume
    } else {
        hull_moment / hull_volume
    }))
}

/// A planar face of the convex hull: the hull triangles sharing one plane.
struct Face {
    normal: Unit<Vector3<f64>>,
    offset: f64,
    triangles: Vec<[u32; 3]>,
}

impl Face {
    /// Whether the projection of `centre` onto the face lies inside it, at least `margin` from
    /// its boundary.
    fn holds(&self, hull: &[Point3<f64>], centre: &Point3<f64>, margin: f64) -> bool {
        let n = self.normal.into_inner();
        let p = centre - n * (n.dot(&centre.coords) - self.offset);
        let inside = self.triangles.iter().any(|t| {
            let [a, b, c] = t.map(|i| hull[i as usize]);
            [(a, b), (b, c), (c, a)]
                .iter()
                .all(|(u, v)| (v - u).cross(&(p - u)).dot(&n) >= 0.0)
        });
        // Boundary edges are the directed edges without their reverse in the face.
        let edges: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .collect();
        let clear = edges
            .iter()
            .filter(|&&(u, v)| !edges.contains(&(v, u)))
            .all(|&(u, v)| {
                let (u, v) = (hull[u as usize], hull[v as usize]);
                let along = (p - u).dot(&(v - u)) / (v - u).norm_squared();
                (p - (u + (v - u) * along.clamp(0.0, 1.0))).norm() > margin
            });
        inside && clear
    }
}

/// Merges hull triangles whose planes agree (normals within 1e-4, offsets within 1e-5 of the
/// hull's size) into faces.
fn coplanar_faces(hull: &[Point3<f64>], triangles: &[[u32; 3]], scale: f64) -> Vec<Face> {
    let inside: Vector3<f64> =
        hull.iter().map(|p| p.coords).sum::<Vector3<f64>>() / hull.len() as f64;
    let mut faces: Vec<Face> = Vec::new();
    for &[i, j, k] in triangles {
        let [a, b, c] = [i, j, k].map(|i| hull[i as usize]);
        let Some(mut normal) = Unit::try_new((b - a).cross(&(c - a)), 1e-18) else {
            continue;
        };
        // Wind outwards whatever the hull's convention.
        let mut triangle = [i, j, k];
        if normal.dot(&(a.coords - inside)) < 0.0 {
            normal = -normal;
            triangle = [i, k, j];
        }
        let triangle = &triangle;
        let offset = normal.dot(&a.coords);
        match faces.iter_mut().find(|f| {
            (f.normal.into_inner() - normal.into_inner()).norm() < 1e-4
                && (f.offset - offset).abs() < 1e-5 * scale
        }) {
            Some(face) => face.triangles.push(*triangle),
            None => faces.push(Face {
                normal,
                offset,
                triangles: vec![*triangle],
            }),
        }
    }
    faces
}

/// Solid angle (fraction of the full sphere) of a triangle seen from the origin (Van Oosterom
/// and Strackee, 1983).
fn solid_angle([a, b, c]: &[Vector3<f64>; 3]) -> f64 {
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let numerator = a.dot(&b.cross(c)).abs();
    let denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * numerator.atan2(denominator) / (4.0 * std::f64::consts::PI)
}
