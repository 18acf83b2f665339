//! so3-grid hot paths: grid generation (levels 4 and 5, all cores), nearest and locate.
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use so3_grid::{Grid, random_rotations};
use std::hint::black_box;

fn generate(c: &mut Criterion) {
    let mut group = c.benchmark_group("grid");
    for level in [4u8, 5] {
        let count = so3_grid::cell_count(level);
        group.throughput(Throughput::Elements(count));
        // From nothing to the full list of rotations: what healpy + numpy is compared with.
        group.bench_function(BenchmarkId::new("generate", format!("level{level}")), |b| {
            b.iter(|| Grid::new(black_box(level)).unwrap().rotations())
        });
        // Regenerating into a reused buffer (no allocation, no HEALPix centres).
        let grid = Grid::new(level).unwrap();
        let mut buffer = vec![UnitQuaternion::identity(); count as usize];
        group.bench_function(BenchmarkId::new("fill", format!("level{level}")), |b| {
            b.iter(|| grid.fill_rotations(black_box(&mut buffer)))
        });
    }
    group.finish();
}

fn queries(c: &mut Criterion) {
    let mut group = c.benchmark_group("grid");
    let rotations = random_rotations(100_000, 1);
    group.throughput(Throughput::Elements(rotations.len() as u64));
    for level in [4u8, 5] {
        let grid = Grid::new(level).unwrap();
        grid.nearest(&rotations[0]).unwrap(); // build the search tables outside the timing
        group.bench_function(
            BenchmarkId::new("nearest_100k", format!("level{level}")),
            |b| {
                b.iter(|| {
                    rotations
                        .par_iter()
                        .map(|q| grid.nearest(q).unwrap().0)
                        .max()
                })
            },
        );
        group.bench_function(
            BenchmarkId::new("locate_100k", format!("level{level}")),
            |b| b.iter(|| rotations.par_iter().map(|q| grid.locate(q).unwrap()).max()),
        );
    }
    group.finish();
}

criterion_group!(benches, generate, queries);
criterion_main!(benches);
