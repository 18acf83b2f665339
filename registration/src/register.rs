//! The whole registration of two prepared clouds: FGR hypotheses, each refined by ICP, the
//! best kept.

use std::time::{Duration, Instant};

use nalgebra::Isometry3;

use crate::RegistrationError;
use crate::fgr::{FgrOptions, align_matched};
use crate::icp::{Alignment, IcpOptions, refine_icp};
use crate::matching::match_features;
use crate::prepare::PreparedCloud;

/// Options of [`register`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterOptions {
    /// Global alignment; hypothesis `h` uses tuple-test seed `fgr.seed + h`.
    pub fgr: FgrOptions,
    /// Refinement of each hypothesis.
    pub icp: IcpOptions,
    /// FGR hypotheses to refine; the one with the highest ICP fitness (then the lowest RMSE)
    /// wins. One is the plain FGR + ICP pipeline.
    pub hypotheses: usize,
}

impl RegisterOptions {
    /// Defaults for clouds prepared at `voxel_size` metres: FGR as in the paper except the
    /// mutual filter (see [`FgrOptions::mutual_filter`]), μ floor 0.5 voxel (Open3D's
    /// tutorial), ICP point-to-plane within 1.5 voxels, 3 hypotheses.
    pub fn for_voxel(voxel_size: f32) -> Self {
        Self {
            fgr: FgrOptions {
                maximum_correspondence_distance: 0.5 * f64::from(voxel_size),
                mutual_filter: false,
                ..FgrOptions::default()
            },
            icp: IcpOptions {
                max_correspondence_distance: 1.5 * voxel_size,
                ..IcpOptions::default()
            },
            hypotheses: 3,
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
    /// The FGR pose it was refined from.
    pub global_pose: Isometry3<f64>,
    /// Which hypothesis won.
    pub hypothesis: usize,
    /// Time spent in feature matching and FGR, all hypotheses.
    pub fgr_time: Duration,
    /// Time spent in ICP, all hypotheses.
    pub icp_time: Duration,
}

/// Registers `source` to `target` (both from [`crate::prepare_cloud`]): features matched
/// once, then `hypotheses` FGR runs (different tuple samples) from `initial`, each refined by
/// ICP against `target`; the best is returned. Deterministic for given options.
///
/// Errors: bad options, or no hypothesis could be aligned (the last hypothesis' error, e.g.
/// [`RegistrationError::NoCorrespondences`]).
pub fn register(
    source: &PreparedCloud,
    target: &PreparedCloud,
    initial: &Isometry3<f64>,
    options: &RegisterOptions,
) -> Result<Registration, RegistrationError> {
    if options.hypotheses == 0 {
        return Err(RegistrationError::InvalidOption {
            name: "hypotheses",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let started = Instant::now();
    let matches = match_features(&source.features, &target.features);
    let mut fgr_time = started.elapsed();
    let mut icp_time = Duration::ZERO;
    let mut best: Option<Registration> = None;
    let mut last_error = None;
    for hypothesis in 0..options.hypotheses {
        let fgr_options = FgrOptions {
            seed: options.fgr.seed.wrapping_add(hypothesis as u64),
            ..options.fgr
        };
        let started = Instant::now();
        let global = align_matched(source, target, &matches, initial, &fgr_options);
        fgr_time += started.elapsed();
        let global = match global {
            Ok(global) => global,
            Err(error) => {
                last_error = Some(error);
                continue;
            }
        };
        let started = Instant::now();
        let refined = refine_icp(
            &source.cloud,
            &target.cloud,
            &target.index,
            &global.pose,
            &options.icp,
        );
        icp_time += started.elapsed();
        let alignment = match refined {
            Ok(alignment) => alignment,
            Err(error) => {
                last_error = Some(error);
                continue;
            }
        };
        let better = best.as_ref().is_none_or(|b| {
            let a = &b.alignment;
            alignment.fitness > a.fitness
                || (alignment.fitness == a.fitness && alignment.inlier_rmse < a.inlier_rmse)
        });
        if better {
            best = Some(Registration {
                alignment,
                global_pose: global.pose,
                hypothesis,
                fgr_time,
                icp_time,
            });
        }
    }
    let mut best = best.ok_or_else(|| {
        last_error.unwrap_or(RegistrationError::NoCorrespondences {
            stage: "FGR",
            found: 0,
            needed: 10,
        })
    })?;
    best.fgr_time = fgr_time;
    best.icp_time = icp_time;
    Ok(best)
}
