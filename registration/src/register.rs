//! The whole registration of two prepared clouds: global hypotheses (FGR, then consensus
//! starts), the best by overlap refined coarse-to-fine by ICP.

use std::time::{Duration, Instant};

use nalgebra::Isometry3;

use crate::RegistrationError;
use crate::error::at_least_one;
use crate::fgr::{FeatureCorrespondences, FgrOptions, align_modes};
use crate::icp::{Alignment, IcpOptions, overlap, refine_icp};
use crate::matching::match_features;
use crate::prepare::PreparedCloud;

/// Iteration cap of the coarse ICP stage.
const COARSE_ITERATIONS: usize = 10;

/// Options of [`register`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterOptions {
    /// Global alignment.
    pub fgr: FgrOptions,
    /// Refinement (the fine stage).
    pub icp: IcpOptions,
    /// Global hypotheses: FGR's own solution, then up to `hypotheses − 1` consensus starts
    /// refined by FGR's Gauss–Newton (see [`crate::align_fgr`] for the first alone). The one
    /// with the largest overlap (fitness at `coarse_factor` × the ICP distance) is refined.
    pub hypotheses: usize,
    /// ICP first runs (at most 10 iterations) with its correspondence distance multiplied by
    /// this (1: no coarse stage), so that a global pose a few degrees off still converges.
    pub coarse_factor: f32,
}

impl RegisterOptions {
    /// Defaults for clouds prepared at `voxel_size` metres: FGR as in the paper except the
    /// candidates ([`FeatureCorrespondences::TargetToSource`]), μ floor 0.5 voxel (Open3D's
    /// tutorial), 2 hypotheses, ICP point-to-plane within 6 then 1.5 voxels.
    pub fn for_voxel(voxel_size: f32) -> Self {
        Self {
            fgr: FgrOptions {
                maximum_correspondence_distance: 0.5 * f64::from(voxel_size),
                correspondences: FeatureCorrespondences::TargetToSource,
                ..FgrOptions::default()
            },
            icp: IcpOptions {
                max_correspondence_distance: 1.5 * voxel_size,
                ..IcpOptions::default()
            },
            hypotheses: 2,
            coarse_factor: 4.0,
        }
    }
}

impl Default for RegisterOptions {
    /// [`RegisterOptions::for_voxel`] at 5 mm.
    fn default() -> Self {
        Self::for_voxel(0.005)
    }
}

/// The result of [`register`].
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// The refined alignment (source → target).
    pub alignment: Alignment,
    /// The global pose it was refined from.
    pub global_pose: Isometry3<f64>,
    /// Which hypothesis that was (0: FGR's own solution).
    pub hypothesis: usize,
    /// Time spent in feature matching and the global stage.
    pub fgr_time: Duration,
    /// Time spent choosing the hypothesis and in ICP.
    pub icp_time: Duration,
}

/// Registers `source` to `target` (both from [`crate::prepare_cloud`]) from `initial`:
/// features matched once, global hypotheses, the one with the largest overlap refined by
/// ICP (coarse, then fine). Deterministic for given options.
///
/// Errors: bad options; no global hypothesis (e.g. [`RegistrationError::NoCorrespondences`]);
/// ICP finding no correspondence.
pub fn register(
    source: &PreparedCloud,
    target: &PreparedCloud,
    initial: &Isometry3<f64>,
    options: &RegisterOptions,
) -> Result<Registration, RegistrationError> {
    at_least_one("hypotheses", options.hypotheses)?;
    if !(options.coarse_factor.is_finite() && options.coarse_factor >= 1.0) {
        return Err(RegistrationError::InvalidOption {
            name: "coarse_factor",
            value: f64::from(options.coarse_factor),
            reason: "must be at least 1",
        });
    }
    let started = Instant::now();
    let matches = match_features(&source.features, &target.features);
    let modes = align_modes(
        source,
        target,
        &matches,
        initial,
        &options.fgr,
        options.hypotheses,
    )?;
    let fgr_time = started.elapsed();

    let started = Instant::now();
    // The coarse stage only has to reach the fine stage's basin.
    let coarse = IcpOptions {
        max_correspondence_distance: options.coarse_factor
            * options.icp.max_correspondence_distance,
        max_iterations: options.icp.max_iterations.min(COARSE_ITERATIONS),
        ..options.icp
    };
    let overlaps: Vec<f64> = modes
        .iter()
        .map(|mode| {
            overlap(
                source.cloud.points(),
                &target.index,
                &mode.pose,
                coarse.max_correspondence_distance,
            )
        })
        .collect();
    // The first of the largest overlaps: FGR's own solution wins ties.
    let hypothesis = (0..modes.len()).fold(0, |best, i| {
        if overlaps[i] > overlaps[best] {
            i
        } else {
            best
        }
    });
    let global_pose = modes[hypothesis].pose;
    let mut pose = global_pose;
    if options.coarse_factor > 1.0 {
        pose = refine_icp(&source.cloud, &target.cloud, &target.index, &pose, &coarse)?.pose;
    }
    let alignment = refine_icp(
        &source.cloud,
        &target.cloud,
        &target.index,
        &pose,
        &options.icp,
    )?;
    Ok(Registration {
        alignment,
        global_pose,
        hypothesis,
        fgr_time,
        icp_time: started.elapsed(),
    })
}
