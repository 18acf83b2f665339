//! The translation model on renders of a cube at random places in front of the camera: it
//! learns where the cube is to a few millimetres; its octree distribution sums to 1 and matches
//! the dense grid; gradient ascent ends near the densest cell; bad input gets typed errors.
use crate::common;

use common::render_cube;
use depth_render::{PinholeCamera, Primitive, Scene};
use ipdf_model::rotation::ImplicitPdf;
use ipdf_model::translation::{
    CROP_VOLUME_SPAN, CameraIntrinsics, CropGeometry, LabelledTranslations,
    TranslationArgmaxOptions, TranslationConfig, TranslationPdf, TranslationPredictor,
    TranslationSpace, TranslationTrainOptions, TranslationTrainer, WorkingVolume, in_crop_span,
};
use ipdf_model::{
    CHECKPOINT_FILE, CellHierarchy, CheckpointInfo, CropOptions, FitOptions, ModelError,
    RefineOptions, crop_box, crop_object, crops_to_tensor, refine_on,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tch::{Device, Tensor};

const SIZE: usize = 32;
const IMAGE: usize = 192;
const FOCAL: f64 = 330.0;

/// Crops of a 10 cm cube (one fixed generic orientation) at `count` random translations
/// (z 450–650 mm, within ±12% of z sideways), their geometry and translations (mm).
struct Renders {
    images: Tensor,
    geometry: Vec<CropGeometry>,
    translations: Vec<Vector3<f64>>,
}

fn renders(count: usize, seed: u64) -> Renders {
    let cube = Primitive::Cuboid { extents: [0.1; 3] };
    let scene = Scene::new(&[cube.mesh().unwrap()]);
    let centre = IMAGE as f64 / 2.0;
    let camera =
        PinholeCamera::new(FOCAL, FOCAL, centre, centre, IMAGE as u32, IMAGE as u32).unwrap();
    let intrinsics = CameraIntrinsics {
        fx: FOCAL,
        fy: FOCAL,
        cx: centre,
        cy: centre,
    };
    let rotation = UnitQuaternion::from_euler_angles(0.5, 0.3, 0.2);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut crops, mut geometry, mut translations) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..count {
        let z = rng.random_range(0.45..0.65);
        let x = z * rng.random_range(-0.12..0.12);
        let y = z * rng.random_range(-0.12..0.12);
        let pose = Isometry3::from_parts(Translation3::new(x, y, z), rotation);
        let (rgb, mask) = render_cube(&scene, &camera, pose);
        let options = CropOptions::new(SIZE);
        crops.push(crop_object(&rgb, &mask, IMAGE, IMAGE, &options).unwrap());
        geometry.push(CropGeometry {
            crop: crop_box(&mask, IMAGE, IMAGE, &options).unwrap(),
            intrinsics,
            width: IMAGE,
            height: IMAGE,
        });
        translations.push(Vector3::new(x, y, z) * 1000.0);
    }
    Renders {
        images: crops_to_tensor(&crops, SIZE).unwrap(),
        geometry,
        translations,
    }
}

fn label_sets(renders: &Renders) -> Vec<Vec<Vector3<f64>>> {
    renders.translations.iter().map(|t| vec![*t]).collect()
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[test]
fn translations_are_learned_to_a_few_millimetres() {
    let train = renders(192, 1);
    let test = renders(24, 2);
    let labels = label_sets(&train);
    let space = TranslationSpace::from_labels(&labels, &train.geometry).unwrap();
    let model =
        TranslationPdf::new(TranslationConfig::small(SIZE as i64, space), Device::Cpu).unwrap();
    let steps = 300;
    let mut options = TranslationTrainOptions {
        queries: 1_024,
        ..TranslationTrainOptions::default()
    };
    options.schedule.total_steps = steps;
    options.schedule.warmup_steps = 20;
    let mut trainer = TranslationTrainer::new(model, options).unwrap();
    let batch = 16;
    let mut first_loss = None;
    let mut last_losses = Vec::new();
    for step in 0..steps as usize {
        let indices: Vec<i64> = (0..batch)
            .map(|i| ((step * batch + i) % train.translations.len()) as i64)
            .collect();
        let images = train.images.index_select(0, &Tensor::from_slice(&indices));
        let geometry: Vec<CropGeometry> = indices
            .iter()
            .map(|&i| train.geometry[i as usize])
            .collect();
        let sets: Vec<Vec<Vector3<f64>>> = indices
            .iter()
            .map(|&i| labels[i as usize].clone())
            .collect();
        let report = trainer.train_step(&images, &geometry, &sets).unwrap();
        first_loss.get_or_insert(report.loss);
        if step as u64 >= steps - 20 {
            last_losses.push(report.loss);
        }
    }
    let model = trainer.into_model();
    let predictor = TranslationPredictor::new(&model);
    let argmax_options = TranslationArgmaxOptions::default();
    let mut errors = Vec::new();
    let mut log_likelihoods = Vec::new();
    let mut uniform_llhs = Vec::new();
    for (i, truth) in test.translations.iter().enumerate() {
        let image = test.images.get(i as i64);
        let geometry = &test.geometry[i];
        let argmax = predictor.argmax(&image, geometry, &argmax_options).unwrap();
        errors.push((argmax.translation - truth).norm());
        assert!(argmax.score >= argmax.start_score);
        let refine = predictor.refine_options(geometry, argmax_options.cell_size);
        let distribution = predictor.hierarchical(&image, geometry, &refine).unwrap();
        assert!((distribution.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        uniform_llhs.push(-predictor.volume(geometry).extent().product().ln());
        let llh = predictor
            .log_densities(&image, geometry, &[*truth], &distribution)
            .unwrap()[0];
        log_likelihoods.push(llh);
        if i == 0 {
            // The crop's terms computed once give the same results.
            let terms = predictor.crop_terms(&image, geometry).unwrap();
            let again = predictor
                .hierarchical_for(&terms, geometry, &refine)
                .unwrap();
            assert_eq!(again, distribution);
            let llh_again = predictor
                .log_densities_for(&terms, &[*truth], &distribution)
                .unwrap()[0];
            assert_eq!(llh_again, llh);
            let from = predictor
                .argmax_from(&terms, geometry, &distribution, &argmax_options)
                .unwrap();
            assert_eq!(from, argmax);
        }
    }
    let uniform_llh = uniform_llhs.iter().sum::<f64>() / uniform_llhs.len() as f64;
    let mean_llh = log_likelihoods.iter().sum::<f64>() / log_likelihoods.len() as f64;
    let median_error = median(errors.clone());
    println!(
        "loss {:.2} → {:.2}; test: median error {median_error:.1} mm (max {:.1}), LLH {mean_llh:.2} (uniform {uniform_llh:.2})",
        first_loss.unwrap(),
        last_losses.iter().sum::<f64>() / last_losses.len() as f64,
        errors.iter().copied().fold(0.0, f64::max),
    );
    assert!(median_error < 6.0, "median error {median_error} mm");
    assert!(
        mean_llh > uniform_llh + 8.0,
        "LLH {mean_llh} vs {uniform_llh}"
    );
    // The label noise keeps every peak at least as wide as itself: no density above that of
    // an isotropic Gaussian of its σ at its mode (an unresolved spike scores far above it).
    let sigma = TranslationTrainOptions::default().label_noise_mm;
    let sharpest = -1.5 * (std::f64::consts::TAU * sigma * sigma).ln();
    assert!(
        mean_llh < sharpest + 1.0,
        "LLH {mean_llh}, sharpest {sharpest}"
    );

    // On one test crop: the hierarchical distribution against the dense level-6 grid (262,144
    // cells of at most 9 mm), and gradient ascent against the densest cell.
    let image = test.images.get(0);
    let geometry = &test.geometry[0];
    let volume = predictor.volume(geometry);
    let dense = predictor
        .hierarchical(
            &image,
            geometry,
            &RefineOptions {
                start_level: 6,
                level: 6,
                keep_mass: 1.0,
                max_queries: usize::MAX,
            },
        )
        .unwrap();
    let budgeted = predictor
        .hierarchical(
            &image,
            geometry,
            &RefineOptions {
                start_level: 4,
                level: 6,
                keep_mass: 0.9999,
                max_queries: 4_096 * 3,
            },
        )
        .unwrap();
    assert_eq!(dense.cells.len(), 262_144);
    let gap = (budgeted.log_normaliser - dense.log_normaliser).abs();
    assert!(
        gap < 0.05,
        "ln Z: hierarchical {} dense {}",
        budgeted.log_normaliser,
        dense.log_normaliser
    );
    let densest = |d: &ipdf_model::CellMasses| {
        let (level, index) = d.cells[d.densest_in(&volume, 1)[0]];
        volume.cell_centre(level, index).unwrap()
    };
    assert!((densest(&budgeted) - densest(&dense)).norm() < 1e-9);
    let refine = predictor.refine_options(geometry, argmax_options.cell_size);
    let fine = predictor.hierarchical(&image, geometry, &refine).unwrap();
    let argmax = predictor.argmax(&image, geometry, &argmax_options).unwrap();
    let finest = volume.extent() / f64::from(1u32 << refine.level);
    let offset = argmax.translation - densest(&fine);
    assert!(
        offset.norm() < 2.0 * finest.norm(),
        "ascent moved {offset:?} mm from the densest cell of size {finest:?}"
    );
}

#[test]
fn the_most_likely_translation_projects_near_its_crop() {
    // Untrained models, whose `F` is any smooth function of the query: over a crop's volume,
    // the box around the rays through the crop's span, it often peaks in a corner far from
    // those rays, where no object of that crop could lie.
    let data = renders(12, 4);
    let labels = label_sets(&data);
    let space = TranslationSpace::from_labels(&labels, &data.geometry).unwrap();
    let options = TranslationArgmaxOptions {
        cell_size: 8.0,
        ..TranslationArgmaxOptions::default()
    };
    let mut densest_outside = 0;
    for seed in 0..4 {
        let mut config = TranslationConfig::small(SIZE as i64, space);
        config.network.seed = seed;
        let model = TranslationPdf::new(config, Device::Cpu).unwrap();
        let predictor = TranslationPredictor::new(&model);
        for (k, geometry) in data.geometry.iter().enumerate() {
            let image = data.images.get(k as i64);
            let volume = predictor.volume(geometry);
            let refine = predictor.refine_options(geometry, options.cell_size);
            let masses = predictor.hierarchical(&image, geometry, &refine).unwrap();
            let (level, index) = masses.cells[masses.densest_in(&volume, 1)[0]];
            let densest = volume.cell_centre(level, index).unwrap();
            densest_outside += usize::from(!in_crop_span(geometry, &densest));
            let argmax = predictor.argmax(&image, geometry, &options).unwrap();
            let t = argmax.translation;
            // Where it projects, in crop sides from the crop's centre (pixel centres at
            // integers), against the half span.
            let (k_, c) = (geometry.intrinsics, geometry.crop);
            let u = (k_.fx * t.x / t.z + k_.cx + 0.5 - c.centre_x) / c.side;
            let v = (k_.fy * t.y / t.z + k_.cy + 0.5 - c.centre_y) / c.side;
            let half = 0.5 * CROP_VOLUME_SPAN;
            assert!(
                u.abs() <= half + 1e-9 && v.abs() <= half + 1e-9,
                "seed {seed}, crop {k}: {t:?} projects at ({u:.2}, {v:.2}) crop sides"
            );
            assert!(volume.contains(&t));
        }
    }
    // The test means something: some densest cells lay outside the span.
    assert!(
        densest_outside > 0,
        "every densest cell projected near its crop"
    );
}

/// An isotropic Gaussian log-density (σ mm) around `centre`, at cell centres.
fn gaussian(
    volume: &WorkingVolume,
    centre: &Vector3<f64>,
    sigma: f64,
    level: u8,
    cells: &[u64],
) -> Vec<f64> {
    cells
        .iter()
        .map(|&i| {
            -(volume.cell_centre(level, i).unwrap() - centre).norm_squared() / (2.0 * sigma * sigma)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn a_crops_volume_holds_every_translation_seen_in_the_crop_and_the_working_volume(
        cx in 200.0f64..440.0, cy in 150.0f64..330.0, centre_x in 0.0f64..640.0,
        centre_y in 0.0f64..480.0, side in 20.0f64..300.0, u in -1.0f64..1.0, v in -1.0f64..1.0,
        depth in 0.0f64..1.0, half_width in 100.0f64..900.0,
    ) {
        let geometry = CropGeometry {
            crop: ipdf_model::CropBox { centre_x, centre_y, side },
            intrinsics: CameraIntrinsics { fx: 600.0, fy: 610.0, cx, cy },
            width: 640,
            height: 480,
        };
        let volume = WorkingVolume::new(
            [-half_width, -0.8 * half_width, 400.0],
            [half_width, 0.8 * half_width, 1300.0],
        ).unwrap();
        let space = TranslationSpace { volume, crop_extent: 150.0 };
        let crop_volume = space.crop_volume(&geometry);
        prop_assert!(crop_volume.validate().is_ok());
        // Inside the working volume, on every axis.
        for axis in 0..3 {
            prop_assert!(crop_volume.min[axis] >= volume.min[axis] && crop_volume.max[axis] <= volume.max[axis]);
        }
        prop_assert_eq!((crop_volume.min[2], crop_volume.max[2]), (400.0, 1300.0));
        // A translation that projects into the crop square (pixel centres at integers) and lies
        // in the working volume lies in the crop's volume.
        let z = 400.0 + 900.0 * depth;
        let (pu, pv) = (centre_x + 0.5 * side * u, centre_y + 0.5 * side * v);
        let t = Vector3::new((pu - cx - 0.5) / 600.0 * z, (pv - cy - 0.5) / 610.0 * z, z);
        if volume.contains(&t) {
            prop_assert!(crop_volume.contains(&t), "{t:?} outside {crop_volume:?}");
        }
        // It projects into the span's square; a translation projecting beyond it does not.
        prop_assert!(in_crop_span(&geometry, &t));
        let beyond = 0.5 * CROP_VOLUME_SPAN * side * (1.0 + 0.5 * depth) + 1.0;
        let (wu, wv) = if u >= 0.0 { (centre_x + beyond, pv) } else { (pu, centre_y - beyond) };
        let wide = Vector3::new((wu - cx - 0.5) / 600.0 * z, (wv - cy - 0.5) / 610.0 * z, z);
        prop_assert!(!in_crop_span(&geometry, &wide), "{wide:?}");
        prop_assert!(!in_crop_span(&geometry, &(-t)));
        // No wider than the span's square at the farthest depth plus how far its edges' rays
        // move between the nearest and farthest depth, nor than the working volume: narrow
        // wherever the crop is (a crop volume that were the whole working volume fails here
        // whenever the crop's frustum is narrower than it).
        let half = 0.5 * ipdf_model::translation::CROP_VOLUME_SPAN * side;
        let (left, right) = ((centre_x - half - cx - 0.5) / 600.0, (centre_x + half - cx - 0.5) / 600.0);
        let slope = left.abs().max(right.abs());
        let width = 2.0 * half * 1300.0 / 600.0;
        let extent = crop_volume.extent().x;
        prop_assert!(extent <= (width + slope * 900.0).min(2.0 * half_width) + 1e-9, "{extent} vs {width}");
        // As wide as that square wherever the working volume holds it at the farthest depth
        // (decided from the inputs, not from the crop volume found).
        if left * 1300.0 >= -half_width && right * 1300.0 <= half_width {
            prop_assert!(extent >= width - 1e-9, "{extent} vs {width}");
        }
    }

    #[test]
    fn octree_refinement_sums_to_one_equals_dense_and_integrates_a_gaussian(
        x in -50.0f64..50.0, y in -50.0f64..50.0, z in 500.0f64..700.0, sigma in 3.0f64..30.0,
    ) {
        let volume = WorkingVolume::new([-200.0, -200.0, 400.0], [200.0, 200.0, 800.0]).unwrap();
        let centre = Vector3::new(x, y, z);
        let everything = RefineOptions { start_level: 1, level: 3, keep_mass: 1.0, max_queries: usize::MAX };
        let refined = refine_on(&volume, |l, c| Ok(gaussian(&volume, &centre, sigma, l, c)), &everything).unwrap();
        let dense = gaussian(&volume, &centre, sigma, 3, &(0..512).collect::<Vec<_>>());
        let peak = dense.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let total: f64 = dense.iter().map(|f| (f - peak).exp()).sum();
        prop_assert!((refined.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        prop_assert_eq!(refined.cells.len(), 512);
        for (&(level, index), mass) in refined.cells.iter().zip(&refined.masses) {
            prop_assert_eq!(level, 3);
            prop_assert!((mass - (dense[index as usize] - peak).exp() / total).abs() < 1e-12);
        }
        // Refined down to cells of ≤ 2 mm where the mass is, the normaliser is the Gaussian's
        // integral, (2πσ²)^{3/2}.
        let options = RefineOptions::translation(&volume, 2.0);
        let fine = refine_on(&volume, |l, c| Ok(gaussian(&volume, &centre, sigma, l, c)), &options).unwrap();
        let expected = 1.5 * (2.0 * std::f64::consts::PI * sigma * sigma).ln();
        prop_assert!((fine.log_normaliser - expected).abs() < 0.02, "{} vs {expected}", fine.log_normaliser);
        prop_assert!(fine.queries <= options.max_queries);
        prop_assert!((fine.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let cell = volume.cell_volume(options.level);
        prop_assert!(cell.cbrt() <= 2.0);
    }
}

#[test]
fn bad_translation_input_gets_typed_errors() {
    let data = renders(2, 3);
    let labels = label_sets(&data);
    let space = TranslationSpace::from_labels(&labels, &data.geometry).unwrap();
    let model =
        TranslationPdf::new(TranslationConfig::small(SIZE as i64, space), Device::Cpu).unwrap();
    let trainer = TranslationTrainer::new(model, TranslationTrainOptions::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut loss = |geometry: &[CropGeometry], sets: &[Vec<Vector3<f64>>]| {
        trainer.loss(&data.images, geometry, sets, &mut rng, false)
    };
    assert!(
        loss(&data.geometry, &labels)
            .unwrap()
            .double_value(&[])
            .is_finite()
    );
    let empty = vec![labels[0].clone(), vec![]];
    assert!(matches!(
        loss(&data.geometry, &empty),
        Err(ModelError::LabelSet { image: 1, .. })
    ));
    let far = vec![labels[0].clone(), vec![Vector3::new(0.0, 0.0, 5_000.0)]];
    let err = loss(&data.geometry, &far).unwrap_err();
    assert!(
        matches!(err, ModelError::LabelSet { image: 1, ref reason } if reason.contains("working volume")),
        "{err}"
    );
    let nan = vec![vec![Vector3::new(f64::NAN, 0.0, 500.0)], labels[1].clone()];
    let err = loss(&data.geometry, &nan);
    assert!(matches!(err, Err(ModelError::LabelSet { image: 0, .. })));
    assert_eq!(
        err.unwrap_err().to_string(),
        "label set 0: translation 0 [NaN, 0.0, 500.0] mm is not finite or not in front of the camera"
    );
    let err = loss(&data.geometry, &empty).unwrap_err();
    assert_eq!(err.to_string(), "label set 1: empty label set");
    let mut outside = data.geometry.clone();
    outside[1].crop.centre_x = IMAGE as f64 + 40.0;
    assert!(matches!(
        loss(&outside, &labels),
        Err(ModelError::CropGeometry { image: 1, .. })
    ));
    let mut principal = data.geometry.clone();
    principal[0].intrinsics.cx = 5_000.0;
    let err = loss(&principal, &labels).unwrap_err();
    assert!(
        matches!(err, ModelError::CropGeometry { image: 0, ref reason } if reason.contains("principal point")),
        "{err}"
    );
    assert!(matches!(
        TranslationSpace::from_labels(&[], &[]),
        Err(ModelError::LabelSet { .. })
    ));
    let predictor = TranslationPredictor::new(trainer.model());
    let volume = trainer.model().space().volume;
    assert!(matches!(
        volume.locate(4, &Vector3::new(0.0, 0.0, -10.0)),
        Err(ModelError::OutsideVolume { .. })
    ));
    assert!(
        predictor
            .argmax(
                &data.images.get(0),
                &outside[1],
                &TranslationArgmaxOptions::default()
            )
            .is_err()
    );
    for cell_size in [0.0, -1.0, f64::NAN] {
        let options = TranslationArgmaxOptions {
            cell_size,
            ..TranslationArgmaxOptions::default()
        };
        let err = predictor
            .argmax(&data.images.get(0), &data.geometry[0], &options)
            .unwrap_err();
        assert!(matches!(err, ModelError::InvalidOption { .. }), "{err}");
    }
}

#[test]
fn translation_runs_checkpoint_resume_and_load_only_as_translation_models() {
    let data = renders(10, 4);
    let labels = label_sets(&data);
    let space = TranslationSpace::from_labels(&labels, &data.geometry).unwrap();
    let mut config = TranslationConfig::small(SIZE as i64, space);
    config.network.head_sizes = vec![16, 16];
    let options = TranslationTrainOptions {
        queries: 64,
        ..TranslationTrainOptions::default()
    };
    let fresh = || {
        TranslationTrainer::new(
            TranslationPdf::new(config.clone(), Device::Cpu).unwrap(),
            options.clone(),
        )
        .unwrap()
    };
    let examples = LabelledTranslations::new(
        data.images.shallow_clone(),
        data.geometry.clone(),
        labels.clone(),
    )
    .unwrap();
    let fit_options = |epochs| FitOptions {
        epochs,
        steps_per_epoch: 2,
        batch_size: 4,
        validation_level: 0,
    };
    let (whole, split) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (trainer, reports, resumed) = common::uninterrupted_and_resumed(
        fresh,
        |dir| TranslationTrainer::resume(dir, Device::Cpu),
        &examples,
        fit_options,
        2,
        (whole.path(), split.path()),
    );
    assert!(
        reports
            .iter()
            .all(|r| r.validation_llh.is_some_and(f64::is_finite))
    );
    let weight =
        |model: &TranslationPdf| model.var_store().variables()["head.output.weight"].copy();
    assert!(weight(resumed.model()).equal(&weight(trainer.model())));

    // The space travels with the checkpoint; the loaded model scores as the trained one.
    let info = CheckpointInfo::read(whole.path()).unwrap();
    let saved = info.translation.unwrap();
    // serde_json's default float parser may be one ulp off.
    let close = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= 1e-9 * y.abs())
    };
    assert!(
        close(&saved.volume.min, &space.volume.min) && close(&saved.volume.max, &space.volume.max)
    );
    assert!(close(&[saved.crop_extent], &[space.crop_extent]));
    let loaded = TranslationPdf::load(whole.path(), Device::Cpu).unwrap();
    let image = data.images.get(0);
    let at = [labels[0][0], labels[0][0] + Vector3::new(5.0, 0.0, 0.0)];
    let a = TranslationPredictor::new(trainer.model())
        .scores(&image, &data.geometry[0], &at)
        .unwrap();
    let b = TranslationPredictor::new(&loaded)
        .scores(&image, &data.geometry[0], &at)
        .unwrap();
    assert_eq!(a, b);
    // Each loader refuses the other kind of checkpoint, naming the file.
    let err = ImplicitPdf::load(whole.path(), Device::Cpu).unwrap_err();
    assert!(err.to_string().contains(CHECKPOINT_FILE), "{err}");
    let rotation = tempfile::tempdir().unwrap();
    ImplicitPdf::new(ipdf_model::ModelConfig::small(16), Device::Cpu)
        .unwrap()
        .save(rotation.path())
        .unwrap();
    let err = TranslationPdf::load(rotation.path(), Device::Cpu).unwrap_err();
    assert!(matches!(err, ModelError::Checkpoint { .. }), "{err}");
}
