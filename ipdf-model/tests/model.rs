//! The model's shapes, gradients, distributions and refinement, through the public API.
use ipdf_model::rotation::{
    ArgmaxOptions, ImplicitPdf, Precision, Predictor, TrainOptions, Trainer, set_nll,
};
use ipdf_model::{EncoderKind, ModelConfig, RefineOptions, refine};
use nalgebra::UnitQuaternion;
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use so3_grid::{Grid, geodesic_distance};
use tch::{Device, Kind, Tensor};

fn images(count: i64, size: i64, seed: i64) -> Tensor {
    let values: Vec<f32> = (0..count * 3 * size * size)
        .map(|i| ((i * 7919 + seed * 104_729) % 1000) as f32 / 1000.0)
        .collect();
    Tensor::from_slice(&values).reshape([count, 3, size, size])
}

#[test]
fn every_encoder_gives_one_score_per_query() {
    for (encoder, size, features) in [
        (EncoderKind::SmallCnn, 32, 256),
        (EncoderKind::SmallCnnDeep, 64, 256),
        (EncoderKind::Resnet18, 64, 512),
        (EncoderKind::Resnet18Stage3, 64, 256 * 4 * 4),
        (EncoderKind::ConvnextTiny, 64, 768),
        (EncoderKind::EfficientnetLite0, 64, 1280),
    ] {
        let config = ModelConfig {
            encoder,
            input_size: size,
            head_sizes: vec![16, 16],
            ..ModelConfig::default()
        };
        let model = ImplicitPdf::new(config, Device::Cpu).unwrap();
        let image_term = model.image_term(&images(2, size, 1), false).unwrap();
        assert_eq!(image_term.size(), [2, 16], "{encoder}");
        let first_layer = model.var_store().variables()["head.image.weight"].size();
        assert_eq!(first_layer, [16, features], "{encoder}");
        let rotations = ipdf_model::rotation::rotations_to_tensor(
            &Grid::new(0).unwrap().rotations(),
            Device::Cpu,
        );
        let scores = model.scores(&image_term.unsqueeze(1), &model.query_term(&rotations));
        assert_eq!(scores.size(), [2, 72], "{encoder}");
        assert!(f64::try_from(scores.isfinite().all().to_kind(Kind::Double)).unwrap() == 1.0);
    }
}

#[test]
fn the_deep_small_cnn_adds_a_stride_one_convolution_to_its_last_two_stages() {
    let convolutions = |encoder| {
        let config = ModelConfig {
            encoder,
            ..ModelConfig::small(64)
        };
        let model = ImplicitPdf::new(config, Device::Cpu).unwrap();
        let mut shapes: Vec<(String, Vec<i64>)> = model
            .var_store()
            .variables()
            .into_iter()
            .filter(|(name, _)| name.starts_with("encoder.conv") && name.ends_with(".weight"))
            .map(|(name, tensor)| (name, tensor.size()))
            .collect();
        shapes.sort();
        shapes
    };
    let plain = convolutions(EncoderKind::SmallCnn);
    let deep = convolutions(EncoderKind::SmallCnnDeep);
    assert_eq!(plain.len(), 4, "{plain:?}");
    // The plain net's four, and a 3×3 one keeping the width of the third and fourth stages.
    let added: Vec<_> = deep.iter().filter(|c| !plain.contains(c)).collect();
    assert_eq!(deep.len(), 6, "{deep:?}");
    assert_eq!(
        added,
        [
            &("encoder.conv3b.weight".to_string(), vec![128, 128, 3, 3]),
            &("encoder.conv4b.weight".to_string(), vec![256, 256, 3, 3]),
        ]
    );
}

#[test]
fn weights_depend_only_on_the_seed() {
    let config = ModelConfig::small(32);
    let a = ImplicitPdf::new(config.clone(), Device::Cpu).unwrap();
    let b = ImplicitPdf::new(config.clone(), Device::Cpu).unwrap();
    let c = ImplicitPdf::new(ModelConfig { seed: 1, ..config }, Device::Cpu).unwrap();
    let weight =
        |m: &ImplicitPdf| m.var_store().variables()["head.hidden.0.weight"].shallow_clone();
    assert!(weight(&a).equal(&weight(&b)));
    assert!(!weight(&a).equal(&weight(&c)));
}

#[test]
fn loss_gradient_matches_finite_differences() {
    let config = ModelConfig {
        head_sizes: vec![8, 8],
        ..ModelConfig::small(16)
    };
    let mut model = ImplicitPdf::new(config, Device::Cpu).unwrap();
    model.var_store_mut().double();
    let options = TrainOptions {
        queries: ipdf_model::rotation::QuerySampling::Uniform { count: 64 },
        ..TrainOptions::default()
    };
    let trainer = Trainer::new(model, options).unwrap();
    let batch = images(2, 16, 3).to_kind(Kind::Double);
    let labels = vec![
        vec![
            UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
            UnitQuaternion::identity(),
        ],
        vec![UnitQuaternion::from_euler_angles(-1.0, 0.5, 2.0)],
    ];
    let loss_at = |trainer: &Trainer| {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        trainer.loss(&batch, &labels, &mut rng, false).unwrap()
    };
    let loss = loss_at(&trainer);
    loss.backward();
    let variables = trainer.model().var_store().variables();
    for name in [
        "head.hidden.0.weight",
        "head.query.weight",
        "head.image.bias",
    ] {
        let mut parameter = variables[name].shallow_clone();
        let analytic = parameter.grad().reshape([-1]);
        for index in [0i64, 5] {
            let h = 1e-6;
            let shift = |delta: f64| {
                tch::no_grad(|| {
                    let flat = parameter.view([-1]);
                    let _ = flat
                        .get(index)
                        .g_add_(&Tensor::from(delta).to_kind(Kind::Double));
                })
            };
            shift(h);
            let up = f64::try_from(loss_at(&trainer)).unwrap();
            shift(-2.0 * h);
            let down = f64::try_from(loss_at(&trainer)).unwrap();
            shift(h);
            let numeric = (up - down) / (2.0 * h);
            let exact = f64::try_from(analytic.get(index)).unwrap();
            assert!(
                (numeric - exact).abs() < 1e-6 * (1.0 + exact.abs()),
                "{name}[{index}]: finite difference {numeric}, autograd {exact}"
            );
            let _ = &mut parameter;
        }
    }
}

#[test]
fn dense_distribution_sums_to_one_and_hierarchy_agrees_where_the_mass_is() {
    let model = ImplicitPdf::new(ModelConfig::small(32), Device::Cpu).unwrap();
    let mut predictor = Predictor::new(&model);
    let image = images(1, 32, 5).get(0);
    let dense = predictor.probabilities(&image, 3).unwrap();
    assert_eq!(dense.len(), 36_864);
    assert!((dense.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    assert!(dense.iter().all(|&m| m > 0.0));
    // Refining every cell from level 2 reproduces the dense level 3 exactly.
    let options = RefineOptions {
        level: 3,
        keep_mass: 1.0,
        max_queries: usize::MAX,
        ..RefineOptions::default()
    };
    let refined = predictor.hierarchical(&image, &options).unwrap();
    assert_eq!(refined.queries, 4_608 + 36_864);
    for ((level, index), mass) in refined.cells.iter().zip(&refined.masses) {
        assert_eq!(*level, 3);
        assert!((mass - dense[*index as usize]).abs() < 1e-9 * (1.0 + dense[*index as usize]));
    }
}

/// Each `…_for` method, given the crop's image term once, returns what its image-taking
/// counterpart returns (evaluation computes the image term once per crop).
#[test]
fn a_crop_scored_from_its_image_term_scores_as_from_its_image() {
    let model = ImplicitPdf::new(ModelConfig::small(32), Device::Cpu).unwrap();
    let mut predictor = Predictor::new(&model);
    let image = images(1, 32, 7).get(0);
    let options = ArgmaxOptions {
        refine: RefineOptions::to_level(3),
        ..ArgmaxOptions::default()
    };
    let masses = predictor.hierarchical(&image, &options.refine).unwrap();
    let rotations = [
        UnitQuaternion::identity(),
        UnitQuaternion::from_euler_angles(0.3, -1.0, 2.0),
    ];
    let term = predictor.image_term(&image).unwrap();
    assert_eq!(
        predictor.hierarchical_for(&term, &options.refine).unwrap(),
        masses
    );
    assert_eq!(
        predictor
            .log_densities_for(&term, &rotations, &masses)
            .unwrap(),
        predictor
            .log_densities(&image, &rotations, &masses)
            .unwrap()
    );
    assert_eq!(
        predictor.probabilities_for(&term, 2).unwrap(),
        predictor.probabilities(&image, 2).unwrap()
    );
    assert_eq!(
        predictor.under_resolution_for(&term, &masses).unwrap(),
        predictor.under_resolution(&image, &masses).unwrap()
    );
    assert_eq!(
        predictor.argmax_from(&term, &masses, &options).unwrap(),
        predictor.argmax(&image, &options).unwrap()
    );
    let no_start = ArgmaxOptions {
        starts: 0,
        ..options
    };
    assert!(predictor.argmax_from(&term, &masses, &no_start).is_err());
}

#[test]
fn bfloat16_head_and_cell_lookups_agree_with_float32() {
    let model = ImplicitPdf::new(ModelConfig::small(32), Device::Cpu).unwrap();
    let image = images(1, 32, 9).get(0);
    let mut exact = Predictor::new(&model);
    let mut fast = Predictor::with_precision(&model, Precision::BFloat16);
    let term = exact.image_term(&image).unwrap();
    let cells: Vec<u64> = (0..4_608).step_by(37).collect();
    // Cells of a cached level are looked up in the grid's query term; arbitrary rotations go
    // through the encoding: the same `F`.
    let looked_up = exact.cell_scores(&term, 2, &cells).unwrap();
    let grid = Grid::new(2).unwrap();
    let rotations: Vec<_> = cells.iter().map(|&c| grid.rotation(c).unwrap()).collect();
    let encoded = exact.rotation_scores(&term, &rotations).unwrap();
    for (a, b) in looked_up.iter().zip(&encoded) {
        assert!((a - b).abs() < 1e-5, "{a} {b}");
    }
    let approximate = fast.cell_scores(&term, 2, &cells).unwrap();
    let spread = looked_up.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    for (a, b) in looked_up.iter().zip(&approximate) {
        assert!((a - b).abs() < 0.02 * (1.0 + spread), "{a} {b}");
    }
    assert_ne!(looked_up, approximate);
    assert!(exact.cell_scores(&term, 2, &[4_608]).is_err());
}

/// `F` peaked at `centre` with a width of about `1/√sharpness` radians.
fn analytic_scores(
    level: u8,
    cells: &[u64],
    centre: &UnitQuaternion<f64>,
    sharpness: f64,
) -> Vec<f64> {
    let grid = Grid::new(level).unwrap();
    cells
        .iter()
        .map(|&i| -sharpness * geodesic_distance(&grid.rotation(i).unwrap(), centre).powi(2))
        .collect()
}

#[test]
fn hierarchical_evaluation_matches_dense_level_4_on_an_analytic_density() {
    let centre = UnitQuaternion::from_euler_angles(0.7, -0.4, 2.2);
    let grid = Grid::new(4).unwrap();
    let all: Vec<u64> = (0..grid.len()).collect();
    let dense_scores = analytic_scores(4, &all, &centre, 50.0);
    let peak = dense_scores
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let total: f64 = dense_scores.iter().map(|s| (s - peak).exp()).sum();
    let options = RefineOptions::default();
    let refined = refine(|l, c| Ok(analytic_scores(l, c, &centre, 50.0)), &options).unwrap();
    assert!(
        refined.queries * 20 <= all.len(),
        "{} queries",
        refined.queries
    );
    // The density at the centre, and the mass on level-4 cells, agree with the dense grid.
    let cell = grid.locate(&centre).unwrap();
    let position = refined.cells.iter().position(|&c| c == (4, cell)).unwrap();
    let dense_mass = (dense_scores[cell as usize] - peak).exp() / total;
    let log_ratio = (refined.masses[position] / dense_mass).ln();
    println!(
        "ln(refined / dense) at the peak: {log_ratio:.2e}, {} queries",
        refined.queries
    );
    assert!(log_ratio.abs() < 0.02, "{log_ratio}");
    let fine_mass: f64 = refined
        .cells
        .iter()
        .zip(&refined.masses)
        .filter(|(c, _)| c.0 == 4)
        .map(|(_, m)| m)
        .sum();
    assert!(fine_mass > 0.999, "{fine_mass}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn refined_masses_sum_to_one_and_equal_dense_when_all_is_refined(
        yaw in -3.1f64..3.1, pitch in -1.5f64..1.5, roll in -3.1f64..3.1, sharpness in 0.0f64..200.0,
    ) {
        let centre = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        let everything = RefineOptions { start_level: 0, level: 1, keep_mass: 1.0, max_queries: usize::MAX };
        let refined = refine(|l, c| Ok(analytic_scores(l, c, &centre, sharpness)), &everything).unwrap();
        let dense = analytic_scores(1, &(0..576).collect::<Vec<_>>(), &centre, sharpness);
        let peak = dense.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let total: f64 = dense.iter().map(|s| (s - peak).exp()).sum();
        prop_assert!((refined.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let log_z = peak + (total * std::f64::consts::PI.powi(2) / 576.0).ln();
        prop_assert!((refined.log_normaliser - log_z).abs() < 1e-9);
        for ((_, index), mass) in refined.cells.iter().zip(&refined.masses) {
            prop_assert!((mass - (dense[*index as usize] - peak).exp() / total).abs() < 1e-12);
        }
        let budget = RefineOptions { start_level: 0, level: 2, keep_mass: 0.9, max_queries: 72 + 80 };
        let partial = refine(|l, c| Ok(analytic_scores(l, c, &centre, sharpness)), &budget).unwrap();
        prop_assert!((partial.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        prop_assert!(partial.queries <= 72 + 80);
    }

    #[test]
    fn equal_scores_give_the_uniform_density(count in 2i64..500, labels in 1i64..5, level in -5.0f64..5.0) {
        let queries = Tensor::full([2, count], level, (Kind::Double, Device::Cpu));
        let label_scores = Tensor::full([2, labels], level, (Kind::Double, Device::Cpu));
        let mask = Tensor::ones([2, labels], (Kind::Double, Device::Cpu));
        let nll = f64::try_from(set_nll(&queries, &label_scores, &mask)).unwrap();
        prop_assert!((nll - std::f64::consts::PI.powi(2).ln()).abs() < 1e-9);
    }
}

/// Two members that differ in seed and head width, the crop and the rotations to score.
fn two_members(seed: u64) -> [ImplicitPdf; 2] {
    let config = |seed, width| ModelConfig {
        seed,
        head_sizes: vec![width, width],
        ..ModelConfig::small(32)
    };
    [
        ImplicitPdf::new(config(seed, 32), Device::Cpu).unwrap(),
        ImplicitPdf::new(config(seed + 1, 16), Device::Cpu).unwrap(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4))]

    /// An ensemble's `F` is the mean of its members' `F`, each scored by a predictor of its
    /// own: on a cached grid level's cells and at arbitrary rotations, with or without views
    /// of the crop. Its distribution on a grid is then the members' normalised geometric
    /// mean, and its argmax reports the mean `F` where it ends.
    #[test]
    fn an_ensembles_score_is_the_mean_of_its_members(
        seed in 0u64..1_000, image_seed in 0i64..1_000, views in 0usize..3,
        yaw in -3.1f64..3.1, pitch in -1.5f64..1.5, roll in -3.1f64..3.1,
    ) {
        let models = two_members(seed);
        let image = images(1, 32, image_seed).get(0);
        let mut together =
            Predictor::ensemble(&models, Precision::Model).unwrap().with_views(views).unwrap();
        let mut alone: Vec<Predictor> = models
            .iter()
            .map(|m| Predictor::new(m).with_views(views).unwrap())
            .collect();
        let term = together.image_term(&image).unwrap();
        let terms: Vec<Tensor> = alone.iter().map(|p| p.image_term(&image).unwrap()).collect();
        let cells: Vec<u64> = (0..4_608).step_by(53).collect();
        let rotations = [
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
            UnitQuaternion::from_euler_angles(yaw, roll, pitch),
        ];
        let ensemble_cells = together.cell_scores(&term, 2, &cells).unwrap();
        let ensemble_rotations = together.rotation_scores(&term, &rotations).unwrap();
        let mut member_cells = Vec::new();
        let mut member_rotations = Vec::new();
        for (predictor, term) in alone.iter_mut().zip(&terms) {
            member_cells.push(predictor.cell_scores(term, 2, &cells).unwrap());
            member_rotations.push(predictor.rotation_scores(term, &rotations).unwrap());
        }
        for (i, f) in ensemble_cells.iter().enumerate() {
            let mean = (member_cells[0][i] + member_cells[1][i]) / 2.0;
            prop_assert!((f - mean).abs() < 1e-5, "cell {}: {} against {}", cells[i], f, mean);
        }
        for (i, f) in ensemble_rotations.iter().enumerate() {
            let mean = (member_rotations[0][i] + member_rotations[1][i]) / 2.0;
            prop_assert!((f - mean).abs() < 1e-5, "rotation {}: {} against {}", i, f, mean);
        }
        let masses = together.probabilities_for(&term, 1).unwrap();
        let p = alone[0].probabilities_for(&terms[0], 1).unwrap();
        let q = alone[1].probabilities_for(&terms[1], 1).unwrap();
        let geometric: Vec<f64> = p.iter().zip(&q).map(|(a, b)| (a * b).sqrt()).collect();
        let total: f64 = geometric.iter().sum();
        for (m, g) in masses.iter().zip(&geometric) {
            prop_assert!((m - g / total).abs() < 1e-9 * (1.0 + g / total), "{} against {}", m, g / total);
        }
        let options = ArgmaxOptions {
            refine: RefineOptions::to_level(2),
            steps: 5,
            ..ArgmaxOptions::default()
        };
        let best = together.argmax(&image, &options).unwrap();
        let at_best: Vec<f64> = alone
            .iter()
            .zip(&terms)
            .map(|(p, t)| p.rotation_scores(t, &[best.rotation]).unwrap()[0])
            .collect();
        let mean = (at_best[0] + at_best[1]) / 2.0;
        prop_assert!((best.score - mean).abs() < 1e-4, "{} against {}", best.score, mean);
    }
}

#[test]
fn models_that_read_other_crops_form_no_ensemble() {
    let message = |models: &[ImplicitPdf]| match Predictor::ensemble(models, Precision::Model) {
        Ok(_) => String::new(),
        Err(e) => e.to_string(),
    };
    assert!(message(&[]).contains("members"));
    let [a, _] = two_members(0);
    let wider = ImplicitPdf::new(ModelConfig::small(48), Device::Cpu).unwrap();
    let refused = message(&[a, wider]);
    assert!(
        refused.contains("members") && refused.contains("48-pixel"),
        "{refused}"
    );
    let [a, _] = two_members(0);
    let turned = ImplicitPdf::new(
        ModelConfig {
            rotation_frame: ipdf_model::rotation::RotationFrame::LineOfSight,
            ..ModelConfig::small(32)
        },
        Device::Cpu,
    )
    .unwrap();
    let refused = message(&[a, turned]);
    assert!(refused.contains("line-of-sight frame"), "{refused}");
    assert!(message(&two_members(3)).is_empty());
}

/// The variables of `trainer`'s model, copied.
fn snapshot(trainer: &Trainer) -> std::collections::HashMap<String, Tensor> {
    trainer
        .model()
        .var_store()
        .variables()
        .into_iter()
        .map(|(name, tensor)| (name, tensor.detach().copy()))
        .collect()
}

/// The encoder block (`Some(i)` for `encoder._blocks.i.…`, `None` for the stem) a variable of
/// EfficientNet-Lite0 belongs to; other variables (the head, the encoder's last convolution)
/// give `Some(usize::MAX)`.
fn lite0_block(name: &str) -> Option<usize> {
    if name.starts_with("encoder._conv_stem") || name.starts_with("encoder._bn0") {
        return None;
    }
    Some(
        name.strip_prefix("encoder._blocks.")
            .and_then(|rest| rest.split('.').next())
            .and_then(|index| index.parse().ok())
            .unwrap_or(usize::MAX),
    )
}

#[test]
fn frozen_blocks_keep_their_weights_and_statistics() {
    let labels = vec![vec![UnitQuaternion::identity()]; 4];
    for frozen in [0, 8] {
        let config = ModelConfig {
            encoder: EncoderKind::EfficientnetLite0,
            input_size: 32,
            head_sizes: vec![16, 16],
            frozen_blocks: frozen,
            ..ModelConfig::default()
        };
        let model = ImplicitPdf::new(config, Device::Cpu).unwrap();
        let mut trainer = Trainer::new(model, TrainOptions::default()).unwrap();
        let before = snapshot(&trainer);
        trainer.train_step(&images(4, 32, 5), &labels).unwrap();
        let after = snapshot(&trainer);
        for (name, old) in &before {
            let changed = !old.equal(&after[name]);
            // Adam moves every trained weight, the step's batch statistics every trained batch
            // norm's running mean and variance.
            let should_change = match lite0_block(name) {
                None => frozen == 0,
                Some(block) => block >= frozen,
            };
            assert_eq!(changed, should_change, "frozen {frozen}: {name}");
        }
    }
}

#[test]
fn only_efficientnet_freezes_and_no_more_than_its_blocks() {
    for (encoder, frozen, valid) in [
        (EncoderKind::EfficientnetLite0, 16, true),
        (EncoderKind::EfficientnetLite0, 17, false),
        (EncoderKind::Resnet18, 1, false),
        (EncoderKind::SmallCnn, 0, true),
    ] {
        let config = ModelConfig {
            encoder,
            input_size: 32,
            frozen_blocks: frozen,
            ..ModelConfig::default()
        };
        let result = ImplicitPdf::new(config, Device::Cpu);
        assert_eq!(result.is_ok(), valid, "{encoder} with {frozen} frozen");
        if let Err(error) = result {
            assert!(error.to_string().contains("frozen_blocks"), "{error}");
        }
    }
}
