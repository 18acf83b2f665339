//! ipdf-model hot paths: a training step (batch 32, 96×96 crops, level-2 grid queries, head
//! 4 × 256) with the small CNN and with ResNet-18, in images/s; the dense level-4 distribution
//! of one image (294,912 queries) and its hierarchical evaluation (level 2 → 4, ≤ 14,336
//! queries), each in float32 and with a bfloat16 head. Compare the training steps with `benches/python/ipdf_train_step.py`, the same
//! step in PyTorch on the same libtorch.
use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ipdf_model::{
    EncoderKind, ImplicitPdf, ModelConfig, Precision, Predictor, RefineOptions, TrainOptions,
    Trainer,
};
use nalgebra::UnitQuaternion;
use so3_grid::random_rotations;
use tch::{Device, Kind, Tensor};

// As the `ipdf` binary: jemalloc keeping freed pages (see examples/ipdf/src/allocator.rs).
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
    group.finish();
}

criterion_group!(benches, train_step, evaluation);
criterion_main!(benches);
