//! metrics hot paths: MAAD of a level-4 distribution against 200 ground-truth rotations, with
//! the library's fused rayon loop and, as the alternative it was chosen over, faer GEMM.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use faer::{Accum, Mat, Par};
use ipdf_metrics::{Distribution, RECALL_THRESHOLD, llh, maad, recall_maad};
use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use so3_grid::{Grid, geodesic_distance, random_rotations};
use std::hint::black_box;

/// MAAD in degrees through dense products: per chunk of cells, `C = A·Bᵀ` (cells × 4 times
/// 4 × gt) with faer, then the row maxima of |C|.
fn maad_faer(dist: &Distribution, gt: &[UnitQuaternion<f64>]) -> f64 {
    const CHUNK: usize = 4096;
    let b = Mat::<f64>::from_fn(gt.len(), 4, |i, j| gt[i].coords[j]);
    let total: f64 = dist
        .rotations()
        .par_chunks(CHUNK)
        .zip(dist.masses().par_chunks(CHUNK))
        .map(|(cells, masses)| {
            let a = Mat::<f64>::from_fn(cells.len(), 4, |i, j| cells[i].coords[j]);
            let mut c = Mat::<f64>::zeros(cells.len(), gt.len());
            faer::linalg::matmul::matmul(
                c.as_mut(),
                Accum::Replace,
                a.as_ref(),
                b.transpose(),
                1.0,
                Par::Seq,
            );
            (0..cells.len())
                .map(|i| {
                    let best =
                        (0..gt.len()).max_by(|&x, &y| c[(i, x)].abs().total_cmp(&c[(i, y)].abs()));
                    masses[i] * best.map_or(0.0, |g| geodesic_distance(&cells[i], &gt[g]))
                })
                .sum::<f64>()
        })
        .sum();
    total.to_degrees()
}

fn scores(c: &mut Criterion) {
    let grid = Grid::new(4).unwrap();
    let raw: Vec<f64> = random_rotations(grid.len() as usize, 3)
        .iter()
        .map(|q| q.angle() + 0.1)
        .collect();
    let sum: f64 = raw.iter().sum();
    let dist = Distribution::dense(&grid, raw.iter().map(|m| m / sum).collect()).unwrap();
    let gt = random_rotations(200, 4);

    let mut group = c.benchmark_group("maad");
    group.throughput(Throughput::Elements(grid.len() * gt.len() as u64));
    group.bench_function("level4_x200/rayon_f32_loop", |b| {
        b.iter(|| maad(black_box(&dist), &gt).unwrap())
    });
    group.bench_function("level4_x200/faer_gemm", |b| {
        b.iter(|| maad_faer(black_box(&dist), &gt))
    });
    group.finish();

    let mut group = c.benchmark_group("scores");
    group.bench_function("llh/level4_x200", |b| {
        b.iter(|| llh(black_box(&dist), &gt).unwrap())
    });
    group.bench_function("recall_maad/level4_x200", |b| {
        b.iter(|| recall_maad(black_box(&dist), &gt, RECALL_THRESHOLD).unwrap())
    });
    group.finish();
}

criterion_group!(benches, scores);
criterion_main!(benches);
