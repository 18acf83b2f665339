//! Fast Global Registration (Zhou, Park, Koltun, ECCV 2016).

use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::RegistrationError;
use crate::matching::{FeatureMatches, match_features};
use crate::prepare::PreparedCloud;
use crate::twist::{NormalEquations, kabsch};

/// Fewest correspondences FGR optimises over (as in the reference implementation).
const MIN_CORRESPONDENCES: usize = 10;

/// Which feature-space nearest neighbours FGR starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureCorrespondences {
    /// Pairs that are each other's nearest neighbour (the paper's cross-check, as in Open3D).
    Mutual,
    /// Every target point with its nearest source feature. Registering a full model (source)
    /// to a partial view (target), every observed point gets a candidate and none of the
    /// model's unseen points does; on the test object this recovered more poses than `Mutual`,
    /// which keeps only a few percent of the points.
    TargetToSource,
}

/// Options of [`align_fgr`]; the defaults are the paper's and Open3D 0.20's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FgrOptions {
    /// The Geman–McClure scale μ is divided by this every 4 iterations (graduated
    /// non-convexity, paper Sec. 3.3).
    pub division_factor: f64,
    /// Measure distances in metres; otherwise (default) both clouds are centred and scaled so
    /// the farthest point lies at distance 1, and the distances below are in those units.
    pub use_absolute_scale: bool,
    /// Apply graduated non-convexity (decrease μ); otherwise μ stays at 1.
    pub decrease_mu: bool,
    /// μ stops decreasing once at or below this value (a squared distance in the units above).
    pub maximum_correspondence_distance: f64,
    /// Gauss–Newton iterations.
    pub iteration_number: usize,
    /// Tuple test: the three edge lengths of a triple of correspondences must agree within
    /// this ratio (paper Sec. 3.2, τ).
    pub tuple_scale: f64,
    /// Stop the tuple test after this many accepted triples.
    pub maximum_tuple_count: usize,
    /// Run the tuple test (otherwise optimise over all mutual correspondences).
    pub tuple_test: bool,
    /// Which nearest-neighbour pairs in feature space are the candidates.
    pub correspondences: FeatureCorrespondences,
    /// Seed of the tuple sampling.
    pub seed: u64,
}

impl Default for FgrOptions {
    fn default() -> Self {
        Self {
            division_factor: 1.4,
            use_absolute_scale: false,
            decrease_mu: true,
            maximum_correspondence_distance: 0.025,
            iteration_number: 64,
            tuple_scale: 0.95,
            maximum_tuple_count: 1000,
            tuple_test: true,
            correspondences: FeatureCorrespondences::Mutual,
            seed: 0,
        }
    }
}

impl FgrOptions {
    fn validate(&self) -> Result<(), RegistrationError> {
        let invalid = |name, value, reason| {
            Err(RegistrationError::InvalidOption {
                name,
                value,
                reason,
            })
        };
        if !(self.division_factor.is_finite() && self.division_factor > 1.0) {
            return invalid(
                "division_factor",
                self.division_factor,
                "must be greater than 1",
            );
        }
        if !(self.maximum_correspondence_distance.is_finite()
            && self.maximum_correspondence_distance > 0.0)
        {
            return invalid(
                "maximum_correspondence_distance",
                self.maximum_correspondence_distance,
                "must be positive",
            );
        }
        if !(self.tuple_scale > 0.0 && self.tuple_scale < 1.0) {
            return invalid("tuple_scale", self.tuple_scale, "must lie in (0, 1)");
        }
        if self.iteration_number == 0 {
            return invalid("iteration_number", 0.0, "must be at least 1");
        }
        Ok(())
    }
}

/// What [`align_fgr`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct FgrAlignment {
    /// Source → target rigid transform (metres), including the initial pose.
    pub pose: Isometry3<f64>,
    /// Feature correspondences before the tuple test.
    pub candidates: usize,
    /// Correspondences optimised over: FGR's own solution, the tuple-test pairs (triples
    /// counted three times); a consensus start, all candidates.
    pub correspondences: usize,
}

/// Globally aligns `source` to `target` from their FPFH features.
///
/// `initial` is applied to the source first (the returned pose includes it): a random
/// initial pose gives FGR's optimisation a different start, as the pseudo-labeller does.
/// Steps (paper Sec. 3): nearest neighbours in feature space (mutual ones with
/// [`FeatureCorrespondences::Mutual`]), the tuple test, then Gauss–Newton on the twist with
/// Geman–McClure weights (μ / (r² + μ))², μ decreasing.
///
/// Errors: bad options; fewer than 10 correspondences survive; singular normal equations.
pub fn align_fgr(
    source: &PreparedCloud,
    target: &PreparedCloud,
    initial: &Isometry3<f64>,
    options: &FgrOptions,
) -> Result<FgrAlignment, RegistrationError> {
    let matches = match_features(&source.features, &target.features);
    let mut modes = align_modes(source, target, &matches, initial, options, 1)?;
    Ok(modes.remove(0))
}

/// Up to `count` global solutions. The first is FGR's (graduated non-convexity from the
/// identity over the tuple-test pairs). The others start from the best-supported closed-form
/// poses of the accepted triples ([`consensus_starts`]) and run FGR's Gauss–Newton at the final
/// μ over all candidates: when outliers outnumber inliers twenty to one, graduated
/// non-convexity can settle in a wrong mode (the object flipped) that these starts avoid.
/// Feature matching is done by the caller, once. At least one solution on success.
pub(crate) fn align_modes(
    source: &PreparedCloud,
    target: &PreparedCloud,
    matches: &FeatureMatches,
    initial: &Isometry3<f64>,
    options: &FgrOptions,
    count: usize,
) -> Result<Vec<FgrAlignment>, RegistrationError> {
    options.validate()?;
    let candidates = match options.correspondences {
        FeatureCorrespondences::Mutual => matches.mutual(),
        FeatureCorrespondences::TargetToSource => matches.target_to_source(),
    };
    let source_points: Vec<Point3<f64>> = source
        .cloud
        .points()
        .iter()
        .map(|p| initial * p.cast::<f64>())
        .collect();
    let target_points: Vec<Point3<f64>> = target
        .cloud
        .points()
        .iter()
        .map(|p| p.cast::<f64>())
        .collect();
    let points = (source_points.as_slice(), target_points.as_slice());
    let pairs = tested_pairs(&candidates, points, options)?;
    let frame = Normalisation::new(source, target, points, initial, options)?;
    let tuple_pairs = frame.pairs(&pairs, points);
    let (pose, _) = gauss_newton(
        &tuple_pairs,
        Isometry3::identity(),
        1.0,
        options.iteration_number,
        options,
    )?;
    let mut modes = vec![FgrAlignment {
        pose: frame.to_metres(pose),
        candidates: candidates.len(),
        correspondences: pairs.len(),
    }];
    if count > 1 {
        let all = frame.pairs(&candidates, points);
        let mu = final_mu(options);
        for start in consensus_starts(&tuple_pairs, &all, mu, count - 1) {
            if let Ok((pose, _)) =
                gauss_newton(&all, start, mu, options.iteration_number / 4, options)
            {
                modes.push(FgrAlignment {
                    pose: frame.to_metres(pose),
                    candidates: candidates.len(),
                    correspondences: all.len(),
                });
            }
        }
    }
    Ok(modes)
}

/// The pairs FGR optimises over: the `candidates` that pass the tuple test (all of them
/// without it), between the `points` of source (moved by the initial pose) and target; an
/// error when fewer than [`MIN_CORRESPONDENCES`] are left.
fn tested_pairs(
    candidates: &[(u32, u32)],
    (source_points, target_points): (&[Point3<f64>], &[Point3<f64>]),
    options: &FgrOptions,
) -> Result<Vec<(u32, u32)>, RegistrationError> {
    let pairs = if options.tuple_test {
        tuple_test(candidates, source_points, target_points, options)
    } else {
        candidates.to_vec()
    };
    if pairs.len() < MIN_CORRESPONDENCES {
        let stage = if options.tuple_test {
            "tuple test"
        } else {
            "feature matching"
        };
        return Err(RegistrationError::NoCorrespondences {
            stage,
            found: pairs.len(),
            needed: MIN_CORRESPONDENCES,
        });
    }
    Ok(pairs)
}

/// FGR's units (paper Sec. 4): each cloud centred on its centroid, both scaled by the
/// farthest point from it (or metres with `use_absolute_scale`).
struct Normalisation {
    /// The source's centroid, moved by the initial pose.
    source_mean: Vector3<f64>,
    target_mean: Vector3<f64>,
    /// Metres per unit.
    scale: f64,
    initial: Isometry3<f64>,
}

impl Normalisation {
    /// The units of `source` (moved by `initial`) and `target`, whose `points` are given.
    fn new(
        source: &PreparedCloud,
        target: &PreparedCloud,
        (source_points, target_points): (&[Point3<f64>], &[Point3<f64>]),
        initial: &Isometry3<f64>,
        options: &FgrOptions,
    ) -> Result<Self, RegistrationError> {
        let (Some(source_mean), Some(target_mean)) =
            (source.cloud.centroid(), target.cloud.centroid())
        else {
            return Err(RegistrationError::EmptyCloud {
                cloud: "source or target",
            });
        };
        let (source_mean, target_mean) = ((initial * source_mean).coords, target_mean.coords);
        let scale = if options.use_absolute_scale {
            1.0
        } else {
            let farthest = |points: &[Point3<f64>], m: Vector3<f64>| {
                points
                    .iter()
                    .map(|p| (p.coords - m).norm())
                    .fold(0.0, f64::max)
            };
            farthest(source_points, source_mean)
                .max(farthest(target_points, target_mean))
                .max(f64::MIN_POSITIVE)
        };
        Ok(Self {
            source_mean,
            target_mean,
            scale,
            initial: *initial,
        })
    }

    /// The `pairs` (source index, target index) of `points`, in these units.
    fn pairs(
        &self,
        pairs: &[(u32, u32)],
        (source_points, target_points): (&[Point3<f64>], &[Point3<f64>]),
    ) -> Vec<(Vector3<f64>, Vector3<f64>)> {
        let normalise = |p: &Point3<f64>, m: Vector3<f64>| (p.coords - m) / self.scale;
        pairs
            .iter()
            .map(|&(s, t)| {
                (
                    normalise(&source_points[s as usize], self.source_mean),
                    normalise(&target_points[t as usize], self.target_mean),
                )
            })
            .collect()
    }

    /// A pose found in these units as the source → target pose in metres, the initial pose
    /// included.
    fn to_metres(&self, pose: Isometry3<f64>) -> Isometry3<f64> {
        // x_t = R (x_s − m_s) + scale · t̂ + m_t.
        let translation = pose.translation.vector * self.scale + self.target_mean
            - pose.rotation * self.source_mean;
        Isometry3::from_parts(Translation3::from(translation), pose.rotation) * self.initial
    }
}

/// The μ that FGR's schedule ends at.
fn final_mu(options: &FgrOptions) -> f64 {
    let mut mu = 1.0;
    for iteration in 0..options.iteration_number {
        if options.decrease_mu && iteration % 4 == 0 && mu > options.maximum_correspondence_distance
        {
            mu /= options.division_factor;
        }
    }
    mu
}

/// Starting poses from the tuple test's triples, RANSAC-style: each accepted triple's
/// closed-form pose, scored by how many `candidates` it brings within √μ, best first, skipping
/// poses within 15° and 2√μ of one already taken. At most `count`.
fn consensus_starts(
    tuple_pairs: &[(Vector3<f64>, Vector3<f64>)],
    candidates: &[(Vector3<f64>, Vector3<f64>)],
    mu: f64,
    count: usize,
) -> Vec<Isometry3<f64>> {
    let mut scored: Vec<(usize, usize, Isometry3<f64>)> = tuple_pairs
        .par_chunks_exact(3)
        .enumerate()
        .filter_map(|(index, triple)| {
            let points: Vec<_> = triple
                .iter()
                .map(|(s, t)| (Point3::from(*s), Point3::from(*t), 1.0))
                .collect();
            let pose = kabsch(&points)?;
            let support = candidates
                .iter()
                .filter(|(s, t)| (pose * Point3::from(*s)).coords.metric_distance(t).powi(2) < mu)
                .count();
            Some((support, index, pose))
        })
        .collect();
    scored.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut starts: Vec<Isometry3<f64>> = Vec::new();
    for (_, _, pose) in scored {
        if starts.len() == count {
            break;
        }
        let distinct = starts.iter().all(|taken| {
            let difference = taken.inverse() * pose;
            difference.rotation.angle() > 15f64.to_radians()
                || difference.translation.vector.norm() > 2.0 * mu.sqrt()
        });
        if distinct {
            starts.push(pose);
        }
    }
    starts
}

/// FGR's optimisation (paper Sec. 3.3, Eq. 6–8) on normalised pairs from `start`, with
/// Geman–McClure scale μ starting at `mu` and divided by the division factor every 4
/// iterations while above the floor: the pose and the final μ.
fn gauss_newton(
    pairs: &[(Vector3<f64>, Vector3<f64>)],
    start: Isometry3<f64>,
    mu: f64,
    iterations: usize,
    options: &FgrOptions,
) -> Result<(Isometry3<f64>, f64), RegistrationError> {
    let mut mu = mu;
    let mut pose = start;
    for iteration in 0..iterations {
        if options.decrease_mu && iteration % 4 == 0 && mu > options.maximum_correspondence_distance
        {
            mu /= options.division_factor;
        }
        let mut equations = NormalEquations::new();
        for (s, t) in pairs {
            let moved = pose * Point3::from(*s);
            let residual_squared = (moved.coords - t).norm_squared();
            let weight = (mu / (residual_squared + mu)).powi(2);
            equations.add_point_to_point(&moved.coords, t, weight);
        }
        let step = equations
            .solve()
            .ok_or(RegistrationError::SingularSystem { stage: "FGR" })?;
        pose = step * pose;
    }
    Ok((pose, mu))
}

/// Tuple-test trials drawn from one random stream.
const TUPLE_BATCH: usize = 4096;

/// The tuple test (paper Sec. 3.2): random triples of correspondences whose three pairwise
/// distances agree between the clouds within `tuple_scale`; accepted triples are concatenated.
///
/// `100 × candidates` trials in batches, batch `b` drawing from ChaCha8 stream `b` of `seed`;
/// batches run in parallel, and the first `maximum_tuple_count` accepted triples in batch order
/// are kept, so the result does not depend on the thread count.
fn tuple_test(
    pairs: &[(u32, u32)],
    source: &[Point3<f64>],
    target: &[Point3<f64>],
    options: &FgrOptions,
) -> Vec<(u32, u32)> {
    let mut accepted = Vec::new();
    if pairs.is_empty() || options.maximum_tuple_count == 0 {
        return accepted;
    }
    let trials = pairs.len() * 100;
    let batches = trials.div_ceil(TUPLE_BATCH);
    let scale = options.tuple_scale as f32;
    let compatible = |a: f32, b: f32| a * scale < b && b < a / scale;
    // Both ends of each candidate side by side: one memory access per draw.
    let ends: Vec<[Point3<f32>; 2]> = pairs
        .iter()
        .map(|&(s, t)| [source[s as usize].cast(), target[t as usize].cast()])
        .collect();
    let run_batch = |batch: usize| {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
        rng.set_stream(batch as u64);
        let count = TUPLE_BATCH.min(trials - batch * TUPLE_BATCH);
        let mut found = Vec::new();
        for _ in 0..count {
            let triple: [usize; 3] = std::array::from_fn(|_| rng.random_range(0..pairs.len()));
            let consistent = (0..3).all(|k| {
                let (a, b) = (&ends[triple[k]], &ends[triple[(k + 1) % 3]]);
                compatible((a[0] - b[0]).norm(), (a[1] - b[1]).norm())
            });
            if consistent {
                found.push(triple.map(|i| pairs[i]));
                if found.len() >= options.maximum_tuple_count {
                    break;
                }
            }
        }
        found
    };
    // A few batches per thread at a time; later groups only run if more triples are needed.
    let group = 2 * rayon::current_num_threads().max(1);
    for first in (0..batches).step_by(group) {
        let found: Vec<Vec<[(u32, u32); 3]>> = (first..batches.min(first + group))
            .into_par_iter()
            .map(run_batch)
            .collect();
        for triple in found.into_iter().flatten() {
            accepted.extend_from_slice(&triple);
            if accepted.len() / 3 >= options.maximum_tuple_count {
                return accepted;
            }
        }
    }
    accepted
}
