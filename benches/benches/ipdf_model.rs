//! ipdf-model hot paths: a training step (batch 32, 96×96 crops, level-2 grid queries, head
//! 4 × 256) with the small CNN and with ResNet-18, in images/s, and the translation model's
//! step (4,096 queries) beside them; the dense level-4 distribution of one image (294,912
//! queries) and its hierarchical evaluation (level 2 → 4, ≤ 14,336 queries), each in float32
//! and with a bfloat16 head, and the hierarchical translation distribution of one image (octree
//! level 4 → 2 mm cells). Compare the training steps with `benches/python/ipdf_train_step.py`,
//! the same step in PyTorch on the same libtorch.
use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ipdf_model::rotation::{ImplicitPdf, Precision, Predictor, TrainOptions, Trainer};
use ipdf_model::translation::{
    CameraIntrinsics, CropGeometry, TranslationConfig, TranslationPdf, TranslationPredictor,
    TranslationSpace, TranslationTrainOptions, TranslationTrainer, WorkingVolume,
};
use ipdf_model::{CropBox, EncoderKind, ModelConfig, RefineOptions};
use nalgebra::{UnitQuaternion, Vector3};
use so3_grid::random_rotations;
use tch::{Device, Kind, Tensor};

// As the `ipdf` binary: mimalloc keeping freed pages (see examples/ipdf/src/allocator.rs).
ipdf::keep_freed_pages_allocator!();

const BATCH: i64 = 32;
const SIZE: i64 = 96;

fn config(encoder: EncoderKind) -> ModelConfig {
    ModelConfig {
        encoder,
        input_size: SIZE,
        ..ModelConfig::default()
    }
}

/// A translation model with the rotation benches' network, over a volume of 600 × 500 × 600 mm
/// at 0.45–1.05 m (the quick pipeline's tabletop views), 2 mm cells at octree level 9.
fn translation_model(encoder: EncoderKind) -> TranslationPdf {
    let space = TranslationSpace {
        volume: WorkingVolume::new([-300.0, -250.0, 450.0], [300.0, 250.0, 1050.0]).unwrap(),
        crop_extent: 250.0,
    };
    let config = TranslationConfig {
        network: config(encoder),
        space,
    };
    TranslationPdf::new(config, Device::Cpu).unwrap()
}

/// A crop of 300 px near the image centre of a 1075 px focal length camera.
fn crop_geometry() -> CropGeometry {
    CropGeometry {
        crop: CropBox {
            centre_x: 300.0,
            centre_y: 260.0,
            side: 300.0,
        },
        intrinsics: CameraIntrinsics {
            fx: 1075.0,
            fy: 1075.0,
            cx: 320.0,
            cy: 240.0,
        },
        width: 640,
        height: 480,
    }
}

fn train_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("train_step");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.throughput(Throughput::Elements(BATCH as u64));
    tch::manual_seed(0);
    let images = Tensor::rand([BATCH, 3, SIZE, SIZE], (Kind::Float, Device::Cpu));
    let labels: Vec<Vec<UnitQuaternion<f64>>> = random_rotations(BATCH as usize, 1)
        .into_iter()
        .map(|r| vec![r])
        .collect();
    for (name, encoder) in [
        ("small_cnn_96px_b32", EncoderKind::SmallCnn),
        ("resnet18_96px_b32", EncoderKind::Resnet18),
    ] {
        let model = ImplicitPdf::new(config(encoder), Device::Cpu).unwrap();
        let mut trainer = Trainer::new(model, TrainOptions::default()).unwrap();
        group.bench_function(name, |b| {
            b.iter(|| black_box(trainer.train_step(&images, &labels).unwrap()))
        });
    }
    let geometry = vec![crop_geometry(); BATCH as usize];
    let translations: Vec<Vec<Vector3<f64>>> = (0..BATCH)
        .map(|i| {
            vec![Vector3::new(
                10.0 * i as f64 - 150.0,
                20.0,
                700.0 + 5.0 * i as f64,
            )]
        })
        .collect();
    let model = translation_model(EncoderKind::SmallCnn);
    let mut trainer = TranslationTrainer::new(model, TranslationTrainOptions::default()).unwrap();
    group.bench_function("translation_small_cnn_96px_b32", |b| {
        b.iter(|| {
            black_box(
                trainer
                    .train_step(&images, &geometry, &translations)
                    .unwrap(),
            )
        })
    });
    group.finish();
}

fn evaluation(c: &mut Criterion) {
    let mut group = c.benchmark_group("evaluate");
    group.sample_size(10);
    let model = ImplicitPdf::new(config(EncoderKind::Resnet18), Device::Cpu).unwrap();
    let image = Tensor::rand([3, SIZE, SIZE], (Kind::Float, Device::Cpu));
    let options = RefineOptions::default();
    for (suffix, precision) in [("", Precision::Model), ("_bf16", Precision::BFloat16)] {
        let mut predictor = Predictor::with_precision(&model, precision);
        // The first call builds and caches the level-4 query term.
        predictor.probabilities(&image, 4).unwrap();
        group.throughput(Throughput::Elements(294_912));
        group.bench_function(format!("dense_level4_resnet18_96px{suffix}"), |b| {
            b.iter(|| black_box(predictor.probabilities(&image, 4).unwrap()))
        });
        group.throughput(Throughput::Elements(1));
        group.bench_function(format!("hierarchical_level4_resnet18_96px{suffix}"), |b| {
            b.iter(|| black_box(predictor.hierarchical(&image, &options).unwrap()))
        });
    }
    let model = translation_model(EncoderKind::Resnet18);
    let predictor = TranslationPredictor::new(&model);
    let geometry = crop_geometry();
    let options = predictor.refine_options(&geometry, 2.0);
    group.bench_function("translation_hierarchical_2mm_resnet18_96px", |b| {
        b.iter(|| black_box(predictor.hierarchical(&image, &geometry, &options).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, train_step, evaluation);
criterion_main!(benches);
