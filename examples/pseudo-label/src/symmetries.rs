//! The model's own symmetries, found from its mesh, and the choice of diverse pose sets.
//!
//! A random initial pose makes FGR land on *some* member of an object's symmetry set, but not
//! on an even spread of them (docs/experiments.md, "Labelling strategy and speed", measures it).
//! So once one pose is accepted, the other members are reached by re-seeding ICP from that pose
//! composed with each self-symmetry of the model, which is found once per object here:
//! ICP of the model cloud onto itself from every rotation of a level-0 grid (72) about its
//! centroid, keeping the motions whose surface residual is
//! tiny. This uses the mesh alone (never a ground-truth pose) and works for any mesh, whatever
//! its symmetries (none, discrete, continuous or approximate).
//!
//! [`principal_turns`] are the poses an object is most often *mistaken* for: on real frames a
//! box registered 90° or 180° off about one of its axes, or a scan that is nearly but not quite
//! symmetric, explains the depth almost as well as the truth, and the first trial that scores
//! under `good_score` may be one of them. Re-seeding from each turn and keeping what scores
//! best makes the first label independent of which basin the trials fell into.
use depth_render::TriangleMesh;
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use rayon::prelude::*;
use registration::{IcpOptions, PreparedCloud, downsample_voxel, refine_icp};
use so3_grid::{Grid, geodesic_distance};

/// Two symmetries closer than this (radians, 5°) are the same: ICP may stop a little short of
/// an exact symmetry where a face slides within its own plane.
const SAME_SYMMETRY: f64 = 5.0f64 * std::f64::consts::PI / 180.0;

/// A motion whose surface residual ([`surface_residual`]) is under this many voxels maps the
/// model onto itself.
pub const SYMMETRIC_RESIDUAL: f64 = 0.08;

/// The mean point-to-plane distance (metres) of the points `pose · source` to `target`, each point's
/// distance capped at `cap` and points with no target point within `2 · cap` counted as `cap`:
/// 0 when the moved points lie on the target's surface, whatever the sampling.
pub fn surface_residual(
    source: &[Point3<f32>],
    target: &PreparedCloud,
    pose: &Isometry3<f64>,
    cap: f32,
) -> f64 {
    let total: f64 = surface_distances(source, target, pose, cap).iter().sum();
    total / source.len().max(1) as f64
}

/// The point-to-plane distance (metres) of each point of `pose · source` to `target`, capped
/// at `cap`, `cap` where no target point lies within `2 · cap` or the target has no normals.
fn surface_distances(
    source: &[Point3<f32>],
    target: &PreparedCloud,
    pose: &Isometry3<f64>,
    cap: f32,
) -> Vec<f64> {
    let Some(normals) = target.cloud.normals() else {
        return vec![f64::from(cap); source.len()];
    };
    let pose = pose.cast::<f32>();
    source
        .par_iter()
        .map(|p| {
            let moved = pose * p;
            let distance = match target
                .index
                .nearest_within_radius(&[moved.x, moved.y, moved.z], 2.0 * cap)
            {
                Some(n) => {
                    let q = target.cloud.points()[n.index as usize];
                    normals[n.index as usize].dot(&(moved - q)).abs().min(cap)
                }
                None => cap,
            };
            f64::from(distance)
        })
        .collect()
}

/// The rigid motions `S` (model frame, metres) with `S · model ≈ model`, identity first, the
/// others by increasing surface residual, no two within 5°. `voxel` is the model cloud's voxel
/// size: a motion is kept when the surface residual after ICP is below
/// [`SYMMETRIC_RESIDUAL`] · `voxel`.
pub fn discover_symmetries(model: &PreparedCloud, voxel: f32) -> Vec<Isometry3<f64>> {
    let Some(centroid) = model.cloud.centroid() else {
        return vec![Isometry3::identity()];
    };
    let to_centre = Translation3::from(-centroid.coords);
    let back = Translation3::from(centroid.coords);
    let grid = Grid::new(0).expect("level 0 exists");
    let coarse = IcpOptions {
        max_correspondence_distance: 4.0 * voxel,
        max_iterations: 15,
        ..IcpOptions::default()
    };
    let fine = IcpOptions {
        max_correspondence_distance: 1.5 * voxel,
        max_iterations: 30,
        ..IcpOptions::default()
    };
    // The moving copy at twice the voxel: a sixth of the points, the same surface.
    let Ok(source) = downsample_voxel(&model.cloud, 2.0 * voxel) else {
        return vec![Isometry3::identity()];
    };
    let mut found: Vec<(Isometry3<f64>, f64)> = grid
        .rotations()
        .par_iter()
        .map(|rotation| {
            let start =
                back * Isometry3::from_parts(Translation3::identity(), *rotation) * to_centre;
            let refine = |pose: &Isometry3<f64>, options: &IcpOptions| {
                refine_icp(&source, &model.cloud, &model.index, pose, options)
                    .ok()
                    .map(|a| a.pose)
            };
            let pose = refine(&start, &coarse).and_then(|p| refine(&p, &fine))?;
            let residual = surface_residual(model.cloud.points(), model, &pose, voxel);
            (residual < SYMMETRIC_RESIDUAL * f64::from(voxel)).then_some((pose, residual))
        })
        .flatten()
        .collect();
    // The best of each cluster first (stable: ties keep grid order).
    found.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut symmetries = vec![Isometry3::identity()];
    for (pose, _) in found {
        if symmetries
            .iter()
            .all(|s| geodesic_distance(&s.rotation, &pose.rotation) > SAME_SYMMETRY)
        {
            symmetries.push(pose);
        }
    }
    symmetries
}

/// An axis about which every turn maps the model onto itself (a can's, a bowl's), in the
/// model's frame (metres): poses that differ by such a turn render the same depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymmetryAxis {
    /// The axis's direction.
    pub axis: Unit<Vector3<f64>>,
    /// A point on the axis.
    pub point: Point3<f64>,
}

impl SymmetryAxis {
    /// The turn by `angle` radians about the axis.
    pub fn turn(&self, angle: f64) -> Isometry3<f64> {
        Isometry3::rotation_wrt_point(
            UnitQuaternion::from_axis_angle(&self.axis, angle),
            self.point,
        )
    }

    /// The axis of the screw motion `motion`, its point the one nearest the origin; `None`
    /// for a motion that turns by less than a thousandth of a radian (its axis is not
    /// defined to any useful precision). A motion with a shift along its axis keeps the axis.
    pub fn of_motion(motion: &Isometry3<f64>) -> Option<Self> {
        let (axis, angle) = motion.rotation.axis_angle()?;
        if angle < 1e-3 {
            return None;
        }
        // t = (I − R)·p for p ⟂ axis on the axis, solved: p = ½ (t⊥ + cot(θ/2) · axis × t⊥).
        let t = motion.translation.vector;
        let across = t - axis.into_inner() * axis.dot(&t);
        let point = 0.5 * (across + axis.cross(&across) / (0.5 * angle).tan());
        Some(Self {
            axis,
            point: Point3::from(point),
        })
    }

    /// The axis of `mesh` as a surface of revolution (model frame): the line that every face's
    /// normal line, through its centre and weighted by its area, meets best, in the
    /// least-squares sense of Pottmann and Randrup's line-complex fit (1998). In Plücker
    /// coordinates a line (direction `a`, moment `ā = c × a`) meets the normal line at `p`
    /// along `n` where `(p × n)·a + n·ā = 0`; minimising the sum of squares over `ā` leaves a
    /// 3 × 3 Schur complement, whose eigenvector of the least eigenvalue is `a`. A mesh turned
    /// onto itself by the turns of its segments gives its axis to rounding, far finer than
    /// the screw axis of one ICP motion ([`Self::of_motion`]). `None` when the normals do
    /// not span space (a flat mesh).
    pub fn of_revolution(mesh: &TriangleMesh) -> Option<Self> {
        let lines: Vec<(Vector3<f64>, Vector3<f64>, f64)> = (0..mesh.triangles().len())
            .filter_map(|i| {
                let [a, b, c] = mesh.corners(i).map(|p| p.coords.cast::<f64>());
                let twice_area = (b - a).cross(&(c - a));
                let area = 0.5 * twice_area.norm();
                (area > 0.0).then(|| ((a + b + c) / 3.0, twice_area / (2.0 * area), area))
            })
            .collect();
        let total: f64 = lines.iter().map(|l| l.2).sum();
        if total <= 0.0 {
            return None;
        }
        let centre = lines.iter().map(|(p, _, w)| p * *w).sum::<Vector3<f64>>() / total;
        let (mut a, mut b, mut c) = (Matrix3::zeros(), Matrix3::zeros(), Matrix3::zeros());
        for (p, n, w) in &lines {
            let m = (p - centre).cross(n);
            a += m * m.transpose() * *w;
            b += m * n.transpose() * *w;
            c += n * n.transpose() * *w;
        }
        if c.symmetric_eigen().eigenvalues.min() < 1e-6 * c.trace() {
            return None;
        }
        let c_inverse = c.try_inverse()?;
        let schur = a - b * c_inverse * b.transpose();
        let eigen = schur.symmetric_eigen();
        let axis = Unit::try_new(
            eigen
                .eigenvectors
                .column(eigen.eigenvalues.imin())
                .into_owned(),
            1e-9,
        )?;
        let moment = -(c_inverse * b.transpose() * axis.into_inner());
        let through = axis.cross(&moment) + centre;
        Some(Self {
            axis,
            point: Point3::from(through - axis.into_inner() * axis.dot(&through)),
        })
    }

    /// Whether the line through `point` along `direction` is this axis: within 5° of its
    /// direction, either way, and `point` within `distance` of it.
    pub fn holds(&self, direction: &Vector3<f64>, point: &Point3<f64>, distance: f64) -> bool {
        let offset = point - self.point;
        let across = offset - self.axis.into_inner() * self.axis.dot(&offset);
        self.parallel(direction) && across.norm() <= distance
    }

    /// Whether `direction` lies within [`SAME_SYMMETRY`] of the axis's, either way.
    fn parallel(&self, direction: &Vector3<f64>) -> bool {
        self.axis.dot(&direction.normalize()).abs() >= SAME_SYMMETRY.cos()
    }
}

/// The turns (degrees) at which an axis of symmetry is tested: none is a multiple of a half, a
/// third, …, or a twelfth of a turn, so an axis of discrete symmetry (a box's half turns, a
/// hexagonal prism's sixths) fails them.
const CONTINUITY_TEST_DEG: [f64; 3] = [7.3, 19.1, 53.9];

/// The share of a model's points that may lie more than a voxel off its surface after a turn
/// about an axis of symmetry: a mug's handle, a twentieth of its surface, is not a symmetry
/// of the mug, though the mean residual of its turns is as small as a real scan's symmetry.
const OFF_SURFACE_SHARE: f64 = 0.002;

/// The axes of a model's turns ([`turn_axes`]), in the model's frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TurnAxes {
    /// The axes about which every turn maps the model onto itself: a can's, a bowl's.
    pub symmetric: Vec<SymmetryAxis>,
    /// The axes about which every turn maps all but a small part of the model onto itself: a
    /// mug's body, whose handle its turns move. A view that hides the part cannot tell these
    /// turns apart; one that shows it is easily labelled a turn off.
    pub nearly: Vec<SymmetryAxis>,
}

/// The axes about which turns map the model onto itself, from the screw axes of its
/// self-symmetries `symmetries` ([`discover_symmetries`]), no two within 5° of each other: an
/// axis whose turns of 7.3°, 19.1° and 53.9° (none a whole fraction of a turn up to a twelfth)
/// all leave a surface residual under [`SYMMETRIC_RESIDUAL`] · `voxel` is symmetric when under
/// 0.2% of the points lie a voxel or more off the surface after each, and nearly symmetric
/// otherwise. A can and a bowl have one symmetric axis, a mug one nearly symmetric, a box none,
/// a sphere three symmetric. A symmetric axis that `revolution` (the surface's axis of
/// revolution, [`SymmetryAxis::of_revolution`]) lies on, within 5° and a
/// voxel, and that passes the same test, is replaced by it: a bowl's screw axis is 0.12° off,
/// its fitted axis 0.01°.
pub fn turn_axes(
    model: &PreparedCloud,
    voxel: f32,
    symmetries: &[Isometry3<f64>],
    revolution: Option<SymmetryAxis>,
) -> TurnAxes {
    // The largest turns first: their axis points are the best determined.
    let mut candidates: Vec<(f64, SymmetryAxis)> = symmetries
        .iter()
        .filter_map(|s| Some((s.rotation.angle(), SymmetryAxis::of_motion(s)?)))
        .filter(|(angle, _)| *angle > SAME_SYMMETRY)
        .collect();
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
    let bar = SYMMETRIC_RESIDUAL * f64::from(voxel);
    // Whether each test turn about an axis stays under the bar, and whether each leaves under
    // OFF_SURFACE_SHARE of the points off the surface.
    let test = |axis: &SymmetryAxis| {
        let (mut close, mut exact) = (true, true);
        for degrees in CONTINUITY_TEST_DEG {
            let turn = axis.turn(degrees.to_radians());
            let distances = surface_distances(model.cloud.points(), model, &turn, voxel);
            let mean = distances.iter().sum::<f64>() / distances.len().max(1) as f64;
            let off = distances.iter().filter(|&&d| d >= f64::from(voxel)).count();
            close &= mean < bar;
            exact &= (off as f64) < OFF_SURFACE_SHARE * distances.len() as f64;
        }
        (close, exact)
    };
    let mut axes = TurnAxes::default();
    for (_, candidate) in candidates {
        let seen = axes.symmetric.iter().chain(&axes.nearly);
        if seen.clone().any(|a| a.parallel(&candidate.axis)) {
            continue;
        }
        match test(&candidate) {
            (true, true) => {
                // A symmetric axis is the surface's axis of revolution, which the fit to
                // every normal finds more finely than one motion's screw axis.
                let fitted = revolution
                    .filter(|r| r.holds(&candidate.axis, &candidate.point, f64::from(voxel)))
                    .filter(|r| test(r) == (true, true));
                axes.symmetric.push(fitted.unwrap_or(candidate));
            }
            (true, false) => axes.nearly.push(candidate),
            _ => {}
        }
    }
    axes
}

/// `symmetries` (identity first) without those that a turn about one of `axes` (within
/// `distance` of it) takes onto one kept before them: a can's turns about its axis reduce to
/// the identity and one half turn that puts it upside down.
pub fn apart_from_axes(
    symmetries: &[Isometry3<f64>],
    axes: &[SymmetryAxis],
    distance: f64,
) -> Vec<Isometry3<f64>> {
    let mut kept: Vec<Isometry3<f64>> = Vec::with_capacity(symmetries.len());
    for symmetry in symmetries {
        let reached = kept.iter().any(|k| {
            let between = k.inverse() * symmetry;
            between.rotation.angle() <= SAME_SYMMETRY
                || SymmetryAxis::of_motion(&between).is_some_and(|turn| {
                    axes.iter()
                        .any(|a| a.holds(&turn.axis, &turn.point, distance))
                })
        });
        if !reached {
            kept.push(*symmetry);
        }
    }
    kept
}

/// Turns about each of `axes` every 15° (the identity left out): the poses a view
/// of an object with a nearly symmetric axis ([`TurnAxes::nearly`]) is mistaken for when the
/// part that breaks the symmetry shows. Checked with the principal turns
/// ([`principal_turns`]), by ICP whose correspondences reach three voxels: a pose 7.5° off the
/// truth pulls a mug's handle, 50 mm from the axis, back from 6.5 mm.
pub fn near_axis_turns(axes: &[SymmetryAxis]) -> Vec<Isometry3<f64>> {
    let steps = (360.0 / NEAR_TURN_DEG).round() as usize;
    axes.iter()
        .flat_map(|axis| {
            (1..steps).map(move |k| axis.turn((k as f64 * NEAR_TURN_DEG).to_radians()))
        })
        .collect()
}

/// Degrees between the turns of [`near_axis_turns`].
const NEAR_TURN_DEG: f64 = 15.0;

/// The 23 turns (model frame, metres) about the model's centroid that map its principal axes
/// onto themselves (the rotation group of a cube in the frame of the model's inertia: quarter
/// and half turns about the axes, third turns about the diagonals), without those that are
/// symmetries themselves (surface residual under [`SYMMETRIC_RESIDUAL`] · `voxel`, as in
/// [`discover_symmetries`]) or within 5° of one of `symmetries`: re-seeding from the
/// symmetries reaches those. Empty for an empty cloud.
pub fn principal_turns(
    model: &PreparedCloud,
    voxel: f32,
    symmetries: &[Isometry3<f64>],
) -> Vec<Isometry3<f64>> {
    let Some(frame) = model.cloud.principal_frame() else {
        return Vec::new();
    };
    cube_rotations()
        .into_iter()
        .skip(1)
        .map(|turn| frame * Isometry3::from_parts(Translation3::identity(), turn) * frame.inverse())
        .filter(|turn| {
            symmetries
                .iter()
                .all(|s| geodesic_distance(&s.rotation, &turn.rotation) > SAME_SYMMETRY)
                && surface_residual(model.cloud.points(), model, turn, voxel)
                    >= SYMMETRIC_RESIDUAL * f64::from(voxel)
        })
        .collect()
}

/// The 24 rotations that map the coordinate axes onto themselves, identity first.
fn cube_rotations() -> Vec<UnitQuaternion<f64>> {
    let quarter = |axis: Vector3<f64>, k: u32| {
        UnitQuaternion::from_scaled_axis(axis * f64::from(k) * std::f64::consts::FRAC_PI_2)
    };
    let mut rotations: Vec<UnitQuaternion<f64>> = Vec::with_capacity(24);
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                let rotation =
                    quarter(Vector3::x(), a) * quarter(Vector3::y(), b) * quarter(Vector3::z(), c);
                if rotations.iter().all(|r| r.angle_to(&rotation) > 0.1) {
                    rotations.push(rotation);
                }
            }
        }
    }
    rotations
}

/// Up to `count` of `rotations` spread as evenly as possible: the first, then repeatedly the
/// one farthest from all chosen (farthest-point sampling). Indices into `rotations`.
pub fn spread(rotations: &[UnitQuaternion<f64>], count: usize) -> Vec<usize> {
    if rotations.is_empty() || count == 0 {
        return Vec::new();
    }
    let mut chosen = vec![0];
    let mut nearest: Vec<f64> = rotations
        .iter()
        .map(|r| geodesic_distance(r, &rotations[0]))
        .collect();
    while chosen.len() < count.min(rotations.len()) {
        let (next, &distance) = nearest
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
            .expect("not empty");
        if distance <= 0.0 {
            break;
        }
        chosen.push(next);
        for (d, r) in nearest.iter_mut().zip(rotations) {
            *d = d.min(geodesic_distance(r, &rotations[next]));
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;
    use registration::PointCloud;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// Farthest-point sampling keeps the first rotation, never picks one twice, and its
        /// choice covers the set: every rotation is within the smallest gap between chosen ones.
        #[test]
        fn spread_is_distinct_and_covering(seed in 0u64..1000, count in 1usize..12) {
            let rotations = so3_grid::random_rotations(40, seed);
            let chosen = spread(&rotations, count);
            prop_assert_eq!(chosen[0], 0);
            prop_assert_eq!(chosen.len(), count.min(40));
            let mut sorted = chosen.clone();
            sorted.sort_unstable();
            sorted.dedup();
            prop_assert_eq!(sorted.len(), chosen.len());
            let gap = chosen.iter().enumerate().flat_map(|(i, &a)| {
                chosen[i + 1..].iter().map(move |&b| (a, b))
            }).map(|(a, b)| geodesic_distance(&rotations[a], &rotations[b]))
            .fold(f64::INFINITY, f64::min);
            for r in &rotations {
                let reach = chosen.iter().map(|&c| geodesic_distance(r, &rotations[c])).fold(f64::INFINITY, f64::min);
                prop_assert!(reach <= gap + 1e-12);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// The turns of a cloud with no symmetry are 23 distinct rotations about its centroid
        /// (they keep it in place) that map its principal axes onto themselves, and those
        /// within 5° of a known symmetry are left out.
        #[test]
        fn principal_turns_map_the_principal_axes_onto_themselves(
            seed in 0u64..1000,
            known in 0usize..4,
        ) {
            use rand::SeedableRng;
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            // Points filling a 3:2:1 box, far apart for the voxel: no turn maps them onto
            // themselves.
            let points: Vec<Point3<f32>> = (0..200)
                .map(|_| Point3::new(rng.random_range(-0.3..0.3), rng.random_range(-0.2..0.2), rng.random_range(-0.1..0.1)))
                .collect();
            let normals = vec![Vector3::z(); points.len()];
            let cloud = PointCloud::new(points).unwrap().with_normals(normals).unwrap();
            let voxel = 0.001;
            let options = registration::PrepareOptions {
                keep_normals: true,
                ..registration::PrepareOptions::for_voxel(voxel)
            };
            let model = registration::prepare_cloud(&cloud, &options).unwrap();
            let all = principal_turns(&model, voxel, &[Isometry3::identity()]);
            prop_assert_eq!(all.len(), 23);
            let symmetries: Vec<_> = std::iter::once(Isometry3::identity())
                .chain(all[..known].iter().copied())
                .collect();
            let turns = principal_turns(&model, voxel, &symmetries);
            prop_assert_eq!(&turns[..], &all[known..]);
            let centroid = model.cloud.centroid().unwrap();
            let axes = model.cloud.principal_frame().unwrap().rotation.to_rotation_matrix();
            for (i, turn) in turns.iter().enumerate() {
                prop_assert!((turn * centroid - centroid).norm() < 1e-9);
                prop_assert!(turn.rotation.angle() > 1.0);
                for axis in axes.matrix().column_iter() {
                    let image = turn.rotation * axis;
                    let nearest = axes.matrix().column_iter().map(|a| a.dot(&image).abs()).fold(0.0, f64::max);
                    prop_assert!((nearest - 1.0).abs() < 1e-9);
                }
                for other in &turns[i + 1..] {
                    prop_assert!(geodesic_distance(&other.rotation, &turn.rotation) > 1.0);
                }
            }
        }
    }

    proptest! {
        /// The screw axis of a turn about a line (with or without a shift along it) is that
        /// line: the same direction, and the point of it nearest the origin.
        #[test]
        fn the_axis_of_a_turn_is_its_line(
            direction in prop::array::uniform3(-1.0..1.0f64),
            point in prop::array::uniform3(-0.5..0.5f64),
            angle in 0.01..3.13f64,
            pitch in -0.1..0.1f64,
        ) {
            let direction = Vector3::from(direction);
            prop_assume!(direction.norm() > 0.1);
            let axis = Unit::new_normalize(direction);
            let line = SymmetryAxis { axis, point: Point3::from(Vector3::from(point)) };
            let motion = Translation3::from(axis.into_inner() * pitch) * line.turn(angle);
            let found = SymmetryAxis::of_motion(&motion).unwrap();
            prop_assert!((found.axis.into_inner() - axis.into_inner()).norm() < 1e-9);
            let nearest = line.point - axis.into_inner() * axis.dot(&line.point.coords);
            prop_assert!((found.point - nearest).norm() < 1e-9, "{} vs {}", found.point, nearest);
            prop_assert!(found.holds(&-direction, &(line.point + axis.into_inner() * 0.3), 1e-9));
            prop_assert!(SymmetryAxis::of_motion(&Translation3::from(axis.into_inner() * pitch).into()).is_none());
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// A bowl or a cone of random size and segments, placed by a random rigid motion: the
        /// fit recovers the placed axis, the line the motion takes the mesh's z axis to. A
        /// flat mesh has no axis.
        #[test]
        fn the_axis_of_revolution_of_a_placed_mesh_is_found(
            radius in 0.02..0.2f64,
            height in 0.02..0.2f64,
            segments in 6u32..100,
            bowl in any::<bool>(),
            rotation in prop::array::uniform3(-3.0..3.0f64),
            shift in prop::array::uniform3(-0.5..0.5f64),
        ) {
            use depth_render::Primitive;
            let shape = if bowl {
                Primitive::Bowl { radius, height, thickness: 0.1 * radius.min(height), segments, rings: 6 }
            } else {
                Primitive::Cone { radius, height, segments }
            };
            let mesh = shape.mesh().unwrap();
            let place = Isometry3::new(Vector3::from(shift), Vector3::from(rotation));
            let positions = mesh.positions().iter().map(|p| (place * p.cast::<f64>()).cast()).collect();
            let placed = TriangleMesh::new(positions, mesh.triangles().to_vec()).unwrap();
            let found = SymmetryAxis::of_revolution(&placed).unwrap();
            let axis = place.rotation * Vector3::z();
            prop_assert!(found.axis.dot(&axis).abs() > (1e-5f64).cos(), "{found:?} vs {axis}");
            prop_assert!(found.holds(&axis, &(place * Point3::origin()), 1e-5), "{found:?}");
            let square = [[0.0, 0.0, 0.0], [radius, 0.0, 0.0], [radius, height, 0.0], [0.0, height, 0.0]];
            let flat = TriangleMesh::new(
                square.iter().map(|&p| (place * Point3::from(p)).cast()).collect(),
                vec![[0, 1, 2], [0, 2, 3]],
            ).unwrap();
            prop_assert!(SymmetryAxis::of_revolution(&flat).is_none());
        }
    }

    #[test]
    fn the_cube_group_has_24_rotations() {
        let rotations = cube_rotations();
        assert_eq!(rotations.len(), 24);
        assert_eq!(rotations[0].angle(), 0.0);
        // Closed under composition.
        for a in &rotations {
            for b in &rotations {
                assert!(rotations.iter().any(|r| r.angle_to(&(a * b)) < 1e-9));
            }
        }
    }

    #[test]
    fn spread_of_a_circle_is_even() {
        let circle: Vec<_> = (0..360)
            .map(|d| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), f64::from(d).to_radians()))
            .collect();
        let chosen = spread(&circle, 4);
        let mut angles: Vec<usize> = chosen.clone();
        angles.sort_unstable();
        assert_eq!(angles, vec![0, 90, 180, 270]);
    }
}
