//! Physically plausible resting poses on a horizontal table: the faces of the convex hull on
//! which the object stands still, i.e. whose support polygon holds the projection of the centre
//! of mass strictly inside, and how firmly it stands there (its tipping angle). A face is the
//! hull triangles within [`FACE_ANGLE_DEG`] of one normal, so that a scan's flat side, whose
//! hull is a patchwork of triangles a degree or two apart, is one face and not a scatter of
//! small ones the centre of mass falls outside.
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
    /// The smallest tilt (radians) that tips the object over an edge of this face: the arctangent
    /// of the distance from the centre of mass's projection to the face's boundary over the
    /// centre's height above the face. A box of edges `a < b < c` standing on its `a × b` end
    /// tips at `atan(a / c)`; a tessellated can lying on one facet of its side, at half the
    /// angle between facets.
    pub tipping_angle: f64,
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
    let faces = hull_faces(&hull, &hull_triangles);
    let mut poses: Vec<RestingPose> = faces
        .iter()
        .filter_map(|face| {
            let clearance = face.clearance(&hull, &centre)?;
            (clearance > 1e-6 * scale).then(|| RestingPose {
                normal: face.normal,
                offset: face.offset,
                probability: face
                    .triangles
                    .iter()
                    .map(|t| solid_angle(&t.map(|i| hull[i as usize] - centre)))
                    .sum(),
                tipping_angle: clearance.atan2(face.offset - face.normal.dot(&centre.coords)),
            })
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

/// A face of the convex hull the object can stand on: the hull triangles whose normals lie
/// within [`FACE_ANGLE_DEG`] of the largest one's, and the plane touching the hull across them.
struct Face {
    normal: Unit<Vector3<f64>>,
    offset: f64,
    triangles: Vec<[u32; 3]>,
}

impl Face {
    /// The distance from the projection of `centre` onto the face's plane to the boundary of
    /// the support polygon (the convex hull of the face's corners projected onto the plane),
    /// `None` where the projection lies outside it.
    fn clearance(&self, hull: &[Point3<f64>], centre: &Point3<f64>) -> Option<f64> {
        let n = self.normal.into_inner();
        // An orthonormal basis of the plane.
        let u = n
            .cross(&if n.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            })
            .normalize();
        let v = n.cross(&u);
        let flat = |p: &Point3<f64>| (u.dot(&p.coords), v.dot(&p.coords));
        let mut corners: Vec<(f64, f64)> = self
            .triangles
            .iter()
            .flatten()
            .map(|&i| flat(&hull[i as usize]))
            .collect();
        let polygon = convex_polygon(&mut corners);
        let (px, py) = flat(centre);
        let mut nearest = f64::INFINITY;
        for (k, &(ax, ay)) in polygon.iter().enumerate() {
            let (bx, by) = polygon[(k + 1) % polygon.len()];
            let (ex, ey) = (bx - ax, by - ay);
            let length = ex.hypot(ey);
            // Counter-clockwise: the inside is on each edge's left.
            let left = (ex * (py - ay) - ey * (px - ax)) / length;
            if left < 0.0 {
                return None;
            }
            nearest = nearest.min(left);
        }
        (polygon.len() >= 3).then_some(nearest)
    }
}

/// The convex hull of `points` (Andrew's monotone chain), counter-clockwise, without collinear
/// points; `points` are sorted in place.
fn convex_polygon(points: &mut [(f64, f64)]) -> Vec<(f64, f64)> {
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let turn = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let chain = |ordered: &mut dyn Iterator<Item = &(f64, f64)>| {
        let mut chain: Vec<(f64, f64)> = Vec::new();
        for &p in ordered {
            while chain.len() >= 2 && turn(chain[chain.len() - 2], chain[chain.len() - 1], p) <= 0.0
            {
                chain.pop();
            }
            chain.push(p);
        }
        // Each chain's last point is the other's first.
        chain.pop();
        chain
    };
    let mut polygon = chain(&mut points.iter());
    polygon.extend(chain(&mut points.iter().rev()));
    polygon
}

/// Hull triangles whose outward normals lie within this many degrees of a face's largest
/// triangle's belong to that face. A scan's flat side is a patchwork of hull triangles a degree
/// or two apart; the facets of a tessellated can's side, 3.75° apart at 96 segments, stay
/// faces of their own.
pub const FACE_ANGLE_DEG: f64 = 3.0;

/// Groups the hull triangles into faces: the largest triangle not yet in a face starts one, and
/// every other triangle within [`FACE_ANGLE_DEG`] of its normal joins it; the face's normal is
/// its triangles' mean (by area) and its plane touches the hull.
fn hull_faces(hull: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<Face> {
    let inside: Vector3<f64> =
        hull.iter().map(|p| p.coords).sum::<Vector3<f64>>() / hull.len() as f64;
    // Each triangle wound outwards, with its normal scaled by twice its area, and its unit
    // normal.
    let mut oriented: Vec<([u32; 3], Vector3<f64>, Vector3<f64>)> = triangles
        .iter()
        .filter_map(|&[i, j, k]| {
            let [a, b, c] = [i, j, k].map(|i| hull[i as usize]);
            let area = (b - a).cross(&(c - a));
            (area.norm() > 0.0).then(|| {
                if area.dot(&(a.coords - inside)) < 0.0 {
                    ([i, k, j], -area, -area.normalize())
                } else {
                    ([i, j, k], area, area.normalize())
                }
            })
        })
        .collect();
    oriented.sort_by(|a, b| b.1.norm_squared().total_cmp(&a.1.norm_squared()));
    let cos = FACE_ANGLE_DEG.to_radians().cos();
    let mut taken = vec![false; oriented.len()];
    let mut faces = Vec::new();
    for seed in 0..oriented.len() {
        if taken[seed] {
            continue;
        }
        let direction = oriented[seed].2;
        let mut sum = Vector3::zeros();
        let mut members = Vec::new();
        for (k, (triangle, area, unit)) in oriented.iter().enumerate() {
            if !taken[k] && unit.dot(&direction) >= cos {
                taken[k] = true;
                sum += area;
                members.push(*triangle);
            }
        }
        let normal = Unit::new_normalize(sum);
        let offset = hull
            .iter()
            .map(|p| normal.dot(&p.coords))
            .fold(f64::NEG_INFINITY, f64::max);
        faces.push(Face {
            normal,
            offset,
            triangles: members,
        });
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
