//! Registration trials: writes a non-symmetric model cloud and rendered, noisy partial views
//! with their true poses (the input of `benches/python/open3d_registration.py`), registers
//! each view with this workspace's FPFH + FGR + ICP, and reports time per stage and success.
//!
//! ```text
//! cargo run --release -p ipdf --example registration_trials -- --out runs/bench/registration
//! ```
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use bop_dataset::write_atomically;
use clap::Parser;
use ipdf::cloud_file::write_cloud;
use ipdf::median::median;
use nalgebra::{Isometry3, Point3};
use registration::{
    NormalOrientation, PointCloud, PrepareOptions, PreparedCloud, RegisterOptions, prepare_cloud,
    register,
};
use serde_json::json;
use synth_data::trials::{RegistrationTrial, egg_mesh, model_cloud, registration_trials};

#[derive(Debug, Parser)]
struct Args {
    /// Folder for model.ply, view_*.ply, trials.json and rust_registration.json.
    #[arg(long, default_value = "runs/bench/registration")]
    out: PathBuf,
    /// Number of views.
    #[arg(long, default_value_t = 50)]
    trials: usize,
    /// Points sampled on the model surface before downsampling.
    #[arg(long, default_value_t = 40_000)]
    model_points: usize,
    /// Voxel size (metres).
    #[arg(long, default_value_t = 0.005)]
    voxel: f32,
    /// Global hypotheses per registration.
    #[arg(long, default_value_t = 2)]
    hypotheses: usize,
    /// Run the registrations this many times; each stage keeps its fastest time.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    /// Seed of the data and of the registration.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// One registration's accuracy and time per stage.
#[derive(Debug, Clone)]
struct TrialResult {
    points: usize,
    features_ms: f64,
    fgr_ms: f64,
    icp_ms: f64,
    rotation_deg: f64,
    translation_m: f64,
    hypothesis: Option<usize>,
    error: Option<String>,
}

impl TrialResult {
    fn success(&self) -> bool {
        self.rotation_deg <= 2.0 && self.translation_m <= 0.005
    }

    /// This result with each stage's time the smaller of the two runs'.
    fn fastest(self, other: Self) -> Self {
        Self {
            features_ms: self.features_ms.min(other.features_ms),
            fgr_ms: self.fgr_ms.min(other.fgr_ms),
            icp_ms: self.icp_ms.min(other.icp_ms),
            ..self
        }
    }
}

fn run_trial(
    source: &PreparedCloud,
    trial: &RegistrationTrial,
    view_options: &PrepareOptions,
    options: &RegisterOptions,
) -> Result<TrialResult> {
    let started = Instant::now();
    let target = prepare_cloud(&trial.view, view_options)?;
    let features_ms = started.elapsed().as_secs_f64() * 1e3;
    let found = register(source, &target, &Isometry3::identity(), options);
    let mut result = TrialResult {
        points: target.cloud.len(),
        features_ms,
        fgr_ms: 0.0,
        icp_ms: 0.0,
        rotation_deg: f64::INFINITY,
        translation_m: f64::INFINITY,
        hypothesis: None,
        error: None,
    };
    match found {
        Ok(found) => {
            let pose = found.alignment.pose;
            result.rotation_deg = (pose.inverse() * trial.truth).rotation.angle().to_degrees();
            result.translation_m =
                (pose.translation.vector - trial.truth.translation.vector).norm();
            result.fgr_ms = found.fgr_time.as_secs_f64() * 1e3;
            result.icp_ms = found.icp_time.as_secs_f64() * 1e3;
            result.hypothesis = Some(found.hypothesis);
        }
        Err(error) => result.error = Some(error.to_string()),
    }
    Ok(result)
}

fn main() -> Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.out)?;
    let mesh = egg_mesh()?;
    let model = model_cloud(&mesh, args.model_points, args.seed)?;
    write_cloud(&args.out.join("model.ply"), &model)?;
    let trials = registration_trials(&mesh, args.trials, args.seed)?;
    write_trials(&args, &trials)?;
    let (model_ms, results, model_points_down) = time_trials(&args, &model, &trials)?;
    report(&args, &results, model_ms, model.len(), model_points_down)
}

/// The views as PLY files and `trials.json`, the manifest the Open3D script reads.
fn write_trials(args: &Args, trials: &[RegistrationTrial]) -> Result<()> {
    let mut listed = Vec::new();
    for (i, trial) in trials.iter().enumerate() {
        let name = format!("view_{i:03}.ply");
        write_cloud(&args.out.join(&name), &trial.view)?;
        let m = trial.truth.to_homogeneous();
        let flat: Vec<f64> = (0..16).map(|k| m[(k / 4, k % 4)]).collect();
        listed.push(json!({"target": name, "target_from_source": flat}));
    }
    let manifest = json!({
        "voxel_size": args.voxel,
        "success": {"rotation_deg": 2.0, "translation_m": 0.005},
        "trials": listed,
    });
    write_atomically(&args.out.join("trials.json"), |f| {
        Ok(serde_json::to_writer_pretty(f, &manifest)?)
    })?;
    Ok(())
}

/// Every trial registered `args.repeat` times; each stage's time is its minimum over the
/// repeats (as the Open3D script's `--repeat`). Returns the model's preparation time (ms), the
/// trials' results and the model's downsampled point count.
fn time_trials(
    args: &Args,
    model: &PointCloud,
    trials: &[RegistrationTrial],
) -> Result<(f64, Vec<TrialResult>, usize)> {
    let options = PrepareOptions::for_voxel(args.voxel);
    let model_options = options.oriented(NormalOrientation::Consistent { neighbours: 10 });
    let view_options = options.oriented(NormalOrientation::TowardsViewpoint(Point3::origin()));
    let mut register_options = RegisterOptions::for_voxel(args.voxel);
    register_options.hypotheses = args.hypotheses;
    let mut model_ms = f64::INFINITY;
    let mut results: Vec<Option<TrialResult>> = vec![None; trials.len()];
    let mut model_points_down = 0;
    for _ in 0..args.repeat.max(1) {
        let started = Instant::now();
        let prepared = prepare_cloud(model, &model_options)?;
        model_ms = model_ms.min(started.elapsed().as_secs_f64() * 1e3);
        for (i, trial) in trials.iter().enumerate() {
            register_options.fgr.seed = args.seed.wrapping_add(1000 * i as u64);
            let result = run_trial(&prepared, trial, &view_options, &register_options)?;
            results[i] = Some(match results[i].take() {
                Some(best) => best.fastest(result),
                None => result,
            });
        }
        model_points_down = prepared.cloud.len();
    }
    Ok((
        model_ms,
        results.into_iter().flatten().collect(),
        model_points_down,
    ))
}

/// Prints the success rate and the stages' median times, and writes `rust_registration.json`.
fn report(
    args: &Args,
    results: &[TrialResult],
    model_ms: f64,
    model_points: usize,
    model_points_down: usize,
) -> Result<()> {
    let successes = results.iter().filter(|r| r.success()).count();
    let stage =
        |pick: fn(&TrialResult) -> f64| median(&mut results.iter().map(pick).collect::<Vec<_>>());
    let medians = json!({
        "model_features": model_ms,
        "target_features": stage(|r| r.features_ms),
        "fgr": stage(|r| r.fgr_ms),
        "icp": stage(|r| r.icp_ms),
        "per_trial": stage(|r| r.features_ms + r.fgr_ms + r.icp_ms),
    });
    let per_trial: Vec<_> = results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            json!({
                "target": format!("view_{i:03}.ply"),
                "target_points_down": r.points,
                "rotation_error_deg": r.rotation_deg.min(1e9),
                "translation_error_m": r.translation_m.min(1e9),
                "target_features_ms": r.features_ms, "fgr_ms": r.fgr_ms, "icp_ms": r.icp_ms,
                "hypothesis": r.hypothesis,
                "success": r.success(),
                "error": r.error,
            })
        })
        .collect();
    let rate = successes as f64 / results.len().max(1) as f64;
    println!(
        "ipdf-rs FPFH + FGR ({} hypotheses) + point-to-plane ICP, {} threads, voxel {} m, \
         model {} points down to {}",
        args.hypotheses,
        rayon::current_num_threads(),
        args.voxel,
        model_points,
        model_points_down
    );
    println!("median ms: {medians}");
    println!("success: {successes}/{} = {rate:.3}", results.len());
    let report = json!({
        "threads": rayon::current_num_threads(),
        "voxel_size": f64::from(args.voxel),
        "repeat": args.repeat,
        "hypotheses": args.hypotheses,
        "trials": results.len(),
        "success_rate": rate,
        "model_points_down": model_points_down,
        "median_ms": medians,
        "per_trial": per_trial,
    });
    write_atomically(&args.out.join("rust_registration.json"), |f| {
        Ok(serde_json::to_writer_pretty(f, &report)?)
    })?;
    Ok(())
}
