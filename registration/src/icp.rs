//! Iterative Closest Point: point-to-point (closed form) and point-to-plane (Gauss–Newton).

use std::num::NonZeroUsize;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::cloud::centre_and_radius;
use crate::error::positive_metres;
use crate::neighbours::{AgreeingScratch, Neighbour, PointIndex};
use crate::twist::{NormalEquations, kabsch, mean_shift};
use crate::{PointCloud, RegistrationError};

/// The error ICP minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IcpMethod {
    /// Σ ‖T p − q‖², solved in closed form each iteration (Besl & McKay 1992).
    PointToPoint,
    /// Σ ((T p − q) · n_q)², one Gauss–Newton step on the twist per iteration (Chen &
    /// Medioni 1992); needs target normals.
    PointToPlane,
}

/// A robust kernel: residuals are weighted by w(r) (iteratively reweighted least squares).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobustKernel {
    /// w = 1 for |r| ≤ k, k/|r| beyond (k in metres).
    Huber(f64),
    /// w = (1 − (r/k)²)² for |r| ≤ k, 0 beyond.
    Tukey(f64),
    /// w = 1 / (1 + (r/k)²).
    Cauchy(f64),
}

impl RobustKernel {
    fn weight(self, residual: f64) -> f64 {
        let r = residual.abs();
        match self {
            Self::Huber(k) => {
                if r <= k {
                    1.0
                } else {
                    k / r
                }
            }
            Self::Tukey(k) => {
                if r <= k {
                    (1.0 - (r / k).powi(2)).powi(2)
                } else {
                    0.0
                }
            }
            Self::Cauchy(k) => 1.0 / (1.0 + (r / k).powi(2)),
        }
    }

    fn scale(self) -> f64 {
        match self {
            Self::Huber(k) | Self::Tukey(k) | Self::Cauchy(k) => k,
        }
    }
}

/// Options of [`refine_icp`]; the convergence criteria are Open3D's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpOptions {
    /// Error to minimise.
    pub method: IcpMethod,
    /// Pairs farther apart than this (metres) are not correspondences.
    pub max_correspondence_distance: f32,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Stop when the fitness changes by less than this between iterations…
    pub relative_fitness: f64,
    /// …and the inlier RMSE by less than this (metres).
    pub relative_rmse: f64,
    /// Point-to-plane: leave out of each update the directions the correspondences hardly
    /// constrain, those whose eigenvalue in the normal equations is under this fraction of the
    /// largest (the turn about the source's centroid measured by its sweep at the RMS radius,
    /// so that turns and shifts compare). A cylinder's or a bowl's turn about its axis is such
    /// a direction: noisy points turn the pose on and on, or back and forth as a few of them
    /// change partner, and ICP never settles. 0 (off, a plain Cholesky solve) in Open3D's
    /// criteria.
    pub min_eigen_ratio: f64,
    /// Optional robust kernel.
    pub kernel: Option<RobustKernel>,
    /// Pair each source point with the nearest of its 8 nearest target points whose normal is
    /// within this many radians of its own (turned by the pose); needs normals on both clouds.
    /// Keeps the two sides of a thin wall (a bowl) from being matched to each other.
    pub max_normal_angle: Option<f32>,
    /// Solve for the shift alone and keep the rotation of the initial pose: where a pose is
    /// tried rotation by rotation (an SO(3) grid), ICP finds each rotation's best shift without
    /// turning it towards a neighbour. Directions of the shift the correspondences hardly
    /// constrain (along a flat face) are left out as `min_eigen_ratio` says.
    pub shift_only: bool,
}

impl Default for IcpOptions {
    /// Point-to-plane, 7.5 mm (1.5 voxels of 5 mm), 30 iterations, 1e-6 / 1e-6, every
    /// direction solved, no kernel, no normal test, rotation and shift.
    fn default() -> Self {
        Self {
            method: IcpMethod::PointToPlane,
            max_correspondence_distance: 0.0075,
            max_iterations: 30,
            relative_fitness: 1e-6,
            relative_rmse: 1e-6,
            min_eigen_ratio: 0.0,
            kernel: None,
            max_normal_angle: None,
            shift_only: false,
        }
    }
}

impl IcpOptions {
    /// Checks every option [`refine_icp`] relies on: a positive correspondence distance, a
    /// kernel with a positive scale, `min_eigen_ratio` in [0, 1) and a non-negative, finite
    /// normal angle. `refine_icp` calls it first.
    pub fn validate(&self) -> Result<(), RegistrationError> {
        positive_metres(
            "max_correspondence_distance",
            self.max_correspondence_distance,
        )?;
        if let Some(kernel) = self.kernel
            && !(kernel.scale().is_finite() && kernel.scale() > 0.0)
        {
            return Err(RegistrationError::InvalidOption {
                name: "kernel",
                value: kernel.scale(),
                reason: "scale must be positive",
            });
        }
        if !(0.0..1.0).contains(&self.min_eigen_ratio) {
            return Err(RegistrationError::InvalidOption {
                name: "min_eigen_ratio",
                value: self.min_eigen_ratio,
                reason: "must be at least 0 and below 1",
            });
        }
        if let Some(angle) = self.max_normal_angle
            && !(angle.is_finite() && angle >= 0.0)
        {
            return Err(RegistrationError::InvalidOption {
                name: "max_normal_angle",
                value: f64::from(angle),
                reason: "must be a non-negative angle",
            });
        }
        Ok(())
    }
}

/// A refined alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alignment {
    /// Source → target rigid transform (metres).
    pub pose: Isometry3<f64>,
    /// Fraction of source points with a target point within the correspondence distance.
    pub fitness: f64,
    /// RMS distance of those correspondences (metres).
    pub inlier_rmse: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Refines `initial` (source → target) by ICP. `target_index` must index `target`'s points.
///
/// Each iteration pairs every moved source point with its nearest target point within
/// `max_correspondence_distance` (in parallel), then solves for an update. It stops when
/// fitness and RMSE both settle or after `max_iterations`. The returned fitness and RMSE are
/// those of the returned pose.
///
/// Errors: empty clouds, bad options, missing target normals (point-to-plane), no
/// correspondences at the initial pose. When the correspondences cannot fix all six degrees of
/// freedom (a singular update) it stops and returns the pose reached so far.
pub fn refine_icp(
    source: &PointCloud,
    target: &PointCloud,
    target_index: &PointIndex,
    initial: &Isometry3<f64>,
    options: &IcpOptions,
) -> Result<Alignment, RegistrationError> {
    if source.is_empty() {
        return Err(RegistrationError::EmptyCloud { cloud: "source" });
    }
    if target.is_empty() {
        return Err(RegistrationError::EmptyCloud { cloud: "target" });
    }
    options.validate()?;
    let normal_test = options
        .max_normal_angle
        .map(|angle| NormalTest::new(source, target, angle))
        .transpose()?;
    let target_normals = match options.method {
        IcpMethod::PointToPlane => Some(target_normals(target)?),
        IcpMethod::PointToPoint => None,
    };
    let pair = |pose: &Isometry3<f64>| {
        correspondences(
            source.points(),
            target_index,
            pose,
            options.max_correspondence_distance,
            normal_test.as_ref(),
        )
    };
    let mut pose = *initial;
    let mut matches = pair(&pose);
    let mut score = Score::of(&matches, source.len());
    if score.count == 0 {
        return Err(RegistrationError::NoCorrespondences {
            stage: "ICP",
            found: 0,
            needed: 3,
        });
    }
    let step = Step {
        source: source.points(),
        target: target.points(),
        target_normals,
        // The turn of a constrained solve is taken about the source's centroid.
        spread: (options.min_eigen_ratio > 0.0)
            .then(|| centre_and_radius(source.points()))
            .flatten(),
        options,
    };
    let mut iterations = 0;
    while iterations < options.max_iterations {
        // Too few or degenerate correspondences to fix every degree of freedom: stay put.
        let Some(update) = step.solve(&matches, &pose) else {
            break;
        };
        pose = update * pose;
        iterations += 1;
        matches = pair(&pose);
        let previous = score;
        score = Score::of(&matches, source.len());
        if (score.fitness - previous.fitness).abs() < options.relative_fitness
            && (score.inlier_rmse - previous.inlier_rmse).abs() < options.relative_rmse
        {
            break;
        }
    }
    Ok(Alignment {
        pose,
        fitness: score.fitness,
        inlier_rmse: score.inlier_rmse,
        iterations,
    })
}

/// A turn of the source that the correspondences at a pose hardly constrain: the source may
/// turn about this axis (target frame) and hardly move off the target's surface, as a can
/// about its own axis or a mug whose handle is out of sight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeakTurn {
    /// The axis's direction.
    pub axis: Unit<Vector3<f64>>,
    /// A point on the axis (metres).
    pub point: Point3<f64>,
    /// The direction's eigenvalue over the largest in the point-to-plane normal equations
    /// (turns measured by their sweep at the source's RMS radius, so that turns and shifts
    /// compare).
    pub ratio: f64,
}

impl WeakTurn {
    /// The motion (target frame) turning by `angle` radians about the axis.
    pub fn motion(&self, angle: f64) -> Isometry3<f64> {
        let centre = Translation3::from(self.point.coords);
        centre
            * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&self.axis, angle),
            )
            * centre.inverse()
    }
}

/// The turns of `pose` (source → target) that the point-to-plane correspondences there leave
/// under `min_ratio` of the best-constrained direction ([`IcpOptions::min_eigen_ratio`]
/// explains the measure), weakest first; a direction that is mostly a shift (a plane sliding)
/// is no turn and is left out. Pairs are made as one [`refine_icp`] iteration makes them under
/// `options` (distance, normal test); needs target normals.
pub fn weak_turns(
    source: &PointCloud,
    target: &PointCloud,
    target_index: &PointIndex,
    pose: &Isometry3<f64>,
    options: &IcpOptions,
    min_ratio: f64,
) -> Result<Vec<WeakTurn>, RegistrationError> {
    options.validate()?;
    let normals = target_normals(target)?;
    let normal_test = options
        .max_normal_angle
        .map(|angle| NormalTest::new(source, target, angle))
        .transpose()?;
    let matches = correspondences(
        source.points(),
        target_index,
        pose,
        options.max_correspondence_distance,
        normal_test.as_ref(),
    );
    let Some((centre, radius)) = centre_and_radius(source.points()) else {
        return Ok(Vec::new());
    };
    let mut equations = NormalEquations::new();
    for (i, m) in matches.iter().enumerate() {
        let Some(m) = m else { continue };
        let moved = pose * source.points()[i].cast::<f64>();
        let target = target.points()[m.index as usize].cast::<f64>();
        let normal: Vector3<f64> = normals[m.index as usize].cast();
        equations.add_point_to_plane(&moved.coords, &target.coords, &normal, 1.0);
    }
    let mut turns: Vec<WeakTurn> = equations
        .weak_turns(&(pose * centre), radius, min_ratio)
        .into_iter()
        .map(|(axis, point, ratio)| WeakTurn { axis, point, ratio })
        .collect();
    turns.sort_by(|a, b| a.ratio.total_cmp(&b.ratio));
    Ok(turns)
}

/// The target's normals, which point-to-plane ICP needs.
fn target_normals(target: &PointCloud) -> Result<&[Vector3<f32>], RegistrationError> {
    target.normals().ok_or(RegistrationError::MissingNormals {
        stage: "point-to-plane ICP",
    })
}

/// What one ICP iteration solves with: the clouds, the target's normals (point-to-plane) and
/// the source's centroid and RMS radius (a constrained solve).
struct Step<'a> {
    source: &'a [Point3<f32>],
    target: &'a [Point3<f32>],
    target_normals: Option<&'a [Vector3<f32>]>,
    spread: Option<(Point3<f64>, f64)>,
    options: &'a IcpOptions,
}

impl Step<'_> {
    /// The update of `pose` that the correspondences `matches` call for (closed form, or one
    /// Gauss–Newton step), or `None` when they cannot fix every degree of freedom.
    fn solve(
        &self,
        matches: &[Option<Neighbour>],
        pose: &Isometry3<f64>,
    ) -> Option<Isometry3<f64>> {
        let kernel = self.options.kernel;
        let pairs = matches.iter().enumerate().filter_map(|(i, m)| {
            m.map(|m| {
                (
                    (pose * self.source[i].cast::<f64>()),
                    self.target[m.index as usize].cast::<f64>(),
                    m.index,
                )
            })
        });
        let Some(normals) = self.target_normals else {
            let weighted: Vec<_> = pairs
                .map(|(moved, target, _)| {
                    let weight = kernel.map_or(1.0, |k| k.weight((moved - target).norm()));
                    (moved, target, weight)
                })
                .collect();
            return if self.options.shift_only {
                mean_shift(&weighted)
            } else {
                kabsch(&weighted)
            };
        };
        let mut equations = NormalEquations::new();
        for (moved, target, index) in pairs {
            let normal: Vector3<f64> = normals[index as usize].cast();
            let weight = kernel.map_or(1.0, |k| k.weight((moved - target).dot(&normal)));
            equations.add_point_to_plane(&moved.coords, &target.coords, &normal, weight);
        }
        if self.options.shift_only {
            return equations.solve_shift(self.options.min_eigen_ratio);
        }
        match self.spread {
            Some((centre, radius)) => {
                equations.solve_constrained(&(pose * centre), radius, self.options.min_eigen_ratio)
            }
            None => equations.solve(),
        }
    }
}

/// Fraction of `source` points (moved by `pose`) with a target point within `max_distance`
/// (ICP's fitness at that pose, without iterating). `target_index` indexes the target.
pub fn overlap(
    source: &[Point3<f32>],
    target_index: &PointIndex,
    pose: &Isometry3<f64>,
    max_distance: f32,
) -> f64 {
    if source.is_empty() {
        return 0.0;
    }
    Score::of(
        &correspondences(source, target_index, pose, max_distance, None),
        source.len(),
    )
    .fitness
}

/// The normals of both clouds and the smallest cosine between paired normals.
struct NormalTest<'a> {
    source: &'a [Vector3<f32>],
    target: &'a [Vector3<f32>],
    min_cosine: f32,
}

impl<'a> NormalTest<'a> {
    /// Pairs whose normals differ by at most `max_angle` (radians); both clouds need normals.
    fn new(
        source: &'a PointCloud,
        target: &'a PointCloud,
        max_angle: f32,
    ) -> Result<Self, RegistrationError> {
        let missing = || RegistrationError::MissingNormals {
            stage: "ICP normal compatibility",
        };
        Ok(Self {
            source: source.normals().ok_or_else(missing)?,
            target: target.normals().ok_or_else(missing)?,
            min_cosine: max_angle.cos(),
        })
    }
}

/// Target candidates searched per source point under a normal test.
const NORMAL_CANDIDATES: usize = 8;

/// For each source point (moved by `pose`), its nearest target point within `max_distance`;
/// with a normal test, the nearest of the 8 nearest whose normal agrees.
fn correspondences(
    source: &[Point3<f32>],
    target_index: &PointIndex,
    pose: &Isometry3<f64>,
    max_distance: f32,
    normals: Option<&NormalTest>,
) -> Vec<Option<Neighbour>> {
    let pose = pose.cast::<f32>();
    let Some(test) = normals else {
        return source
            .par_iter()
            .map(|p| {
                let moved = pose * p;
                target_index.nearest_within_radius(&[moved.x, moved.y, moved.z], max_distance)
            })
            .collect();
    };
    let candidates = NonZeroUsize::new(NORMAL_CANDIDATES).expect("not zero");
    source
        .par_iter()
        .zip(test.source)
        .map_init(AgreeingScratch::default, |scratch, (p, normal)| {
            let moved = pose * p;
            let query = [moved.x, moved.y, moved.z];
            let turned = pose.rotation * normal;
            let agrees = |index: u32| turned.dot(&test.target[index as usize]) >= test.min_cosine;
            // The nearest usually agrees; only otherwise are the next ones searched.
            let nearest = target_index.nearest_within_radius(&query, max_distance)?;
            if agrees(nearest.index) {
                return Some(nearest);
            }
            target_index.nearest_agreeing(&query, max_distance, candidates, agrees, scratch)
        })
        .collect()
}

/// Fitness and inlier RMSE of a correspondence set.
#[derive(Debug, Clone, Copy)]
struct Score {
    count: usize,
    fitness: f64,
    inlier_rmse: f64,
}

impl Score {
    fn of(matches: &[Option<Neighbour>], source_len: usize) -> Self {
        let (count, sum) = matches.iter().flatten().fold((0usize, 0f64), |(c, s), n| {
            (c + 1, s + f64::from(n.distance_squared))
        });
        let inlier_rmse = if count == 0 {
            0.0
        } else {
            (sum / count as f64).sqrt()
        };
        Self {
            count,
            fitness: count as f64 / source_len as f64,
            inlier_rmse,
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::normals::{NormalOptions, NormalOrientation, estimate_normals};

    /// A closed, lumpy, non-symmetric surface (~1.5 mm spacing) and a small rigid motion.
    fn patch() -> (PointCloud, Isometry3<f64>) {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let points = (0..8000)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 8000.0;
                let (r, a) = ((1.0 - z * z).sqrt(), golden * i as f32);
                let u = Vector3::new(r * a.cos(), r * a.sin(), z);
                let radius =
                    0.05 * (1.0 + 0.3 * u.x + 0.2 * (3.0 * u.y + 1.0).sin() * (2.0 * u.z).cos());
                Point3::new(0.0, 0.0, 0.5) + u.component_mul(&Vector3::new(1.0, 0.8, 0.6)) * radius
            })
            .collect();
        let motion = Isometry3::new(
            Vector3::new(0.002, -0.001, 0.0015),
            Vector3::new(0.03, -0.02, 0.04),
        );
        (PointCloud::new(points).unwrap(), motion)
    }

    fn with_normals(cloud: &PointCloud) -> (PointCloud, PointIndex) {
        let index = PointIndex::from_points(cloud.points());
        let options = NormalOptions {
            radius: 0.006,
            max_neighbours: 30,
            orientation: NormalOrientation::Consistent { neighbours: 10 },
        };
        (estimate_normals(cloud, &index, &options).unwrap(), index)
    }

    #[test]
    fn both_methods_recover_a_small_motion() {
        let (source, truth) = patch();
        let (target, index) = with_normals(&source.transformed(&truth));
        for method in [IcpMethod::PointToPoint, IcpMethod::PointToPlane] {
            let options = IcpOptions {
                method,
                max_correspondence_distance: 0.01,
                max_iterations: 100,
                ..IcpOptions::default()
            };
            let found =
                refine_icp(&source, &target, &index, &Isometry3::identity(), &options).unwrap();
            let error = found.pose.inverse() * truth;
            let (angle, shift) = (error.rotation.angle(), error.translation.vector.norm());
            assert!(
                angle < 2e-3 && shift < 2e-4,
                "{method:?}: {angle} rad, {shift} m"
            );
            assert!(
                found.fitness > 0.95 && found.inlier_rmse < 5e-4,
                "{method:?}: {found:?}"
            );
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(16))]
        /// With `shift_only`, both methods keep the initial rotation to the last bit and find
        /// the shift of a known motion when that rotation is the motion's.
        #[test]
        fn a_shift_only_solve_finds_the_shift_and_keeps_the_rotation(
            shift in proptest::array::uniform3(-0.004..0.004f64),
            turn in proptest::array::uniform3(-0.05..0.05f64),
            point_to_plane in proptest::bool::ANY,
        ) {
            let (source, _) = patch();
            let truth = Isometry3::new(Vector3::from(shift), Vector3::from(turn));
            let (target, index) = with_normals(&source.transformed(&truth));
            let options = IcpOptions {
                method: if point_to_plane { IcpMethod::PointToPlane } else { IcpMethod::PointToPoint },
                max_correspondence_distance: 0.01,
                max_iterations: 100,
                shift_only: true,
                ..IcpOptions::default()
            };
            let initial = Isometry3::from_parts(Translation3::identity(), truth.rotation);
            let found = refine_icp(&source, &target, &index, &initial, &options).unwrap();
            proptest::prop_assert_eq!(found.pose.rotation, truth.rotation);
            let error = (found.pose.translation.vector - truth.translation.vector).norm();
            proptest::prop_assert!(error < 2e-4, "{} m off", error);
        }
    }

    /// `count` points drawn uniformly on a closed cylinder (radius 35 mm, height 100 mm, axis
    /// z, centred on the origin), with their normals.
    fn cylinder(rng: &mut ChaCha8Rng, count: usize) -> (Vec<Point3<f32>>, Vec<Vector3<f32>>) {
        let (radius, half_height) = (0.035f32, 0.05f32);
        let side = 2.0 * half_height / (2.0 * half_height + radius);
        (0..count)
            .map(|_| {
                let a = rng.random::<f32>() * std::f32::consts::TAU;
                if rng.random::<f32>() < side {
                    let z = (rng.random::<f32>() * 2.0 - 1.0) * half_height;
                    let normal = Vector3::new(a.cos(), a.sin(), 0.0);
                    (Point3::new(0.0, 0.0, z) + normal * radius, normal)
                } else {
                    let r = radius * rng.random::<f32>().sqrt();
                    let cap = if rng.random::<bool>() { 1.0 } else { -1.0 };
                    (
                        Point3::new(r * a.cos(), r * a.sin(), cap * half_height),
                        Vector3::new(0.0, 0.0, cap),
                    )
                }
            })
            .unzip()
    }

    #[test]
    fn leaving_out_unconstrained_directions_stops_a_turn_about_a_symmetry_axis() {
        // A cylinder's model points (~2 mm apart) and the noisy part of it seen from +x and above
        // (σ = 1 mm along the normal, as a depth sensor's at 0.8 m): the correspondences cannot
        // fix the turn about the axis.
        let (source, target) = cylinder_and_view(3);
        let index = PointIndex::from_points(target.points());
        let run = |min_eigen_ratio| {
            let options = IcpOptions {
                max_correspondence_distance: 0.006,
                max_normal_angle: Some(1.0),
                min_eigen_ratio,
                ..IcpOptions::default()
            };
            refine_icp(&source, &target, &index, &Isometry3::identity(), &options).unwrap()
        };
        let (bouncing, stopped) = (run(0.0), run(1e-3));
        // Started at the truth, the plain solve wanders about the axis for many iterations.
        assert!(bouncing.iterations >= 15, "{bouncing:?}");
        assert!(bouncing.pose.rotation.angle() > 0.05, "{bouncing:?}");
        // Without that direction it settles at once, as good a fit: the axis and the centre
        // where they were, the turn about the axis untouched.
        assert!(stopped.iterations <= 3, "{stopped:?}");
        let axis = stopped.pose.rotation * Vector3::z();
        assert!(axis.angle(&Vector3::z()) < 5e-3, "{axis}");
        let turn = stopped.pose.rotation * Vector3::x();
        assert!(turn.angle(&Vector3::x()) < 5e-3, "{turn}");
        assert!(stopped.pose.translation.vector.norm() < 3e-4, "{stopped:?}");
        assert!((stopped.inlier_rmse - bouncing.inlier_rmse).abs() < 5e-5);
        assert!((stopped.fitness - bouncing.fitness).abs() < 1e-2);
        for bad in [1.0, -0.1, f64::NAN] {
            let options = IcpOptions {
                min_eigen_ratio: bad,
                ..IcpOptions::default()
            };
            let refused = refine_icp(&source, &target, &index, &Isometry3::identity(), &options);
            assert!(
                matches!(
                    refused,
                    Err(RegistrationError::InvalidOption {
                        name: "min_eigen_ratio",
                        ..
                    })
                ),
                "{refused:?}"
            );
        }
    }

    /// The cylinder's target and the noisy part of it seen from +x and above, with normals.
    fn cylinder_and_view(seed: u64) -> (PointCloud, PointCloud) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (points, normals) = cylinder(&mut rng, 8000);
        let target = PointCloud::new(points)
            .unwrap()
            .with_normals(normals)
            .unwrap();
        let (seen, seen_normals): (Vec<_>, Vec<_>) = {
            let (points, normals) = cylinder(&mut rng, 3000);
            points
                .into_iter()
                .zip(normals)
                .filter(|(p, n)| n.x > 0.2 || n.z > 0.0 && p.x > 0.0)
                .map(|(p, n)| (p + n * (rng.random::<f32>() - 0.5) * 0.0035, n))
                .unzip()
        };
        let source = PointCloud::new(seen)
            .unwrap()
            .with_normals(seen_normals)
            .unwrap();
        (source, target)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(16))]
        /// A view of a cylinder, moved anywhere, leaves exactly one turn free: about the
        /// cylinder's axis (the z-axis of the target's frame, through its origin), and a turn
        /// about it keeps the view on the surface.
        #[test]
        fn the_free_turn_of_a_cylinder_is_its_axis(
            seed in 0u64..1000,
            axis in proptest::array::uniform3(-1.0..1.0f64),
            angle in 0.0..3.0f64,
            shift in proptest::array::uniform3(-0.3..0.3f64),
        ) {
            let (source, target) = cylinder_and_view(seed);
            let index = PointIndex::from_points(target.points());
            let axis = Vector3::from(axis);
            proptest::prop_assume!(axis.norm() > 0.1);
            let motion = Isometry3::new(Vector3::from(shift), axis.normalize() * angle);
            // The source moved away, and the pose that brings it back.
            let moved = source.transformed(&motion);
            let pose = motion.inverse();
            let options = IcpOptions {
                max_correspondence_distance: 0.006,
                max_normal_angle: Some(1.0),
                ..IcpOptions::default()
            };
            let turns = weak_turns(&moved, &target, &index, &pose, &options, 1e-3).unwrap();
            proptest::prop_assert_eq!(turns.len(), 1, "{:?}", turns);
            let turn = turns[0];
            proptest::prop_assert!(turn.axis.dot(&Vector3::z()).abs() > 0.999, "{:?}", turn);
            let off_axis = Vector3::new(turn.point.x, turn.point.y, 0.0).norm();
            proptest::prop_assert!(off_axis < 1e-3, "{:?}", turn);
            proptest::prop_assert!(turn.ratio < 1e-3);
            // Turned by 40° about it, the view still lies on the cylinder; about a
            // perpendicular axis through the same point, it does not.
            let on_surface = |pose: &Isometry3<f64>| overlap(moved.points(), &index, pose, 0.003);
            let at_truth = on_surface(&pose);
            proptest::prop_assert!(on_surface(&(turn.motion(0.7) * pose)) > 0.95 * at_truth);
            let across = WeakTurn { axis: Vector3::x_axis(), ..turn };
            proptest::prop_assert!(on_surface(&(across.motion(0.7) * pose)) < 0.5 * at_truth);
        }
    }

    #[test]
    fn a_lumpy_surface_has_no_free_turn() {
        let (source, truth) = patch();
        let (target, index) = with_normals(&source.transformed(&truth));
        let source = with_normals(&source).0;
        let options = IcpOptions {
            max_correspondence_distance: 0.01,
            max_normal_angle: Some(1.0),
            ..IcpOptions::default()
        };
        let turns = weak_turns(&source, &target, &index, &truth, &options, 1e-3).unwrap();
        assert!(turns.is_empty(), "{turns:?}");
        let bad = IcpOptions {
            max_correspondence_distance: -1.0,
            ..options
        };
        assert!(weak_turns(&source, &target, &index, &truth, &bad, 1e-3).is_err());
    }

    #[test]
    fn the_normal_test_keeps_the_two_sides_of_a_thin_wall_apart() {
        // Two parallel sheets 3 mm apart, facing away from each other; the source is the upper
        // sheet's points (normals up), started 2 mm below it: without the test the source
        // snaps onto the lower sheet (normals down), which is nearer.
        let sheet = |z: f32, up: f32| {
            let points: Vec<Point3<f32>> = (0..400)
                .map(|i| Point3::new((i % 20) as f32 * 0.003, (i / 20) as f32 * 0.003, z))
                .collect();
            let normals = vec![Vector3::new(0.0, 0.0, up); points.len()];
            (points, normals)
        };
        let (upper, upper_normals) = sheet(0.003, 1.0);
        let (lower, lower_normals) = sheet(0.0, -1.0);
        let target = PointCloud::new([upper.clone(), lower].concat())
            .unwrap()
            .with_normals([upper_normals.clone(), lower_normals].concat())
            .unwrap();
        let index = PointIndex::from_points(target.points());
        let source = PointCloud::new(upper)
            .unwrap()
            .with_normals(upper_normals)
            .unwrap();
        let start = Isometry3::translation(0.0015, 0.0015, -0.0025);
        let height = |max_normal_angle| {
            // Point-to-point: a flat sheet leaves point-to-plane's system singular.
            let options = IcpOptions {
                method: IcpMethod::PointToPoint,
                max_correspondence_distance: 0.004,
                max_normal_angle,
                ..IcpOptions::default()
            };
            let found = refine_icp(&source, &target, &index, &start, &options).unwrap();
            found.pose.translation.vector.z
        };
        assert!((height(None) + 0.003).abs() < 1e-4, "{}", height(None));
        assert!(height(Some(1.0)).abs() < 1e-4, "{}", height(Some(1.0)));
        let no_normals = PointCloud::new(vec![Point3::origin(); 3]).unwrap();
        let options = IcpOptions {
            max_normal_angle: Some(1.0),
            ..IcpOptions::default()
        };
        assert!(matches!(
            refine_icp(&no_normals, &target, &index, &start, &options),
            Err(RegistrationError::MissingNormals { .. })
        ));
    }

    #[test]
    fn a_robust_kernel_ignores_outliers() {
        let (clean, truth) = patch();
        let (target, index) = with_normals(&clean.transformed(&truth));
        // One source point in three lifted 4–8 mm along +z: least squares is pulled off the
        // true pose (where the search starts), a robust kernel much less.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut points = clean.points().to_vec();
        for p in points.iter_mut().step_by(3) {
            p.z += 0.004 + 0.004 * rng.random::<f32>();
        }
        let source = PointCloud::new(points).unwrap();
        let error_with = |kernel| {
            let options = IcpOptions {
                kernel,
                max_correspondence_distance: 0.01,
                max_iterations: 100,
                ..IcpOptions::default()
            };
            let found = refine_icp(&source, &target, &index, &truth, &options).unwrap();
            (found.pose.inverse() * truth).translation.vector.norm()
        };
        let (plain, robust) = (
            error_with(None),
            error_with(Some(RobustKernel::Tukey(0.003))),
        );
        assert!(
            robust < 0.5 * plain,
            "Tukey {robust} vs least squares {plain}"
        );
        assert!(error_with(Some(RobustKernel::Huber(0.0005))) < plain);
        assert!(error_with(Some(RobustKernel::Cauchy(0.0005))) < plain);
    }

    #[test]
    fn each_option_out_of_range_is_refused_by_name_before_any_work() {
        let (cloud, _) = patch();
        let index = PointIndex::from_points(cloud.points());
        assert!(IcpOptions::default().validate().is_ok());
        // Each option named with a change of the defaults that puts it out of range.
        type Spoil = fn(&mut IcpOptions);
        let bad: [(&str, Spoil); 7] = [
            ("max_correspondence_distance", |o| {
                o.max_correspondence_distance = 0.0
            }),
            ("kernel", |o| o.kernel = Some(RobustKernel::Huber(0.0))),
            ("kernel", |o| {
                o.kernel = Some(RobustKernel::Cauchy(f64::NAN))
            }),
            ("min_eigen_ratio", |o| o.min_eigen_ratio = 1.0),
            ("min_eigen_ratio", |o| o.min_eigen_ratio = -0.1),
            ("max_normal_angle", |o| o.max_normal_angle = Some(-0.1)),
            ("max_normal_angle", |o| {
                o.max_normal_angle = Some(f32::INFINITY)
            }),
        ];
        for (name, spoil) in bad {
            let mut options = IcpOptions::default();
            spoil(&mut options);
            let refused = |result: Result<(), RegistrationError>| match result {
                Err(RegistrationError::InvalidOption { name: named, .. }) => named == name,
                _ => false,
            };
            assert!(refused(options.validate()), "{options:?}");
            // The cloud has no normals: a check of the options after the normals' would fail
            // with MissingNormals instead.
            let icp = refine_icp(&cloud, &cloud, &index, &Isometry3::identity(), &options);
            assert!(refused(icp.map(|_| ())), "{options:?}");
        }
    }
}
