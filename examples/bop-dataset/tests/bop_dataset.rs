//! The BOP reader and writer: round trips, a dataset laid out as T-LESS ships it
//! (`tests/data/tless_layout`: `models_cad/`, `camera_primesense.json`,
//! `test_primesense/000001/` with non-consecutive image ids, two instances in one image, PNG and
//! JPEG colour images, T-LESS's extra `scene_camera.json` keys), and errors that name the file
//! and the key.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use bop_dataset::{
    BopDataset, GtInfo, GtInstance, Intrinsics, ModelInfo, PseudoInstance, PseudoLabel,
    RotationRepairs, read_depth, read_mask, read_models_info, read_object_ids, read_pseudo_gt,
    read_rgb, read_scene_camera, read_scene_gt, read_scene_gt_info, read_scene_gt_repaired,
    write_models_info, write_pseudo_gt, write_scene_camera, write_scene_gt, write_scene_gt_info,
};
use nalgebra::{Isometry3, Translation3};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tless_layout")
}

fn pose(seed: u64) -> Isometry3<f64> {
    let rotation = so3_grid::random_rotations(1, seed)[0];
    Isometry3::from_parts(Translation3::new(0.01 * seed as f64, -0.02, 0.7), rotation)
}

fn close(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
    (a.translation.vector - b.translation.vector).norm() < 1e-9
        && a.rotation.angle_to(&b.rotation) < 1e-9
}

#[test]
fn the_writers_round_trip_through_the_readers() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let can = depth_render::Primitive::Cylinder {
        radius: 0.05,
        height: 0.1,
        segments: 32,
    };
    let shape = can.symmetry().unwrap();
    let group = ipdf_metrics::SymmetryGroup::about_origin(&shape.discrete, &shape.continuous);
    let info = ModelInfo::of_mesh(&can.mesh().unwrap(), &group);
    let models = BTreeMap::from([
        (1, info.clone()),
        (
            12,
            ModelInfo {
                symmetry: Default::default(),
                ..info
            },
        ),
    ]);
    write_models_info(&path("models_info.json"), &models).unwrap();
    let back = read_models_info(&path("models_info.json")).unwrap();
    assert_eq!(back.keys().copied().collect::<Vec<_>>(), vec![1, 12]);
    assert!((back[&1].diameter - (100f64.powi(2) + 100f64.powi(2)).sqrt()).abs() < 1e-3);
    assert_eq!(back[&1].symmetry.continuous.len(), 1);
    assert_eq!(back[&1].symmetry.discrete.len(), 1);
    assert!(back[&12].symmetry.discrete.is_empty());

    let intrinsics = Intrinsics {
        fx: 600.5,
        fy: 601.0,
        cx: 320.25,
        cy: 240.0,
        depth_scale: 0.1,
    };
    let cameras = BTreeMap::from([(0, intrinsics), (10, intrinsics), (2, intrinsics)]);
    write_scene_camera(&path("scene_camera.json"), &cameras).unwrap();
    assert_eq!(
        read_scene_camera(&path("scene_camera.json")).unwrap(),
        cameras
    );

    let gt = BTreeMap::from([
        (
            0,
            vec![
                GtInstance {
                    obj_id: 1,
                    pose: pose(1),
                },
                GtInstance {
                    obj_id: 12,
                    pose: pose(2),
                },
            ],
        ),
        (
            10,
            vec![GtInstance {
                obj_id: 12,
                pose: pose(3),
            }],
        ),
    ]);
    write_scene_gt(&path("scene_gt.json"), &gt).unwrap();
    let back = read_scene_gt(&path("scene_gt.json")).unwrap();
    assert_eq!(
        back.keys().collect::<Vec<_>>(),
        gt.keys().collect::<Vec<_>>()
    );
    for (im_id, instances) in &gt {
        assert_eq!(back[im_id].len(), instances.len(), "image {im_id}");
        for (a, b) in instances.iter().zip(&back[im_id]) {
            assert_eq!(a.obj_id, b.obj_id);
            assert!(close(&a.pose, &b.pose));
        }
    }
    let ids = read_object_ids(&path("scene_gt.json")).unwrap();
    assert_eq!(ids, BTreeMap::from([(0, vec![1, 12]), (10, vec![12])]));

    let info = GtInfo {
        bbox_obj: [1, 2, 30, 40],
        bbox_visib: [-1, -1, -1, -1],
        px_count_all: 1200,
        px_count_valid: 1100,
        px_count_visib: 0,
        visib_fract: 0.0,
    };
    let infos = BTreeMap::from([(0, vec![info, info]), (10, vec![info])]);
    write_scene_gt_info(&path("scene_gt_info.json"), &infos).unwrap();
    assert_eq!(
        read_scene_gt_info(&path("scene_gt_info.json")).unwrap(),
        infos
    );

    let labels = BTreeMap::from([(
        0,
        vec![
            PseudoInstance {
                obj_id: 1,
                labels: vec![
                    PseudoLabel {
                        pose: pose(4),
                        score: 0.0012,
                    },
                    PseudoLabel {
                        pose: pose(5),
                        score: 0.002,
                    },
                ],
                error: None,
                warning: Some("doubt".into()),
                best: None,
            },
            PseudoInstance {
                obj_id: 12,
                labels: vec![],
                error: Some("the mask is empty".into()),
                warning: None,
                best: None,
            },
            PseudoInstance {
                obj_id: 3,
                labels: vec![],
                error: Some("no pose explains the depth".into()),
                warning: None,
                best: Some(PseudoLabel {
                    pose: pose(6),
                    score: 0.0069,
                }),
            },
        ],
    )]);
    write_pseudo_gt(&path("scene_pseudo_gt.json"), &labels).unwrap();
    let back = read_pseudo_gt(&path("scene_pseudo_gt.json")).unwrap();
    assert_eq!(back.keys().collect::<Vec<_>>(), [&0]);
    assert_eq!(back[&0].len(), labels[&0].len());
    assert_eq!(back[&0][1], labels[&0][1]);
    let (best, expected) = (
        back[&0][2].best.as_ref().unwrap(),
        labels[&0][2].best.as_ref().unwrap(),
    );
    assert!(close(&best.pose, &expected.pose) && (best.score - expected.score).abs() < 1e-15);
    assert!(back[&0][2].labels.is_empty() && back[&0][0].best.is_none());
    assert_eq!(back[&0][0].warning, labels[&0][0].warning);
    assert_eq!(back[&0][0].labels.len(), labels[&0][0].labels.len());
    for (a, b) in labels[&0][0].labels.iter().zip(&back[&0][0].labels) {
        assert!(close(&a.pose, &b.pose) && (a.score - b.score).abs() < 1e-15);
    }
}

#[test]
fn a_dataset_in_t_less_layout_loads() {
    let dataset = BopDataset::open(&fixture(), "models_cad").unwrap();
    let models = read_models_info(&dataset.models_info_path()).unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[&1].symmetry.continuous.len(), 1);
    assert_eq!(models[&2].symmetry.discrete.len(), 3);
    assert!(dataset.model_path(2).exists());
    assert_eq!(dataset.scene_ids("test_primesense").unwrap(), vec![1]);
    let scene = dataset.scene("test_primesense", 1);
    let cameras = read_scene_camera(&scene.camera_path()).unwrap();
    assert_eq!(cameras.keys().copied().collect::<Vec<_>>(), vec![0, 5]);
    let gt = read_scene_gt(&scene.gt_path()).unwrap();
    assert_eq!(
        gt[&0].iter().map(|i| i.obj_id).collect::<Vec<_>>(),
        vec![1, 2]
    );
    assert_eq!(
        read_scene_gt_info(&scene.gt_info_path()).unwrap()[&0].len(),
        2
    );
    // Image 0 has a PNG, image 5 a JPEG; all images are the camera's size.
    assert_eq!(scene.rgb_path(5).extension().unwrap(), "jpg");
    for im_id in [0, 5] {
        let rgb = read_rgb(&scene.rgb_path(im_id)).unwrap();
        let depth = read_depth(&scene.depth_path(im_id), cameras[&im_id].depth_scale).unwrap();
        let mask = read_mask(&scene.mask_visib_path(im_id, 0)).unwrap();
        assert_eq!(
            (rgb.width, rgb.height, depth.width, mask.height),
            (160, 120, 160, 120)
        );
        // The object's depth, in metres, at the camera distances of the fixture (0.25–0.3 m).
        let on_object: Vec<f32> = depth
            .pixels
            .iter()
            .zip(&mask.pixels)
            .filter(|(_, m)| **m)
            .map(|(d, _)| *d)
            .collect();
        assert!(!on_object.is_empty() && on_object.iter().all(|d| (0.15..0.4).contains(d)));
        let camera = cameras[&im_id].camera(depth.width, depth.height).unwrap();
        assert_eq!(camera.camera.fx, 270.0);
    }
}

#[test]
fn malformed_files_name_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let path = write(
        "models_info.json",
        r#"{"1": {"diameter": 10}, "2": {"min_x": 1}}"#,
    );
    let error = read_models_info(&path).unwrap_err();
    assert_eq!(
        (error.path.as_path(), error.field.as_str()),
        (path.as_path(), "2.diameter")
    );
    let path = write(
        "m2.json",
        r#"{"1": {"diameter": 10, "symmetries_discrete": [[1, 0]]}}"#,
    );
    assert_eq!(
        read_models_info(&path).unwrap_err().field,
        "1.symmetries_discrete[0]"
    );
    let path = write(
        "scene_gt.json",
        r#"{"0": [{"obj_id": 1, "cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0]}]}"#,
    );
    assert_eq!(read_scene_gt(&path).unwrap_err().field, "0[0].cam_t_m2c");
    // Ground truth as real BOP datasets publish it, orthonormal only to about 1e-2 (here a
    // rotation about z by 0.6 rad, scaled by 1.005): read as that rotation. An entry off by 0.3
    // is refused, naming the field.
    let (c, s) = (0.6f64.cos() * 1.005, 0.6f64.sin() * 1.005);
    let path = write(
        "published.json",
        &format!(
            r#"{{"0": [{{"obj_id": 1, "cam_R_m2c": [{c}, {}, 0, {s}, {c}, 0, 0, 0, 1.005], "cam_t_m2c": [0, 0, 700]}}]}}"#,
            -s
        ),
    );
    let read = read_scene_gt(&path).unwrap();
    let angle = read[&0][0]
        .pose
        .rotation
        .angle_to(&nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.6));
    assert!(angle < 1e-12, "{angle}");
    // The repair is counted: |RᵀR − I| of the scaled matrix is 1.005² − 1 on the diagonal.
    let (_, repairs) = read_scene_gt_repaired(&path).unwrap();
    assert_eq!(repairs.count, 1);
    assert!((repairs.worst_orthogonality_error - (1.005f64.powi(2) - 1.0)).abs() < 1e-12);
    assert!(
        repairs
            .worst_at
            .unwrap()
            .ends_with("published.json: 0[0].cam_R_m2c")
    );
    let exact = write(
        "exact.json",
        r#"{"0": [{"obj_id": 1, "cam_R_m2c": [0, -1, 0, 1, 0, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 700]}]}"#,
    );
    assert_eq!(
        read_scene_gt_repaired(&exact).unwrap().1,
        RotationRepairs::default()
    );
    let path = write(
        "garbled.json",
        &format!(
            r#"{{"0": [{{"obj_id": 1, "cam_R_m2c": [{c}, {}, 0.3, {s}, {c}, 0, 0, 0, 1.005], "cam_t_m2c": [0, 0, 700]}}]}}"#,
            -s
        ),
    );
    let error = read_scene_gt(&path).unwrap_err();
    assert_eq!(
        (error.path.as_path(), error.field.as_str()),
        (path.as_path(), "0[0].cam_R_m2c")
    );
    let path = write("ids.json", r#"{"0": [{"obj_id": -3}]}"#);
    assert_eq!(read_object_ids(&path).unwrap_err().field, "0[0].obj_id");
    let path = write(
        "scene_camera.json",
        r#"{"zero": {"cam_K": [1, 0, 0, 0, 1, 0, 0, 0, 1]}}"#,
    );
    assert_eq!(read_scene_camera(&path).unwrap_err().field, "zero");
    let path = write(
        "cam2.json",
        r#"{"0": {"cam_K": [1, 0, 0, 0, 1, 0, 0, 0, 1], "depth_scale": -1}}"#,
    );
    assert_eq!(read_scene_camera(&path).unwrap_err().field, "0.depth_scale");
    let path = write(
        "info.json",
        r#"{"3": [{"bbox_obj": [0, 0, 1], "bbox_visib": [0, 0, 1, 1]}]}"#,
    );
    assert_eq!(
        read_scene_gt_info(&path).unwrap_err().field,
        "3[0].bbox_obj"
    );
    let path = write("pseudo.json", r#"{"3": [{"obj_id": 1, "labels": {}}]}"#);
    assert_eq!(read_pseudo_gt(&path).unwrap_err().field, "3[0].labels");
    let path = write(
        "best.json",
        r#"{"3": [{"obj_id": 1, "labels": [], "error": "no pose", "best": {"cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 700], "score": "low"}}]}"#,
    );
    assert_eq!(read_pseudo_gt(&path).unwrap_err().field, "3[0].best.score");
    let path = write("truncated.json", r#"{"3": [{"obj_id": 1, "lab"#);
    assert_eq!(read_pseudo_gt(&path).unwrap_err().field, "file");
    assert!(
        read_scene_gt(&dir.path().join("absent.json"))
            .unwrap_err()
            .to_string()
            .contains("absent.json")
    );
}

#[test]
fn a_dataset_is_copied_file_for_file() {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("copy");
    bop_dataset::copy_dataset(&fixture(), &copy).unwrap();
    let files = |root: &Path| {
        let mut found = BTreeMap::new();
        let mut folders = vec![root.to_path_buf()];
        while let Some(folder) = folders.pop() {
            for entry in std::fs::read_dir(folder).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    folders.push(path);
                } else {
                    let name = path.strip_prefix(root).unwrap().to_path_buf();
                    found.insert(name, std::fs::read(&path).unwrap());
                }
            }
        }
        found
    };
    let (original, copied) = (files(&fixture()), files(&copy));
    // tests/data/tless_layout: 4 files outside its scene folder, 13 in it.
    assert_eq!(original.len(), 17);
    assert!(original == copied);
    let missing = dir.path().join("absent");
    let error = bop_dataset::copy_dataset(&missing, &dir.path().join("other")).unwrap_err();
    assert_eq!(error.path, missing);
}

#[test]
fn a_scene_has_masks_where_it_has_a_visible_or_a_full_mask_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scene = BopDataset::new(dir.path()).scene("test", 2);
    std::fs::create_dir_all(scene.dir.join("rgb")).unwrap();
    assert!(!scene.has_masks());
    // A file named like the folder is not one.
    std::fs::write(scene.dir.join("mask_visib"), "").unwrap();
    assert!(!scene.has_masks());
    std::fs::create_dir_all(scene.dir.join("mask")).unwrap();
    assert!(scene.has_masks());
    std::fs::remove_dir(scene.dir.join("mask")).unwrap();
    std::fs::remove_file(scene.dir.join("mask_visib")).unwrap();
    std::fs::create_dir_all(scene.dir.join("mask_visib")).unwrap();
    assert!(scene.has_masks());
}
