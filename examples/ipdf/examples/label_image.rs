//! Label one image: the pseudo ground-truth pose set of a cracker box seen in a rendered RGB-D
//! frame, from its depth, its mask and its mesh alone, and each label's distance to the nearest
//! truly symmetric pose.
//!
//! ```text
//! cargo run --release -p ipdf --example label_image
//! ```
use anyhow::{Context, Result};
use depth_render::{DepthSensor, MaskErrors, Material};
use pseudo_label::{LabelOptions, ObjectModel, Observation, label_instance};
use rand::SeedableRng;
use synth_data::{FrameRenderer, FrameStyle, ObjectKind, SynthObject, SynthOptions, ViewRange};

fn main() -> Result<()> {
    // A frame of the box on a table; with a dataset, read its depth and mask_visib PNGs instead
    // (`bop_dataset::read_depth`, `read_mask`).
    let object = SynthObject::built_in(ObjectKind::Box)?;
    let camera = SynthOptions::t_less_camera().camera;
    let style = FrameStyle {
        distractors: 2,
        sensor: Some(DepthSensor::kinect()),
        mask_errors: Some(MaskErrors::default()),
        ..FrameStyle::plain(Material::Uniform(object.colour))
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let frame = FrameRenderer::new(&object.mesh)?.render(
        &camera,
        &ViewRange::default(),
        &style,
        &mut rng,
    )?;

    let options = LabelOptions::default();
    let model = ObjectModel::new(1, &object.mesh, &options)?; // once per object
    println!(
        "the mesh has {} self-symmetries (identity included)",
        model.symmetries.len()
    );
    let observation =
        Observation::new(camera, &frame.depth, &frame.mask_visib).context("the box is hidden")?;
    let labels = label_instance(&model, &observation, &options, 0).labels?;
    for label in &labels {
        let errors = object
            .symmetry
            .class_distances(&frame.pose.rotation, &label.pose.rotation);
        let error = errors.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        println!(
            "label: score {:.2} mm, {:.2}° from a symmetric pose",
            label.score * 1e3,
            error.to_degrees()
        );
    }
    Ok(())
}
