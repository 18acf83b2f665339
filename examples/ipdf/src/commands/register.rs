//! `ipdf register`: align a source cloud to a target cloud (FPFH + FGR + ICP).
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use bop_dataset::{FileError, write_atomically};
use nalgebra::{Isometry3, Matrix4, Point3};
use registration::{
    Alignment, IcpMethod, NormalOrientation, PointCloud, PrepareOptions, PreparedCloud,
    RegisterOptions, prepare_cloud, register,
};
use serde_json::json;

/// ICP error metric, as named on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum IcpChoice {
    /// Point-to-plane (Gauss–Newton on the twist; uses target normals).
    PointToPlane,
    /// Point-to-point (closed-form Kabsch each iteration).
    PointToPoint,
}

/// How target normals are oriented when the target file has none.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum TargetNormals {
    /// Towards a camera at the origin (a depth view in its camera frame).
    Viewpoint,
    /// Consistent propagation over the surface (a full scan or model).
    Consistent,
}

/// Arguments of `ipdf register`.
#[derive(Debug, clap::Args)]
pub struct RegisterArgs {
    /// Source cloud (PLY or OBJ: vertices, optional `nx ny nz`); a mesh reads as 20,000 points
    /// sampled on its surface.
    #[arg(long)]
    pub source: PathBuf,
    /// Target cloud (PLY), e.g. an unprojected depth view in its camera frame.
    #[arg(long)]
    pub target: PathBuf,
    /// Multiply both clouds' coordinates by this (0.001 for millimetre files).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Voxel size in metres; normals use 2 voxels, FPFH 5, ICP 1.5.
    #[arg(long, default_value_t = 0.005)]
    pub voxel: f32,
    /// ICP error metric.
    #[arg(long, value_enum, default_value = "point-to-plane")]
    pub icp: IcpChoice,
    /// Global hypotheses: FGR's solution plus consensus starts; the largest overlap is
    /// refined by ICP.
    #[arg(long, default_value_t = 2)]
    pub hypotheses: usize,
    /// Orientation of target normals estimated here (file normals are kept). Source normals
    /// not in the file are always propagated consistently.
    #[arg(long, value_enum, default_value = "viewpoint")]
    pub target_normals: TargetNormals,
    /// Initial pose P0 applied to the source before FGR: a JSON file with `"transformation"`
    /// (16 floats, row-major), e.g. an earlier result.
    #[arg(long)]
    pub initial: Option<PathBuf>,
    /// Write the result JSON here (atomically).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `ipdf register`; returns `{"transformation": [16, row-major, source→target],
/// "fitness", "inlier_rmse", "fgr_ms", "icp_ms", "features_ms", …}`.
pub fn run(args: &RegisterArgs, seed: u64) -> Result<serde_json::Value> {
    if !(args.scale.is_finite() && args.scale > 0.0) {
        anyhow::bail!("--scale must be a positive number, got {}", args.scale);
    }
    let initial = match &args.initial {
        Some(path) => read_transformation(path)?,
        None => Isometry3::identity(),
    };
    let source = ipdf::cloud_file::read_cloud(&args.source, args.scale)?;
    let target = ipdf::cloud_file::read_cloud(&args.target, args.scale)?;
    if !(args.voxel.is_finite() && args.voxel > 0.0) {
        bail!(
            "--voxel must be a positive number of metres, got {}",
            args.voxel
        );
    }
    check_units(&source, args.voxel, args.scale, &args.source)?;
    check_units(&target, args.voxel, args.scale, &args.target)?;
    let options = PrepareOptions::for_voxel(args.voxel);
    let target_orientation = match args.target_normals {
        TargetNormals::Viewpoint => NormalOrientation::TowardsViewpoint(Point3::origin()),
        TargetNormals::Consistent => NormalOrientation::Consistent { neighbours: 10 },
    };
    let started = Instant::now();
    let source_options = options.oriented(NormalOrientation::Consistent { neighbours: 10 });
    let source = prepare(&source, &source_options, &args.source)?;
    let target = prepare(&target, &options.oriented(target_orientation), &args.target)?;
    let features_ms = started.elapsed().as_secs_f64() * 1e3;

    let mut register_options = RegisterOptions::for_voxel(args.voxel);
    register_options.fgr.seed = seed;
    register_options.hypotheses = args.hypotheses;
    register_options.icp.method = match args.icp {
        IcpChoice::PointToPlane => IcpMethod::PointToPlane,
        IcpChoice::PointToPoint => IcpMethod::PointToPoint,
    };
    let found = register(&source, &target, &initial, &register_options).with_context(|| {
        format!(
            "registering {} to {}",
            args.source.display(),
            args.target.display()
        )
    })?;
    check_overlap(
        &found.alignment,
        register_options.icp.max_correspondence_distance,
    )
    .with_context(|| {
        format!(
            "registering {} to {}",
            args.source.display(),
            args.target.display()
        )
    })?;
    let matrix = found.alignment.pose.to_homogeneous();
    let summary = json!({
        "transformation": (0..16).map(|k| matrix[(k / 4, k % 4)]).collect::<Vec<f64>>(),
        "fitness": found.alignment.fitness,
        "inlier_rmse": found.alignment.inlier_rmse,
        "icp_iterations": found.alignment.iterations,
        "hypothesis": found.hypothesis,
        "source_points": source.cloud.len(),
        "target_points": target.cloud.len(),
        "features_ms": features_ms,
        "fgr_ms": found.fgr_time.as_secs_f64() * 1e3,
        "icp_ms": found.icp_time.as_secs_f64() * 1e3,
    });
    if let Some(out) = &args.out {
        write_atomically(out, |file| {
            serde_json::to_writer_pretty(&mut *file, &summary)?;
            Ok(())
        })?;
    }
    Ok(summary)
}

/// Refuses an alignment with no source point within ICP's correspondence distance
/// (`max_correspondence_distance`, metres) of the target at the pose reached (fitness 0): the
/// data do not support that pose, however it was found.
fn check_overlap(alignment: &Alignment, max_correspondence_distance: f32) -> Result<()> {
    if alignment.fitness.is_nan() || alignment.fitness <= 0.0 {
        anyhow::bail!(
            "ICP ended with 0 correspondences (fitness 0) within {max_correspondence_distance} m; \
             the clouds do not overlap at the pose found (check --scale, --voxel and --initial)"
        );
    }
    Ok(())
}

/// Voxels across a cloud beyond which (or below which) the voxel and the cloud's units
/// disagree: a 10 m room at 5 mm voxels is 2,000 across, an object's view at least a few.
const VOXELS_ACROSS: (f64, f64) = (3.0, 20_000.0);

/// Refuses a cloud whose extent is not a sensible number of voxels, before normal estimation
/// fails on it with a count of neighbours: the sign of a file in millimetres read as metres
/// (or the reverse), naming `--scale` and `--voxel`.
fn check_units(cloud: &PointCloud, voxel: f32, scale: f64, path: &Path) -> Result<()> {
    let Some((low, high)) = depth_render::bounding_box(cloud.points()) else {
        // Registration names an empty cloud itself.
        return Ok(());
    };
    let extent = f64::from((high - low).norm());
    let across = extent / f64::from(voxel);
    if across > VOXELS_ACROSS.1 {
        bail!(
            "{}: the cloud is {extent:.4} m across at --scale {scale}, {across:.0} voxels of \
             --voxel {voxel} m: is it in millimetres? (--scale 0.001 reads it so)",
            path.display()
        );
    }
    if across < VOXELS_ACROSS.0 {
        bail!(
            "{}: the cloud is {extent:.6} m across at --scale {scale}, under {} voxels of \
             --voxel {voxel} m: choose a smaller --voxel, or a larger --scale if it is not in \
             {}",
            path.display(),
            VOXELS_ACROSS.0,
            if scale == 1.0 {
                "metres"
            } else {
                "the units --scale assumes"
            }
        );
    }
    Ok(())
}

fn prepare(cloud: &PointCloud, options: &PrepareOptions, path: &Path) -> Result<PreparedCloud> {
    prepare_cloud(cloud, options).with_context(|| format!("{}: cannot register it", path.display()))
}

/// Reads `"transformation"` (16 floats, row-major rigid transform) from a JSON file.
fn read_transformation(path: &Path) -> Result<Isometry3<f64>> {
    let bad = |reason: &str| FileError::new(path, "transformation", reason);
    let value = bop_dataset::read_json(path)?;
    let numbers: Vec<f64> = value
        .get("transformation")
        .and_then(|v| v.as_array())
        .ok_or_else(|| bad("missing or not an array"))?
        .iter()
        .map(|v| v.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| bad("holds a value that is not a finite number"))?;
    if numbers.len() != 16 {
        return Err(bad(&format!("has {} numbers, expected 16", numbers.len())).into());
    }
    let matrix = Matrix4::from_row_slice(&numbers);
    let block: [f64; 9] = std::array::from_fn(|k| matrix[(k / 3, k % 3)]);
    let rotation =
        so3_grid::rotation_from_matrix(&block).map_err(|e| bad(&format!("rotation block: {e}")))?;
    if matrix
        .row(3)
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(a, b)| (a - b).abs() > 1e-9)
    {
        return Err(bad("last row must be 0 0 0 1").into());
    }
    let translation = nalgebra::Translation3::new(matrix[(0, 3)], matrix[(1, 3)], matrix[(2, 3)]);
    Ok(Isometry3::from_parts(translation, rotation))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alignment(fitness: f64) -> Alignment {
        Alignment {
            pose: Isometry3::translation(1.6, 0.0, 0.0),
            fitness,
            inlier_rmse: 0.0,
            iterations: 1,
        }
    }

    #[test]
    fn an_alignment_without_inliers_is_an_error() {
        for fitness in [0.0, f64::NAN] {
            let error = check_overlap(&alignment(fitness), 0.0075).unwrap_err();
            let text = format!("{error:#}");
            assert!(text.contains("0 correspondences"), "{text}");
            assert_eq!(text.lines().count(), 1, "{text}");
        }
        assert!(check_overlap(&alignment(0.3), 0.0075).is_ok());
    }
}
