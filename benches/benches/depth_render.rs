//! depth-render hot paths: BVH build of a ~100k-triangle mesh, a 640×480 depth render of an
//! object at 0.7 m, and a 100×100 window of it (render-and-compare's unit). The baseline is
//! obvhs' own compressed-wide BVH traversal, one ray per pixel (its flagship CPU path).
//!
//! Group `sensor`: the sensor presets' readings of a 640×480 frame (an object on a table, every
//! pixel rendered), against rendering that frame's depth in the same run.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use depth_render::{DepthSensor, Instance, PinholeCamera, Scene, TriangleMesh, Window, primitives};
use glam::Vec3A;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use rayon::prelude::*;
use std::hint::black_box;

/// One ray per pixel through an obvhs CWBVH, rows in parallel: the baseline.
struct CwBaseline {
    bvh: CwBvh,
    triangles: Vec<Triangle>,
}

impl CwBaseline {
    fn new(mesh: &TriangleMesh) -> Self {
        let triangles: Vec<Triangle> = (0..mesh.triangles().len())
            .map(|t| {
                let [v0, v1, v2] = mesh.corners(t).map(|p| Vec3A::new(p.x, p.y, p.z));
                Triangle { v0, v1, v2 }
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &triangles,
            BvhBuildParams::medium_build(),
            &mut Default::default(),
        );
        let triangles = bvh
            .primitive_indices
            .iter()
            .map(|&i| triangles[i as usize])
            .collect();
        Self { bvh, triangles }
    }

    fn render(&self, camera: &PinholeCamera, pose: &Isometry3<f64>, window: Window) -> Vec<f32> {
        let model_from_camera = pose.inverse();
        let o = model_from_camera * Point3::origin();
        let origin = Vec3A::new(o.x as f32, o.y as f32, o.z as f32);
        let rotation = model_from_camera.rotation.to_rotation_matrix().into_inner();
        let width = window.width() as usize;
        let mut depth = vec![0.0f32; width * window.height() as usize];
        depth
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(row, out)| {
                for (column, d) in out.iter_mut().enumerate() {
                    let [x, y, z] = camera.ray_direction(
                        f64::from(window.u0) + column as f64,
                        f64::from(window.v0) + row as f64,
                    );
                    let local = rotation * nalgebra::Vector3::new(x, y, z);
                    let direction = Vec3A::new(local.x as f32, local.y as f32, local.z as f32);
                    let mut hit = RayHit::none();
                    let ray = Ray::new(origin, direction, 0.0, f32::INFINITY);
                    if self
                        .bvh
                        .ray_traverse(ray, &mut hit, |r, i| self.triangles[i].intersect(r))
                    {
                        *d = hit.t;
                    }
                }
            });
        depth
    }
}

fn rendering(c: &mut Criterion) {
    let mut group = c.benchmark_group("render");
    let big = primitives::sphere(0.1, 6).unwrap(); // 81,920 triangles
    group.throughput(Throughput::Elements(big.triangles().len() as u64));
    group.bench_function("bvh_build/82k_triangles", |b| {
        b.iter(|| Scene::new(black_box(std::slice::from_ref(&big))))
    });
    group.bench_function("bvh_build/82k_triangles/obvhs_cwbvh_baseline", |b| {
        b.iter(|| CwBaseline::new(black_box(&big)))
    });
    let huge = primitives::sphere(0.1, 7).unwrap(); // 327,680 triangles
    group.throughput(Throughput::Elements(huge.triangles().len() as u64));
    group.bench_function("bvh_build/328k_triangles", |b| {
        b.iter(|| Scene::new(black_box(std::slice::from_ref(&huge))))
    });

    // T-LESS-like intrinsics; a 20k-triangle sphere of 0.1 m radius at 0.7 m fills ~1/4 of the
    // image.
    let camera = PinholeCamera::new(1075.65, 1073.90, 320.0, 240.0, 640, 480).unwrap();
    let object = primitives::sphere(0.1, 5).unwrap(); // 20,480 triangles
    let baseline = CwBaseline::new(&object);
    let scene = Scene::new(std::slice::from_ref(&object));
    let pose = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.7),
        UnitQuaternion::from_euler_angles(0.2, 0.4, 0.1),
    );
    let instances = [Instance::new(0, pose)];
    let roi = Window {
        u0: 270,
        v0: 190,
        u1: 370,
        v1: 290,
    };
    for (name, window) in [
        ("640x480_20k_triangles", Window::full(&camera)),
        ("roi_100x100", roi),
    ] {
        group.throughput(Throughput::Elements(u64::from(
            window.width() * window.height(),
        )));
        group.bench_function(format!("depth/{name}"), |b| {
            b.iter(|| {
                scene
                    .render(&camera, black_box(&instances), window)
                    .unwrap()
            })
        });
        group.bench_function(format!("depth/{name}/obvhs_cwbvh_baseline"), |b| {
            b.iter(|| baseline.render(&camera, black_box(&pose), window))
        });
    }
    group.finish();
}

fn sensor(c: &mut Criterion) {
    let mut group = c.benchmark_group("sensor");
    let camera = PinholeCamera::new(1075.65, 1073.90, 320.0, 240.0, 640, 480).unwrap();
    let meshes = [
        primitives::sphere(0.1, 5).unwrap(),
        primitives::plane(1.2, 1.2).unwrap(),
    ];
    let scene = Scene::new(&meshes);
    // The camera 0.8 m from the table, looking down at 40° from the vertical.
    let tilt = UnitQuaternion::from_euler_angles(-0.7, 0.0, 0.0);
    let table = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.8), tilt);
    let ball = table * Translation3::new(0.0, 0.0, 0.1);
    let instances = [Instance::new(0, ball), Instance::new(1, table)];
    let window = Window::full(&camera);
    let depth = scene.render(&camera, &instances, window).unwrap().depth;
    group.throughput(Throughput::Elements(depth.len() as u64));
    group.bench_function("640x480/render_baseline", |b| {
        b.iter(|| {
            scene
                .render(&camera, black_box(&instances), window)
                .unwrap()
        })
    });
    for (name, preset) in [
        ("kinect", DepthSensor::kinect()),
        ("realsense", DepthSensor::realsense()),
    ] {
        group.bench_function(format!("640x480/{name}"), |b| {
            b.iter(|| preset.apply(black_box(&depth), &camera, 7))
        });
    }
    group.finish();
}

criterion_group!(benches, rendering, sensor);
criterion_main!(benches);
