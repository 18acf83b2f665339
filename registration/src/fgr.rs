//! Fast Global Registration (Zhou, Park, Koltun, ECCV 2016).

use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::RegistrationError;
use crate::matching::{FeatureMatches, match_features};
use crate::prepare::PreparedCloud;
use crate::twist::NormalEquations;

/// Fewest correspondences FGR optimises over (as in the reference implementation).
const MIN_CORRESPONDENCES: usize = 10;

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
    /// Keep only mutual nearest neighbours in feature space (the paper's cross-check);
    /// otherwise every pair where either side is the other's nearest neighbour.
    pub mutual_filter: bool,
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
            mutual_filter: true,
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
    /// Correspondences optimised over (after the tuple test, triples counted three times).
    pub correspondences: usize,
}

/// Globally aligns `source` to `target` from their FPFH features.
///
/// `initial` is applied to the source first (the returned pose includes it): a random
/// initial pose gives FGR's optimisation a different start, as the pseudo-labeller does.
/// Steps (paper Sec. 3): nearest neighbours in feature space (mutual ones with
/// `mutual_filter`), the tuple test, then Gauss–Newton on the twist with Geman–McClure
/// weights (μ / (r² + μ))², μ decreasing.
///
/// Errors: bad options; fewer than 10 correspondences survive; singular normal equations.
pub fn align_fgr(
    source: &PreparedCloud,
    target: &PreparedCloud,
    initial: &Isometry3<f64>,
    options: &FgrOptions,
) -> Result<FgrAlignment, RegistrationError> {
    let matches = match_features(&source.features, &target.features);
    align_matched(source, target, &matches, initial, options)
}

/// [`align_fgr`] with the feature matching already done (it does not depend on the seed or
/// the initial pose, so several hypotheses share it).
pub(crate) fn align_matched(
    source: &PreparedCloud,
    target: &PreparedCloud,
    matches: &FeatureMatches,
    initial: &Isometry3<f64>,
    options: &FgrOptions,
) -> Result<FgrAlignment, RegistrationError> {
    options.validate()?;
    let candidates = if options.mutual_filter {
        matches.mutual()
    } else {
        matches.either()
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
    let pairs = if options.tuple_test {
        tuple_test(&candidates, &source_points, &target_points, options)
    } else {
        candidates.clone()
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
    // Normalise: centre each cloud, scale both by the farthest point (paper Sec. 4).
    let mean = |points: &[Point3<f64>]| {
        points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64
    };
    let (source_mean, target_mean) = (mean(&source_points), mean(&target_points));
    let scale = if options.use_absolute_scale {
        1.0
    } else {
        let farthest = |points: &[Point3<f64>], m: Vector3<f64>| {
            points
                .iter()
                .map(|p| (p.coords - m).norm())
                .fold(0.0, f64::max)
        };
        farthest(&source_points, source_mean)
            .max(farthest(&target_points, target_mean))
            .max(f64::MIN_POSITIVE)
    };
    let normalise = |p: &Point3<f64>, m: Vector3<f64>| (p.coords - m) / scale;
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = pairs
        .iter()
        .map(|&(s, t)| {
            (
                normalise(&source_points[s as usize], source_mean),
                normalise(&target_points[t as usize], target_mean),
            )
        })
        .collect();

    let mut mu = 1.0;
    let mut pose = Isometry3::identity();
    for iteration in 0..options.iteration_number {
        if options.decrease_mu && iteration % 4 == 0 && mu > options.maximum_correspondence_distance
        {
            mu /= options.division_factor;
        }
        let mut equations = NormalEquations::new();
        for (s, t) in &pairs {
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
    // Back to metres: x_t = R (x_s − m_s) + scale · t̂ + m_t.
    let translation = pose.translation.vector * scale + target_mean - pose.rotation * source_mean;
    let pose = Isometry3::from_parts(Translation3::from(translation), pose.rotation) * initial;
    Ok(FgrAlignment {
        pose,
        candidates: candidates.len(),
        correspondences: pairs.len(),
    })
}

/// The tuple test (paper Sec. 3.2): random triples of correspondences whose three pairwise
/// distances agree between the clouds within `tuple_scale`; accepted triples are concatenated.
fn tuple_test(
    pairs: &[(u32, u32)],
    source: &[Point3<f64>],
    target: &[Point3<f64>],
    options: &FgrOptions,
) -> Vec<(u32, u32)> {
    let mut accepted = Vec::new();
    if pairs.is_empty() {
        return accepted;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let scale = options.tuple_scale;
    let compatible = |a: f64, b: f64| a * scale < b && b < a / scale;
    for _ in 0..pairs.len() * 100 {
        let triple: [(u32, u32); 3] =
            std::array::from_fn(|_| pairs[rng.random_range(0..pairs.len())]);
        let ok = (0..3).all(|k| {
            let (a, b) = (triple[k], triple[(k + 1) % 3]);
            let source_length = (source[a.0 as usize] - source[b.0 as usize]).norm();
            let target_length = (target[a.1 as usize] - target[b.1 as usize]).norm();
            compatible(source_length, target_length)
        });
        if ok {
            accepted.extend_from_slice(&triple);
            if accepted.len() / 3 >= options.maximum_tuple_count {
                break;
            }
        }
    }
    accepted
}
