//! depth-render hot paths: BVH build of a 100k-triangle mesh, a 640×480 depth render of a
//! ~10k-triangle object at 0.7 m, and a 100×100 window of it (render-and-compare's unit).
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use depth_render::{Instance, PinholeCamera, Scene, Window, primitives};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::hint::black_box;

fn rendering(c: &mut Criterion) {
    let mut group = c.benchmark_group("render");
    let big = primitives::sphere(0.1, 6).unwrap(); // 81,920 triangles
    let huge = primitives::sphere(0.1, 7).unwrap(); // 327,680 triangles
    group.throughput(Throughput::Elements(big.triangles().len() as u64));
    group.bench_function("bvh_build/82k_triangles", |b| {
        b.iter(|| Scene::new(black_box(std::slice::from_ref(&big))))
    });
    group.throughput(Throughput::Elements(huge.triangles().len() as u64));
    group.bench_function("bvh_build/328k_triangles", |b| {
        b.iter(|| Scene::new(black_box(std::slice::from_ref(&huge))))
    });

    // T-LESS-like intrinsics; a 20k-triangle sphere of 0.1 m radius at 0.7 m fills ~1/6 of the image.
    let camera = PinholeCamera::new(1075.65, 1073.90, 320.0, 240.0, 640, 480).unwrap();
    let object = primitives::sphere(0.1, 5).unwrap(); // 20,480 triangles
    let scene = Scene::new(&[object]);
    let pose = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.7),
        UnitQuaternion::from_euler_angles(0.2, 0.4, 0.1),
    );
    let instances = [Instance::new(0, pose)];
    group.throughput(Throughput::Elements(640 * 480));
    group.bench_function("depth/640x480_20k_triangles", |b| {
        b.iter(|| {
            scene
                .render(&camera, black_box(&instances), Window::full(&camera))
                .unwrap()
        })
    });
    let window = Window {
        u0: 270,
        v0: 190,
        u1: 370,
        v1: 290,
    };
    group.throughput(Throughput::Elements(100 * 100));
    group.bench_function("depth/roi_100x100", |b| {
        b.iter(|| {
            scene
                .render(&camera, black_box(&instances), window)
                .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, rendering);
criterion_main!(benches);
