//! Real frames: three YCB-Video frames (Asus Xtion, structured light) with their ground-truth
//! poses and the objects' real scans, as a BOP dataset (`tests/data/ycbv_real`; sources,
//! licences and how the meshes were put in the dataset's frame in its `SOURCES.md`), labelled
//! by [`pseudo_label::label_dataset`] with the default options (the Kinect preset, which
//! stands for the Xtion too) and scored against the ground truth three ways: the angle and the
//! centre's distance to the nearest pose of the ground truth expanded by the object's
//! geometric symmetries; BOP's Visible Surface Discrepancy, under which poses the view cannot
//! tell apart (a mug with its handle hidden, turned about its axis) are the same; and ADD(-S),
//! ADD-S for the objects BOP evaluates as symmetric.
use crate::common;

use std::path::{Path, PathBuf};

use bop_dataset::{
    BopDataset, ModelInfo, read_depth, read_models_info, read_pseudo_gt, read_scene_camera,
    read_scene_gt,
};
use common::{copy_dir, label_split};
use depth_render::{
    Instance, Scene, Window, load_mesh, sample_surface, visible_surface_discrepancy,
};
use ipdf_metrics::{ModelPoints, add, add_s};
use nalgebra::{Isometry3, Point3, Vector3};
use pseudo_label::LabelOptions;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ycbv_real")
}

/// The YCB-Video objects BOP evaluates as symmetric, with ADD-S (`symmetric_obj_ids` of
/// `ycbv` in `bop_toolkit_lib/dataset_params.py`): the can, the bowl, the mug, the wood block,
/// the marker, the two clamps and the foam brick.
const BOP_SYMMETRIC: [u32; 8] = [1, 13, 14, 16, 18, 19, 20, 21];

/// Best labels a correct labeller must get right by ADD(-S), BOP's criterion (under 10% of the
/// diameter): all 11 but three it cannot. The cracker box, whose scan is not symmetric but
/// whose view is: its pose turned over explains the depth better than the truth (scores 0.74
/// against 0.86), so the best label is the turned one, 168 mm off by ADD. The sugar box,
/// whose ground truth is off: it explains 81% of the box's depth within 5 mm, each label 99%,
/// and the labels lie 22 mm from it, more than 10% of its diameter (19.9 mm). The first
/// mustard bottle, whose 180° turn about its axis is a symmetry of the scan at the sensor's
/// resolution (`SOURCES.md`) but not in BOP's evaluation with ADD: either pose may come first.
/// The mug's and the foam brick's turned poses count as correct: BOP evaluates them with
/// ADD-S. See the real-frame table of docs/results.md.
const ADD_CORRECT: usize = 8;

/// Best labels a correct labeller must place within 5° and 10 mm of a true pose of the
/// geometric symmetry group: all 11 but four where the view, not the labeller, decides. The
/// mug with its handle hidden (any turn about its axis looks the same, so the best label is
/// one of them), the foam brick (the scan is not symmetric, but its square section is: the
/// turned pose looks the same), the cracker box (turned over, preferred by the depth) and the
/// sugar box (its ground truth is off by 22 mm).
const BEST_NEAR: usize = 7;

/// Label sets a correct labeller must make hold a pose within 5° and 10 mm: all 11 but three.
/// The mug (its labels sample the turns about its axis; nothing makes one fall within 5° of
/// the hidden truth), the cracker box (the truth scores 0.12 worse than the turned pose, more
/// than the 0.1 margin, so it is not a label) and the sugar box (ground truth off). The foam
/// brick's set holds both of its look-alike poses.
const ANY_NEAR: usize = 8;

/// One label's errors against the ground truth.
#[derive(Debug, Clone, Copy)]
struct Errors {
    /// Angle to the nearest ground-truth symmetric rotation (degrees).
    angle: f64,
    /// Distance of the bounding box's centre from its true position (mm).
    offset: f64,
    /// BOP's VSD against the ground-truth pose (δ 15 mm, τ 20 mm).
    vsd: f32,
    /// ADD, or ADD-S for [`BOP_SYMMETRIC`] objects (mm), over 2,000 surface points.
    add: f64,
    /// 10% of the object's diameter (mm): the classic ADD(-S) threshold.
    add_threshold: f64,
}

impl Errors {
    fn of(
        label: &Isometry3<f64>,
        truth: &Isometry3<f64>,
        info: &ModelInfo,
        vsd: f32,
        (points, symmetric): (&ModelPoints, bool),
    ) -> Self {
        // The bounding box's centre lies on every symmetry axis: the same point in each
        // symmetric pose.
        let (min, size) = (info.min.unwrap(), info.size.unwrap());
        let centre = Point3::from((Vector3::from(min) + Vector3::from(size) / 2.0) / 1000.0);
        let angle = info
            .symmetry
            .class_distances(&truth.rotation, &label.rotation)
            .into_iter()
            .fold(f64::INFINITY, f64::min)
            .to_degrees();
        let distance = if symmetric { add_s } else { add };
        Self {
            angle,
            offset: 1000.0 * (label * centre - truth * centre).norm(),
            vsd,
            add: 1000.0 * distance(points, label, truth),
            add_threshold: 0.1 * info.diameter,
        }
    }

    /// Within 5° and 10 mm of a true symmetric pose.
    fn near_a_symmetric_pose(&self) -> bool {
        self.angle < 5.0 && self.offset < 10.0
    }

    /// Correct by BOP 2018's VSD criterion.
    fn same_visible_surface(&self) -> bool {
        self.vsd < 0.3
    }

    /// Correct by the ADD(-S) criterion: under 10% of the diameter.
    fn add_correct(&self) -> bool {
        self.add < self.add_threshold
    }
}

/// One instance: its scene and object, whether the image's border cuts it, and the errors of
/// each of its labels, best first.
#[derive(Debug)]
struct Scored {
    scene: u32,
    obj_id: u32,
    truncated: bool,
    errors: Vec<Errors>,
    warning: Option<String>,
}

/// Whether a rendering of the whole image (`width` columns) reaches the image's border.
fn touches_border(depth: &[f32], width: usize) -> bool {
    let height = depth.len() / width;
    depth.iter().enumerate().any(|(i, &z)| {
        let (u, v) = (i % width, i / width);
        z > 0.0 && (u == 0 || v == 0 || u == width - 1 || v == height - 1)
    })
}

fn label_and_score(root: &Path, options: &LabelOptions) -> Vec<Scored> {
    let dataset = BopDataset::open(root, "models").unwrap();
    let summary = label_split(&dataset, "test", options).unwrap();
    assert!(summary.failures.is_empty(), "{summary:?}");
    assert_eq!((summary.images, summary.instances), (3, 11), "{summary:?}");
    let models = read_models_info(&dataset.models_info_path()).unwrap();
    let mut scored = Vec::new();
    for scene_id in [0u32, 1, 2] {
        let scene = dataset.scene("test", scene_id);
        let truth = read_scene_gt(&scene.gt_path()).unwrap();
        let labels = read_pseudo_gt(&scene.pseudo_gt_path()).unwrap();
        let cameras = read_scene_camera(&scene.camera_path()).unwrap();
        for (im_id, instances) in &truth {
            let intrinsics = &cameras[im_id];
            let depth = read_depth(&scene.depth_path(*im_id), intrinsics.depth_scale).unwrap();
            let camera = intrinsics.camera(depth.width, depth.height).unwrap().camera;
            assert_eq!(labels[im_id].len(), instances.len(), "scene {scene_id}");
            for (gt, found) in instances.iter().zip(&labels[im_id]) {
                assert!(found.error.is_none(), "scene {scene_id}: {found:?}");
                let mesh = load_mesh(&dataset.model_path(gt.obj_id), 0.001)
                    .unwrap()
                    .mesh;
                let scene = Scene::new(std::slice::from_ref(&mesh));
                let render = |pose: &Isometry3<f64>| {
                    let window = Window::full(&camera);
                    scene
                        .render(&camera, &[Instance::new(0, *pose)], window)
                        .unwrap()
                        .depth
                };
                let truth_depth = render(&gt.pose);
                let info = &models[&gt.obj_id];
                let (samples, _) = sample_surface(&mesh, 2_000, u64::from(gt.obj_id));
                let samples: Vec<Point3<f64>> = samples.iter().map(|p| p.cast()).collect();
                let points = ModelPoints::new(&samples).unwrap();
                let symmetric = BOP_SYMMETRIC.contains(&gt.obj_id);
                let errors = found
                    .labels
                    .iter()
                    .map(|label| {
                        let vsd = visible_surface_discrepancy(
                            &depth.pixels,
                            &render(&label.pose),
                            &truth_depth,
                            0.015,
                            0.02,
                        )
                        .unwrap();
                        Errors::of(&label.pose, &gt.pose, info, vsd, (&points, symmetric))
                    })
                    .collect();
                scored.push(Scored {
                    scene: scene_id,
                    obj_id: gt.obj_id,
                    truncated: touches_border(&truth_depth, camera.width as usize),
                    errors,
                    warning: found.warning.clone(),
                });
            }
        }
    }
    scored
}

#[test]
fn real_frames_are_all_labelled_and_their_labels_show_the_true_surface() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("ycbv");
    copy_dir(&fixture(), &root);
    let scored = label_and_score(&root, &LabelOptions::default());
    for instance in &scored {
        eprintln!(
            "scene {}, object {}: {} labels, best first:",
            instance.scene,
            instance.obj_id,
            instance.errors.len()
        );
        for e in &instance.errors {
            eprintln!(
                "    {:.1}°, {:.1} mm, VSD {:.3}, ADD(-S) {:.1} mm (10%: {:.1})",
                e.angle, e.offset, e.vsd, e.add, e.add_threshold
            );
        }
    }
    assert_eq!(scored.len(), 11);
    // The can and the sugar box of scene 1 run out of the image at its lower edge: how far they
    // reach, the depth cannot say (the sugar box's labels are all 22 mm off).
    let truncated: Vec<_> = scored
        .iter()
        .filter(|s| s.truncated)
        .map(|s| (s.scene, s.obj_id))
        .collect();
    assert_eq!(truncated, [(1, 1), (1, 3)]);
    // Every label is a true pose or one the view cannot tell from it (a mug whose handle is
    // hidden, a foam brick turned over).
    for instance in scored.iter().filter(|s| !s.truncated) {
        for label in &instance.errors {
            assert!(
                label.near_a_symmetric_pose() || label.same_visible_surface(),
                "{instance:?}"
            );
        }
    }
    // Where the view leaves no ambiguity, the best label is a true pose; where it does, the
    // set holds one more often than not.
    let best = scored
        .iter()
        .filter(|s| s.errors[0].near_a_symmetric_pose())
        .count();
    assert!(
        best >= BEST_NEAR,
        "{best} of 11 best labels within 5° and 10 mm"
    );
    let any = scored
        .iter()
        .filter(|s| s.errors.iter().any(Errors::near_a_symmetric_pose))
        .count();
    assert!(
        any >= ANY_NEAR,
        "{any} of 11 label sets hold a pose within 5° and 10 mm"
    );
    // BOP's ADD(-S) criterion on the best label, and on any label of the set.
    let add = scored.iter().filter(|s| s.errors[0].add_correct()).count();
    let add_any = scored
        .iter()
        .filter(|s| s.errors.iter().any(Errors::add_correct))
        .count();
    eprintln!(
        "{add} of 11 best labels and {add_any} of 11 sets under 10% of the diameter by ADD(-S)"
    );
    assert!(
        add >= ADD_CORRECT,
        "{add} of 11 best labels correct by ADD(-S)"
    );
}

/// The real frames' colours drop the look-alike poses that their depth cannot tell apart and
/// that the print can, and nothing else: labelled with the colours and without (the same seeds),
/// every set keeps its poses near the truth, and the sugar box's and pudding box's sets, which
/// hold their half turns without the colours, hold none with them. The published rotation is
/// the oracle; poses counted near it are near a pose of its geometric symmetry group, half
/// turns those over 90° from every such pose. Scene 0's colour image is made unreadable: its
/// (coloured) instances keep their depth-only labels and each warns of it, naming the image.
#[test]
fn real_colours_drop_the_half_turns_of_printed_boxes_and_keep_their_poses() {
    let dir = tempfile::tempdir().unwrap();
    let unreadable = Path::new("test/000000/rgb/000001.jpg");
    let label = |name: &str, margin: f64| {
        let root = dir.path().join(name);
        copy_dir(&fixture(), &root);
        if margin > 0.0 {
            std::fs::write(root.join(unreadable), b"not a JPEG").unwrap();
        }
        let options = LabelOptions {
            appearance_margin: margin,
            ..LabelOptions::default()
        };
        label_and_score(&root, &options)
    };
    let without = label("depth", 0.0);
    let with = label("colour", pseudo_label::APPEARANCE_MARGIN);
    let half_turns = |s: &Scored| s.errors.iter().filter(|e| e.angle > 90.0).count();
    for (before, after) in without.iter().zip(&with) {
        eprintln!(
            "scene {}, object {}: {} labels, {} half turns → {} labels, {} half turns",
            before.scene,
            before.obj_id,
            before.errors.len(),
            half_turns(before),
            after.errors.len(),
            half_turns(after)
        );
        assert!(after.errors.len() <= before.errors.len());
        let near = |s: &Scored| s.errors.iter().any(Errors::near_a_symmetric_pose);
        assert!(near(after) || !near(before), "{after:?}");
        if [3, 7].contains(&after.obj_id) {
            assert!(half_turns(before) > 0, "{before:?}");
            assert_eq!(half_turns(after), 0, "{after:?}");
        }
        let warned = after
            .warning
            .as_deref()
            .is_some_and(|w| w.contains("depth alone") && w.contains(unreadable.to_str().unwrap()));
        assert_eq!(warned, after.scene == 0, "{after:?}");
        if after.scene == 0 {
            let angles = |s: &Scored| s.errors.iter().map(|e| e.angle).collect::<Vec<_>>();
            assert_eq!(angles(after), angles(before));
        }
    }
}

/// Every real instance's labels cover at least 90% of its reference set A, the poses the
/// acceptance rule accepts found by brute force (`reference_dataset`: 576 ICP starts, then a
/// flood fill on a level-4 grid), which share nothing with the labeller's search but the rule.
#[test]
fn real_label_sets_cover_the_poses_the_view_cannot_tell_apart() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("ycbv");
    copy_dir(&fixture(), &root);
    let dataset = BopDataset::open(&root, "models").unwrap();
    let options = LabelOptions::default();
    label_split(&dataset, "test", &options).unwrap();
    let dataset_options = pseudo_label::DatasetOptions {
        split: "test".into(),
        mesh_scale: 0.001,
        obj_id: None,
        shard: pseudo_label::Shard::ALL,
        relabel: false,
    };
    let reference = pseudo_label::ReferenceOptions::default();
    let found =
        pseudo_label::reference_dataset(&dataset, &dataset_options, &options, &reference, &())
            .unwrap();
    assert_eq!((found.instances, found.labelled), (11, 11), "{found:?}");
    let report = pseudo_label::report(&dataset, "test", &Default::default(), "ycbv").unwrap();
    let instances: Vec<_> = report
        .objects
        .values()
        .flat_map(|o| o.against_reference.iter())
        .collect();
    assert_eq!(instances.len(), 11);
    for instance in instances {
        assert!(instance.completeness >= 0.9, "{instance:?}");
    }
}
