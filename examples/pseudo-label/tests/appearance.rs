//! Telling apart by colour the poses that depth cannot (`pseudo_label::appearance_match`,
//! `LabelOptions::appearance_margin`), on the real scan of YCB's pudding box with its own
//! texture (`tests/data/ycbv_real`, see its `SOURCES.md`): a box whose half turns fit its depth
//! and whose print does not.
use std::path::{Path, PathBuf};

use bop_dataset::mesh_appearance;
use depth_render::{
    DepthSensor, Instance, Lighting, MaskErrors, Material, PinholeCamera, Scene, TriangleMesh,
    Window, load_mesh,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use pseudo_label::{
    APPEARANCE_MARGIN, LabelOptions, ObjectModel, Observation, appearance_match, label_instance,
};
use rand::SeedableRng;
use synth_data::{FrameRenderer, FrameStyle, Randomization, SynthOptions, ViewRange};

fn pudding_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ycbv_real/models/obj_000007.ply")
}

/// The pudding box's mesh and its texture.
fn pudding() -> (TriangleMesh, Material) {
    let path = pudding_path();
    let loaded = load_mesh(&path, 0.001).unwrap();
    let appearance = mesh_appearance(&path, &loaded).unwrap().unwrap();
    assert!(matches!(appearance, Material::Image(_)));
    (loaded.mesh, appearance)
}

/// The pudding box prepared for labelling, with its texture and without: built once.
fn models() -> &'static (ObjectModel, ObjectModel) {
    static MODELS: std::sync::OnceLock<(ObjectModel, ObjectModel)> = std::sync::OnceLock::new();
    MODELS.get_or_init(|| {
        let (mesh, appearance) = pudding();
        let grey = ObjectModel::new(7, &mesh, &LabelOptions::default()).unwrap();
        let textured = ObjectModel::new(7, &mesh, &LabelOptions::default())
            .unwrap()
            .with_appearance(Some(appearance));
        (textured, grey)
    })
}

fn camera() -> PinholeCamera {
    PinholeCamera::new(600.0, 600.0, 160.0, 120.0, 320, 240).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// Where the observed colours are the surface's own colours under any exposure and white
    /// balance (each channel `gain · albedo + offset`), the pose they were rendered at matches
    /// them perfectly: the match is a correlation, blind to gain and offset.
    #[test]
    fn the_rendered_pose_matches_its_own_colours_under_any_exposure(
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in 0.0f64..std::f64::consts::PI,
        gain in 0.3f64..1.0,
        offsets in prop::array::uniform3(0.0f64..60.0),
    ) {
        let axis = Vector3::from(axis);
        prop_assume!(axis.norm() > 0.1);
        let (mesh, appearance) = pudding();
        let camera = camera();
        let rotation = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
        let pose = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), rotation);
        let scene = Scene::new(std::slice::from_ref(&mesh));
        let instances = [Instance::new(0, pose)];
        let rendering = scene.render(&camera, &instances, Window::full(&camera)).unwrap();
        let unlit = Lighting { ambient: 1.0, diffuse: 0.0, ..Lighting::default() };
        let albedo = scene
            .shade(&camera, &instances, std::slice::from_ref(&appearance), &unlit, &rendering)
            .unwrap();
        let colour: Vec<[u8; 3]> = albedo
            .iter()
            .map(|c| std::array::from_fn(|k| (gain * f64::from(c[k]) + offsets[k]).round() as u8))
            .collect();
        let mask: Vec<bool> = rendering.instance.iter().map(Option::is_some).collect();
        let observation = Observation::new(camera, &rendering.depth, &mask)
            .unwrap()
            .with_colour(&colour);
        let (model, grey) = models();
        let matched = appearance_match(model, &observation, &pose).unwrap();
        prop_assert!(matched > 0.99, "{matched}");
        // Without the image's colour, or a mesh without colours, there is nothing to match.
        prop_assert!(appearance_match(grey, &observation, &pose).is_none());
        let depth_only = Observation::new(camera, &rendering.depth, &mask).unwrap();
        prop_assert!(appearance_match(model, &depth_only, &pose).is_none());
    }
}

/// On randomised renders of the textured scan (lights, tints, backgrounds, distractors,
/// occluders, the colour camera's chain, Kinect depth), the labels found from depth hold the
/// box's half turns beside the rendered pose; with the colours, the rendered pose stays and
/// most of its look-alikes go (the oracle: the pose each frame was rendered at).
#[test]
fn the_print_drops_a_boxs_half_turns_from_its_labels_and_keeps_its_pose() {
    let (mesh, appearance) = pudding();
    let camera = SynthOptions::default().camera.camera;
    let style = FrameStyle {
        distractors: 2,
        occluders: 1,
        sensor: Some(DepthSensor::kinect()),
        mask_errors: Some(MaskErrors::default()),
        randomization: Randomization::ALL,
        ..FrameStyle::plain(appearance)
    };
    let renderer = FrameRenderer::new(&mesh).unwrap();
    let off = LabelOptions::default();
    let on = LabelOptions {
        appearance_margin: APPEARANCE_MARGIN,
        ..LabelOptions::default()
    };
    let model = &models().0;
    let near = |labels: &[bop_dataset::PseudoLabel], pose: &Isometry3<f64>| {
        let angles: Vec<f64> = labels
            .iter()
            .map(|l| l.pose.rotation.angle_to(&pose.rotation).to_degrees())
            .collect();
        let near = angles.iter().filter(|&&a| a < 5.0).count();
        (near, angles.len() - near)
    };
    let (mut kept, mut truths, mut far_without, mut far_with) = (0, 0, 0, 0);
    for seed in 0..8u64 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let frame = renderer
            .render(&camera, &ViewRange::default(), &style, &mut rng)
            .unwrap();
        let Some(observation) = Observation::new(camera, &frame.depth, &frame.mask_visib) else {
            continue;
        };
        let observation = observation.with_colour(&frame.rgb);
        let without = label_instance(model, &observation, &off, seed).labels;
        let with = label_instance(model, &observation, &on, seed).labels;
        let (Ok(without), Ok(with)) = (without, with) else {
            continue;
        };
        let (near_without, far) = near(&without, &frame.pose);
        let (near_with, far_kept) = near(&with, &frame.pose);
        eprintln!("frame {seed}: {near_without} + {far} labels → {near_with} + {far_kept}");
        // The colours only drop labels.
        assert!(with.len() <= without.len());
        if near_without > 0 {
            truths += 1;
            kept += usize::from(near_with > 0);
        }
        far_without += far;
        far_with += far_kept;
    }
    assert!(
        truths >= 6,
        "{truths} of 8 frames labelled with a true pose"
    );
    // On 341 such frames, the true pose was dropped in 4% of them.
    assert!(
        kept + 1 >= truths,
        "the true pose kept in {kept} of {truths} frames"
    );
    assert!(
        far_without >= truths,
        "{far_without} look-alikes without the colours"
    );
    assert!(
        2 * far_with <= far_without,
        "{far_with} of {far_without} look-alikes kept"
    );
}
