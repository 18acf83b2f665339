//! Tiny synthetic renders for the model tests: a flat-coloured cube under Lambert shading,
//! whose images are identical under its 24 proper symmetries; and a run trained through and the
//! same run interrupted and resumed, for the checkpoint tests of either model.
#![allow(dead_code)]

use std::path::Path;

use depth_render::{Instance, Lighting, Material, PinholeCamera, Primitive, Scene, Window};
use ipdf_metrics::SymmetryGroup;
use ipdf_model::{
    CropOptions, EpochReport, FitOptions, FitTarget, ModelError, crop_object, crops_to_tensor, fit,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tch::Tensor;

/// Crops `[N, 3, size, size]` of a cube at `count` orientations, with those orientations and
/// the cube's symmetry group. The orientations are a fixed generic tilt turned by a uniform
/// random angle about the camera's optical axis: a one-parameter family in which every image
/// shows one orientation up to the cube's symmetries, small enough to learn in seconds.
pub struct CubeRenders {
    pub images: Tensor,
    pub poses: Vec<UnitQuaternion<f64>>,
    pub group: SymmetryGroup,
}

/// The colour image (RGB bytes, row-major) and the mask (1 on the object) of `scene`'s first
/// mesh, flat orange under the default lighting, at `pose` in `camera`'s frame.
pub fn render_cube(
    scene: &Scene,
    camera: &PinholeCamera,
    pose: Isometry3<f64>,
) -> (Vec<u8>, Vec<u8>) {
    let instances = [Instance::new(0, pose)];
    let rendering = scene
        .render(camera, &instances, Window::full(camera))
        .unwrap();
    let rgb = scene
        .shade(
            camera,
            &instances,
            &[Material::Uniform([0.9, 0.6, 0.2])],
            &Lighting::default(),
            &rendering,
        )
        .unwrap()
        .concat();
    let mask = rendering
        .instance
        .iter()
        .map(|hit| u8::from(hit.is_some()))
        .collect();
    (rgb, mask)
}

pub fn cube_renders(count: usize, seed: u64, size: usize) -> CubeRenders {
    let cube = Primitive::Cuboid { extents: [0.1; 3] };
    let scene = Scene::new(&[cube.mesh().unwrap()]);
    let camera = PinholeCamera::new(150.0, 150.0, 32.0, 32.0, 64, 64).unwrap();
    let tilt = UnitQuaternion::from_euler_angles(0.5, 0.3, 0.2);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let poses: Vec<UnitQuaternion<f64>> = (0..count)
        .map(|_| {
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle) * tilt
        })
        .collect();
    let crops: Vec<Vec<f32>> = poses
        .iter()
        .map(|rotation| {
            let pose = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), *rotation);
            let (rgb, mask) = render_cube(&scene, &camera, pose);
            crop_object(&rgb, &mask, 64, 64, &CropOptions::new(size)).unwrap()
        })
        .collect();
    CubeRenders {
        images: crops_to_tensor(&crops, size).unwrap(),
        poses,
        group: {
            let shape = cube.symmetry().unwrap();
            ipdf_metrics::SymmetryGroup::about_origin(&shape.discrete, &shape.continuous)
        },
    }
}

/// A run of two epochs on `data` (validated on it) into `whole`, and the same run interrupted:
/// one epoch into `split`, dropped, resumed from there (`resume`) after `first_steps` steps and
/// trained to the end of the second epoch. `fresh` starts a trainer, `fit_options` has the
/// epochs given. Returns the uninterrupted trainer, its epochs' reports, and the resumed one.
pub fn uninterrupted_and_resumed<T: FitTarget>(
    fresh: impl Fn() -> T,
    resume: impl Fn(&Path) -> Result<T, ModelError>,
    data: &T::Data,
    fit_options: impl Fn(u64) -> FitOptions,
    first_steps: u64,
    (whole, split): (&Path, &Path),
) -> (T, Vec<EpochReport>, T) {
    let mut trainer = fresh();
    let reports = fit(
        &mut trainer,
        data,
        Some(data),
        &fit_options(2),
        whole,
        |_| {},
    )
    .unwrap();
    let mut first = fresh();
    fit(&mut first, data, None, &fit_options(1), split, |_| {}).unwrap();
    drop(first);
    let mut resumed = resume(split).unwrap();
    assert_eq!(resumed.steps_done(), first_steps);
    fit(&mut resumed, data, None, &fit_options(2), split, |_| {}).unwrap();
    (trainer, reports, resumed)
}
