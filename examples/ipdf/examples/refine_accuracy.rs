//! How close the hierarchical evaluation (level 2 → 4, default budget) comes to the dense
//! level-4 grid on trained models: for each run under a models folder (`OBJECT/LABELS/`, as
//! `ipdf pipeline` writes them), the mean |ΔLLH| (the reference's `F(R_gt) − ln Z`) and |ΔMAAD|
//! over validation crops, and the queries and time of the hierarchy. Arguments: the models
//! folder, the crops per run (20) and the query budget (14,336).
//!
//! ```text
//! cargo run --release -p ipdf --example refine_accuracy -- runs/demo/models 20 14336
//! ```
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use ipdf::eval::rotation::cell_distribution;
use ipdf::run_info::{RUN_FILE, RunInfo};
use ipdf::training_data::{ExampleOptions, load_examples, to_unit_floats};
use ipdf_metrics::maad;
use ipdf_model::RefineOptions;
use ipdf_model::rotation::{ImplicitPdf, Predictor};

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let models = PathBuf::from(args.next().unwrap_or("runs/demo/models".into()));
    let images: usize = args.next().map_or(Ok(20), |n| n.parse())?;
    let budget = RefineOptions {
        max_queries: args.next().map_or(Ok(14_336), |n| n.parse())?,
        ..RefineOptions::default()
    };
    let mut runs: Vec<PathBuf> = glob_runs(&models)?;
    runs.sort();
    let dense = RefineOptions::dense(4);
    for run in runs {
        let info = RunInfo::read(&run)?;
        let model = ImplicitPdf::load(&run, ipdf_model::default_device())?;
        let size = model.config().input_size as usize;
        let options = ExampleOptions::evaluation("val", info.obj_id, size);
        let examples = load_examples(&info.dataset(None)?, &options)?;
        let Some(truths) = &examples.truth_sets else {
            continue;
        };
        let mut predictor = Predictor::new(&model);
        let (mut llh_gap, mut maad_gap, mut queries, mut seconds) = (0.0, 0.0, 0, 0.0);
        let count = truths.len().min(images);
        for (i, truth) in truths.iter().take(count).enumerate() {
            let crop = to_unit_floats(&examples.crops.get(i as i64));
            let full = predictor.hierarchical(&crop, &dense)?;
            let started = Instant::now();
            let refined = predictor.hierarchical(&crop, &budget)?;
            seconds += started.elapsed().as_secs_f64();
            queries = queries.max(refined.queries);
            let mean = |values: Vec<f64>| values.iter().sum::<f64>() / values.len() as f64;
            let dense_llh = mean(predictor.log_densities(&crop, truth, &full)?);
            let refined_llh = mean(predictor.log_densities(&crop, truth, &refined)?);
            llh_gap += (refined_llh - dense_llh).abs();
            let (full, refined) = (cell_distribution(&full)?, cell_distribution(&refined)?);
            maad_gap += (maad(&refined, truth)? - maad(&full, truth)?).abs();
        }
        let n = count.max(1) as f64;
        println!(
            "{:<5} {:<10} |ΔLLH| {:.4}  |ΔMAAD| {:.3}°  ≤ {queries} queries  {:.0} ms",
            info.object,
            info.labels,
            llh_gap / n,
            maad_gap / n,
            1e3 * seconds / n
        );
    }
    Ok(())
}

/// The run folders one and two levels below `models` (those holding a `run.json`).
fn glob_runs(models: &std::path::Path) -> Result<Vec<PathBuf>> {
    let mut runs = Vec::new();
    for object in std::fs::read_dir(models)? {
        for run in std::fs::read_dir(object?.path())? {
            let run = run?.path();
            if run.join(RUN_FILE).is_file() {
                runs.push(run);
            }
        }
    }
    Ok(runs)
}
