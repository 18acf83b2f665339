//! Registration hot paths on the `registration_trials` data: a 5,000-point model (40,000
//! surface samples of a lumpy egg at 5 mm voxels) against a ~3,000-point rendered, noisy
//! partial view. Stages separately (features, FGR, ICP) and the whole `register`; and the
//! neighbour search behind them, kiddo's k-d tree against parry3d's BVH (the alternative it
//! was chosen over). Open3D's time on the same clouds: `benches/python/open3d_registration.py`.
use std::hint::black_box;
use std::num::NonZeroUsize;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Isometry3, Point3};
use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};
use parry3d::query::PointProjection;
use registration::{
    AgreeingScratch, NormalOrientation, PointIndex, PrepareOptions, RegisterOptions, align_fgr,
    compute_fpfh, downsample_voxel, estimate_normals, prepare_cloud, refine_icp, register,
};
use synth_data::trials::{egg_mesh, model_cloud, registration_trials};

const VOXEL: f32 = 0.005;

fn registration(c: &mut Criterion) {
    let mesh = egg_mesh().unwrap();
    let model = model_cloud(&mesh, 40_000, 0).unwrap();
    let trial = registration_trials(&mesh, 1, 0).unwrap().remove(0);
    let model_options =
        PrepareOptions::for_voxel(VOXEL).oriented(NormalOrientation::Consistent { neighbours: 10 });
    let view_options = PrepareOptions::for_voxel(VOXEL)
        .oriented(NormalOrientation::TowardsViewpoint(Point3::origin()));
    let source = prepare_cloud(&model, &model_options).unwrap();
    let target = prepare_cloud(&trial.view, &view_options).unwrap();
    let options = RegisterOptions::for_voxel(VOXEL);
    let label = format!("{}_vs_{}", source.cloud.len(), target.cloud.len());

    let mut group = c.benchmark_group("registration");
    group.sample_size(20);
    group.throughput(Throughput::Elements(source.cloud.len() as u64));
    group.bench_function(format!("features/model_{}", source.cloud.len()), |b| {
        b.iter(|| prepare_cloud(black_box(&model), &model_options).unwrap())
    });
    group.throughput(Throughput::Elements(target.cloud.len() as u64));
    group.bench_function(format!("features/view_{}", target.cloud.len()), |b| {
        b.iter(|| prepare_cloud(black_box(&trial.view), &view_options).unwrap())
    });
    let identity = Isometry3::identity();
    group.bench_function(format!("fgr/{label}"), |b| {
        b.iter(|| align_fgr(black_box(&source), &target, &identity, &options.fgr).unwrap())
    });
    let global = align_fgr(&source, &target, &identity, &options.fgr)
        .unwrap()
        .pose;
    group.bench_function(format!("icp_point_to_plane/{label}"), |b| {
        b.iter(|| {
            refine_icp(
                &source.cloud,
                &target.cloud,
                &target.index,
                black_box(&global),
                &options.icp,
            )
            .unwrap()
        })
    });
    group.bench_function(format!("register/{label}"), |b| {
        b.iter(|| register(black_box(&source), &target, &identity, &options).unwrap())
    });
    group.finish();

    // The preprocessing stages of the view, one by one.
    let mut group = c.benchmark_group("preprocess_view");
    group.sample_size(20);
    let down = downsample_voxel(&trial.view, VOXEL).unwrap();
    let index = PointIndex::from_points(down.points());
    group.throughput(Throughput::Elements(trial.view.len() as u64));
    group.bench_function("downsample", |b| {
        b.iter(|| downsample_voxel(black_box(&trial.view), VOXEL).unwrap())
    });
    group.throughput(Throughput::Elements(down.len() as u64));
    group.bench_function("kd_tree_build", |b| {
        b.iter(|| PointIndex::from_points(black_box(down.points())))
    });
    group.bench_function("normals", |b| {
        b.iter(|| estimate_normals(black_box(&down), &index, &view_options.normals).unwrap())
    });
    let with_normals = estimate_normals(&down, &index, &view_options.normals).unwrap();
    group.bench_function("fpfh", |b| {
        b.iter(|| compute_fpfh(black_box(&with_normals), &index, &view_options.fpfh).unwrap())
    });
    group.finish();
}

/// The downsampled view of a registration trial, and a parry BVH over its points.
fn view_points() -> (Vec<Point3<f32>>, Bvh) {
    let mesh = egg_mesh().unwrap();
    let trial = registration_trials(&mesh, 1, 0).unwrap().remove(0);
    let points = downsample_voxel(&trial.view, VOXEL)
        .unwrap()
        .points()
        .to_vec();
    let leaves: Vec<Aabb> = points.iter().map(|p| Aabb::new(glam(p), glam(p))).collect();
    let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
    (points, bvh)
}

fn glam(p: &Point3<f32>) -> parry3d::math::Vector {
    parry3d::math::Vector::new(p.x, p.y, p.z)
}

/// Radius queries over the view (FPFH: the 100 nearest within 5 voxels).
fn radius_neighbours(c: &mut Criterion) {
    let (points, bvh) = view_points();
    let radius = 5.0 * VOXEL;
    let kiddo = PointIndex::from_points(&points);
    let max = NonZeroUsize::new(100).unwrap();

    let mut group = c.benchmark_group("neighbours");
    group.throughput(Throughput::Elements(points.len() as u64));
    group.bench_function(format!("radius_100/kiddo/{}", points.len()), |b| {
        let mut out = Vec::new();
        b.iter(|| {
            let mut total = 0;
            for p in &points {
                kiddo.nearest_within(&[p.x, p.y, p.z], radius, max, &mut out);
                total += out.len();
            }
            total
        })
    });
    group.bench_function(format!("radius_100/parry_bvh/{}", points.len()), |b| {
        let mut out: Vec<(f32, u32)> = Vec::new();
        b.iter(|| {
            let mut total = 0;
            for p in &points {
                let half = parry3d::math::Vector::splat(radius);
                let query = Aabb::new(glam(p) - half, glam(p) + half);
                out.clear();
                out.extend(bvh.intersect_aabb(&query).filter_map(|i| {
                    let d = (points[i as usize] - p).norm_squared();
                    (d <= radius * radius).then_some((d, i))
                }));
                // The same answer as the k-d tree's: the 100 nearest, sorted.
                out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
                out.truncate(100);
                total += out.len();
            }
            total
        })
    });
    group.finish();
}

/// Nearest-one queries over the view (ICP) and the nearest agreeing point (ICP under a normal
/// test), by kiddo and by the grid that `PointIndex::with_nearest_grid` adds (the model index
/// of labelling's ICP); the nearest one by parry's BVH too.
fn nearest_neighbours(c: &mut Criterion) {
    let (points, bvh) = view_points();
    let kiddo = PointIndex::from_points(&points);
    let mut group = c.benchmark_group("neighbours");
    group.throughput(Throughput::Elements(points.len() as u64));
    let shifted: Vec<Point3<f32>> = points
        .iter()
        .map(|p| p + nalgebra::Vector3::new(0.001, -0.002, 0.001))
        .collect();
    // The nearest point, and the nearest within 1.5 voxels as ICP's refinement asks.
    let grid = PointIndex::with_nearest_grid(&points);
    for (name, index) in [("kiddo", &kiddo), ("grid", &grid)] {
        group.bench_function(format!("nearest/{name}/{}", points.len()), |b| {
            b.iter(|| {
                shifted
                    .iter()
                    .map(|p| index.nearest(&[p.x, p.y, p.z]).unwrap().index)
                    .sum::<u32>()
            })
        });
        group.bench_function(
            format!("nearest_within_1.5_voxels/{name}/{}", points.len()),
            |b| {
                b.iter(|| {
                    shifted
                        .iter()
                        .filter_map(|p| index.nearest_within_radius(&[p.x, p.y, p.z], 1.5 * VOXEL))
                        .count()
                })
            },
        );
        // ICP's correspondence under a normal test where the nearest point disagrees: here
        // one point in four agrees.
        group.bench_function(
            format!("nearest_agreeing_1.5_voxels/{name}/{}", points.len()),
            |b| {
                let mut scratch = AgreeingScratch::default();
                let eight = NonZeroUsize::new(8).expect("not zero");
                b.iter(|| {
                    shifted
                        .iter()
                        .filter_map(|p| {
                            let query = [p.x, p.y, p.z];
                            let agrees = |i: u32| i.is_multiple_of(4);
                            index.nearest_agreeing(&query, 1.5 * VOXEL, eight, agrees, &mut scratch)
                        })
                        .count()
                })
            },
        );
    }
    group.bench_function(format!("nearest/parry_bvh/{}", points.len()), |b| {
        b.iter(|| {
            shifted
                .iter()
                .map(|p| {
                    let q = glam(p);
                    let found = bvh.project_point(q, f32::MAX, |i, _| {
                        Some(PointProjection::new(false, glam(&points[i as usize])))
                    });
                    found.map_or(0, |(i, _)| i)
                })
                .sum::<u32>()
        })
    });
    group.finish();
}

criterion_group!(benches, registration, radius_neighbours, nearest_neighbours);
criterion_main!(benches);
