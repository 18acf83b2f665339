//! Render a mesh: the can at a pose seen by a 640 × 480 camera, into BOP-style depth, RGB and
//! mask PNGs (with a symmetry-breaking texture).
//!
//! ```text
//! cargo run --release -p ipdf --example render_mesh -- runs/examples
//! ```
use std::path::PathBuf;

use anyhow::Result;
use bop_dataset::{write_depth, write_mask, write_rgb};
use depth_render::{Instance, Lighting, Material, Primitive, Scene, Window};
use nalgebra::{Isometry3, Vector3};
use synth_data::SynthOptions;

fn main() -> Result<()> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or("runs/examples".into()));
    let can = Primitive::Cylinder {
        radius: 0.051,
        height: 0.14,
        segments: 96,
    };
    let camera = SynthOptions::t_less_camera().camera; // or depth_render::PinholeCamera::new(…)
    let scene = Scene::new(&[can.mesh()?]); // one BVH per mesh, built once
    // Model→camera: tilted 60° about x, 0.7 m in front of the camera.
    let pose = Isometry3::new(
        Vector3::new(0.0, 0.0, 0.7),
        Vector3::x() * 60f64.to_radians(),
    );
    let instances = [Instance::new(0, pose)];
    let rendering = scene.render(&camera, &instances, Window::full(&camera))?;
    let texture = Material::Patches {
        cell: 0.02,
        seed: 1,
    };
    let rgb = scene.shade(
        &camera,
        &instances,
        &[texture],
        &Lighting::default(),
        &rendering,
    )?;
    let mask: Vec<bool> = rendering.instance.iter().map(Option::is_some).collect();
    let (width, height) = (camera.width, camera.height);
    write_depth(
        &out.join("can_depth.png"),
        &rendering.depth,
        width,
        height,
        0.1,
    )?;
    write_rgb(&out.join("can_rgb.png"), &rgb, width, height)?;
    write_mask(&out.join("can_mask.png"), &mask, width, height)?;
    let pixels = mask.iter().filter(|m| **m).count();
    println!(
        "{pixels} pixels of can; wrote can_{{depth,rgb,mask}}.png in {}",
        out.display()
    );
    Ok(())
}
