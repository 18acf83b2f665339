//! The paper's central contrast on tiny cube renders: trained with the analytic symmetry set,
//! the model's predicted set recalls the cube's 24 symmetries; trained with the single
//! rendering pose, it does not.
use crate::common;

use ipdf_metrics::{
    Distribution, GridCell, RECALL_THRESHOLD, llh, maad, nearest_distances, recall_maad,
};
use ipdf_model::rotation::{
    ArgmaxOptions, ImplicitPdf, LabelLoss, LabelledImages, Precision, Predictor, QuerySampling,
    TrainOptions, Trainer, UNDER_RESOLUTION_LIMIT,
};
use ipdf_model::{Augmentation, LearningRateSchedule, ModelConfig, RefineOptions};
use nalgebra::UnitQuaternion;
use so3_grid::Grid;
use tch::Device;

const SIZE: usize = 32;
const STEPS: u64 = 400;
const BATCH: usize = 16;
/// A symmetry counts as recalled when a predicted cell lies within this angle of it.
const RECALLED_WITHIN_DEG: f64 = 20.0;

/// Scores over the test images against their full symmetry sets, on the dense level-3 grid.
struct Scores {
    /// Mean log-likelihood.
    llh: f64,
    /// Mean Recall MAAD, degrees.
    recall_maad: f64,
    /// Mean fraction of the 24 symmetric orientations with a predicted cell (mass above
    /// Recall MAAD's threshold) within [`RECALLED_WITHIN_DEG`].
    recalled: f64,
}

fn score(model: &ImplicitPdf, test: &common::CubeRenders) -> Scores {
    let grid = Grid::new(3).unwrap();
    let mut predictor = Predictor::new(model);
    let (mut total_llh, mut total_recall, mut total_recalled) = (0.0, 0.0, 0.0);
    for (i, pose) in test.poses.iter().enumerate() {
        let masses = predictor
            .probabilities(&test.images.get(i as i64), 3)
            .unwrap();
        let distribution = Distribution::dense(&grid, masses).unwrap();
        let truth = test.group.expand(pose);
        total_llh += llh(&distribution, &truth).unwrap();
        total_recall += recall_maad(&distribution, &truth, RECALL_THRESHOLD).unwrap();
        let predicted: Vec<UnitQuaternion<f64>> = (0..distribution.len())
            .filter(|&c| distribution.masses()[c] / 8.0 > RECALL_THRESHOLD) // level-4 cell volume
            .map(|c| distribution.rotations()[c])
            .collect();
        let distances = nearest_distances(&truth, &predicted);
        let within = distances
            .iter()
            .filter(|d| d.to_degrees() < RECALLED_WITHIN_DEG)
            .count();
        total_recalled += within as f64 / truth.len() as f64;
    }
    let n = test.poses.len() as f64;
    Scores {
        llh: total_llh / n,
        recall_maad: total_recall / n,
        recalled: total_recalled / n,
    }
}

/// How the hierarchical evaluation (level 2 → 4, default budget) compares with the dense
/// level-4 grid over the test images.
#[derive(Debug, Default)]
struct HierarchyGaps {
    /// Mean |ΔLLH| of the reference's log-likelihood, `F(R_gt) − ln Z`.
    llh: f64,
    /// The same for the hierarchy evaluated in bfloat16 against the dense float32 grid.
    llh_bf16: f64,
    /// Mean |ΔLLH| of the cell-based log-likelihood (`ipdf_metrics::llh`: the density of the cell
    /// holding each ground-truth rotation).
    cell_llh: f64,
    /// Mean |ΔMAAD|, degrees.
    maad: f64,
    /// The largest query count of the hierarchy.
    queries: usize,
    /// Mean distance (degrees) from the argmax to the nearest symmetric pose.
    argmax_error: f64,
}

fn distribution(masses: ipdf_model::CellMasses) -> Distribution {
    let cells = masses
        .cells
        .iter()
        .map(|&(level, index)| GridCell { level, index })
        .collect();
    Distribution::from_cells(cells, masses.masses).unwrap()
}

/// [`Predictor::under_resolution`] of `model` on the test images, mean over them, with the
/// distribution refined to `level`.
fn under_resolution(model: &ImplicitPdf, test: &common::CubeRenders, level: u8) -> f64 {
    let mut predictor = Predictor::new(model);
    let values: Vec<f64> = (0..test.poses.len())
        .map(|i| {
            let image = test.images.get(i as i64);
            let masses = predictor
                .hierarchical(&image, &RefineOptions::to_level(level))
                .unwrap();
            predictor.under_resolution(&image, &masses).unwrap()
        })
        .collect();
    values.iter().sum::<f64>() / values.len() as f64
}

fn hierarchy_against_dense(model: &ImplicitPdf, test: &common::CubeRenders) -> HierarchyGaps {
    let mut predictor = Predictor::new(model);
    let mut bf16 = Predictor::with_precision(model, Precision::BFloat16);
    let dense_options = RefineOptions {
        start_level: 4,
        max_queries: usize::MAX,
        ..RefineOptions::default()
    };
    let mut gaps = HierarchyGaps::default();
    let mean = |values: Vec<f64>| values.iter().sum::<f64>() / values.len() as f64;
    for (i, pose) in test.poses.iter().enumerate() {
        let image = test.images.get(i as i64);
        let truth = test.group.expand(pose);
        let dense = predictor.hierarchical(&image, &dense_options).unwrap();
        let refined = predictor
            .hierarchical(&image, &RefineOptions::default())
            .unwrap();
        let refined_bf16 = bf16
            .hierarchical(&image, &RefineOptions::default())
            .unwrap();
        gaps.queries = gaps.queries.max(refined.queries);
        let dense_llh = mean(predictor.log_densities(&image, &truth, &dense).unwrap());
        let refined_llh = mean(predictor.log_densities(&image, &truth, &refined).unwrap());
        let bf16_llh = mean(bf16.log_densities(&image, &truth, &refined_bf16).unwrap());
        gaps.llh += (refined_llh - dense_llh).abs();
        gaps.llh_bf16 += (bf16_llh - dense_llh).abs();
        let (dense, refined) = (distribution(dense), distribution(refined));
        gaps.cell_llh += (llh(&refined, &truth).unwrap() - llh(&dense, &truth).unwrap()).abs();
        gaps.maad += (maad(&refined, &truth).unwrap() - maad(&dense, &truth).unwrap()).abs();
        let best = predictor.argmax(&image, &ArgmaxOptions::default()).unwrap();
        gaps.argmax_error += nearest_distances(&[best.rotation], &truth)[0].to_degrees();
    }
    let n = test.poses.len() as f64;
    HierarchyGaps {
        llh: gaps.llh / n,
        llh_bf16: gaps.llh_bf16 / n,
        cell_llh: gaps.cell_llh / n,
        maad: gaps.maad / n,
        argmax_error: gaps.argmax_error / n,
        ..gaps
    }
}

fn train(train: &common::CubeRenders, label_sets: Vec<Vec<UnitQuaternion<f64>>>) -> ImplicitPdf {
    let config = ModelConfig {
        head_sizes: vec![64, 64],
        ..ModelConfig::small(SIZE as i64)
    };
    let model = ImplicitPdf::new(config, Device::Cpu).unwrap();
    let options = TrainOptions {
        schedule: LearningRateSchedule {
            peak: 5e-3,
            warmup_steps: 20,
            total_steps: STEPS,
        },
        queries: QuerySampling::Grid { level: 2 },
        label_loss: LabelLoss::WholeSet,
        augmentation: Augmentation::NONE,
        ..TrainOptions::default()
    };
    let data = LabelledImages::new(train.images.shallow_clone(), label_sets).unwrap();
    let mut trainer = Trainer::new(model, options).unwrap();
    let order: Vec<usize> = (0..data.len()).collect();
    for step in 0..STEPS as usize {
        let indices: Vec<usize> = (0..BATCH)
            .map(|i| order[(step * BATCH + i) % order.len()])
            .collect();
        let (images, sets) = data.batch(&indices);
        trainer.train_step(&images, &sets).unwrap();
    }
    trainer.into_model()
}

#[test]
fn symmetry_sets_are_learned_from_set_labels_and_not_from_single_labels() {
    let started = std::time::Instant::now();
    let train_set = common::cube_renders(256, 1, SIZE);
    let test_set = common::cube_renders(16, 2, SIZE);
    let analytic_sets = train_set
        .poses
        .iter()
        .map(|pose| train_set.group.expand(pose))
        .collect();
    let single_sets = train_set.poses.iter().map(|pose| vec![*pose]).collect();

    let analytic_model = train(&train_set, analytic_sets);
    let analytic = score(&analytic_model, &test_set);
    let single_model = train(&train_set, single_sets);
    let single = score(&single_model, &test_set);
    println!(
        "analytic: LLH {:.2}, recall MAAD {:.1}°, {:.0}% recalled; \
         single: LLH {:.2}, recall MAAD {:.1}°, {:.0}% recalled; {:.0} s",
        analytic.llh,
        analytic.recall_maad,
        100.0 * analytic.recalled,
        single.llh,
        single.recall_maad,
        100.0 * single.recalled,
        started.elapsed().as_secs_f64()
    );
    for (name, model) in [("analytic", &analytic_model), ("single", &single_model)] {
        let gaps = hierarchy_against_dense(model, &test_set);
        println!("{name}: hierarchical − dense level 4: {gaps:?}");
        assert!(gaps.queries * 20 <= 294_912, "{name}: {gaps:?}");
        if name == "single" {
            // A concentrated density: the bounds.
            assert!(gaps.llh < 0.02 && gaps.maad < 0.2, "{name}: {gaps:?}");
        } else {
            // 400 steps leave 5–15% of this model's mass in peaks inside level-2 cells whose
            // centres and siblings barely see them (≈ 0.13 nats of the normaliser are missed;
            // on the demo's trained models the gap is ≤ 0.005, see docs/results.md); the bound only
            // catches a broken hierarchy.
            assert!(gaps.llh < 0.5 && gaps.maad < 2.0, "{name}: {gaps:?}");
            assert!(gaps.argmax_error < 10.0, "{name}: {gaps:?}");
        }
    }
    // The analytic model's peaks hide inside level-2 cells (see above): the check that tells
    // `ipdf eval` a level is too coarse sees it there and much less at level 4.
    let coarse_and_fine = [2, 4].map(|level| under_resolution(&analytic_model, &test_set, level));
    println!("analytic: under-resolution at levels 2 and 4: {coarse_and_fine:?}");
    assert!(
        coarse_and_fine[0] > UNDER_RESOLUTION_LIMIT
            && coarse_and_fine[1] < 0.5 * coarse_and_fine[0],
        "{coarse_and_fine:?}"
    );
    let uniform_llh = -std::f64::consts::PI.powi(2).ln();
    assert!(
        analytic.llh > uniform_llh + 3.0,
        "analytic LLH {}",
        analytic.llh
    );
    assert!(
        analytic.recalled > 0.6,
        "analytic recalled {}",
        analytic.recalled
    );
    assert!(single.recalled < 0.3, "single recalled {}", single.recalled);
    assert!(
        single.recall_maad > analytic.recall_maad + 30.0,
        "recall MAAD: single {}°, analytic {}°",
        single.recall_maad,
        analytic.recall_maad
    );
}
