//! 6D poses through the real binary: `train --target translation|pose`, `eval` and `predict`
//! of translation models and pose runs on a few synthetic frames (barely trained: the files,
//! their shapes and the figures' ranges are checked, not accuracy), and bad inputs.
use crate::common;

use std::path::Path;

use common::{
    BRIEF_TRAINING, SMALL_NETWORK, assert_fails, copy_dir, ipdf_json, predict_args, read_json,
    read_npy, s, synth, train_single, viz_args,
};
use nalgebra::{Quaternion, Unit, UnitQuaternion, Vector3};
use serde_json::Value;

/// The unit quaternion of a JSON `[w, x, y, z]`.
fn quaternion(value: &Value) -> UnitQuaternion<f64> {
    let q = |i: usize| finite(&value[i]);
    UnitQuaternion::from_quaternion(Quaternion::new(q(0), q(1), q(2), q(3)))
}

/// The turn from the line of sight's frame into the camera's for the crop around `mask`: the
/// shortest turn taking z onto the ray through the middle of the mask's bounding box (the
/// crop's centre), in pixel coordinates with pixel centres at integers, for `cam_K` `k`.
fn line_of_sight(mask: &Path, k: &Value) -> UnitQuaternion<f64> {
    let mask = image::open(mask).unwrap().to_luma8();
    let set: Vec<(u32, u32)> = mask
        .enumerate_pixels()
        .filter(|p| p.2.0[0] > 0)
        .map(|p| (p.0, p.1))
        .collect();
    let middle = |coordinate: fn(&(u32, u32)) -> u32| {
        let low = set.iter().map(coordinate).min().unwrap();
        let high = set.iter().map(coordinate).max().unwrap();
        f64::from(low + high) / 2.0
    };
    let (u, v) = (middle(|p| p.0), middle(|p| p.1));
    let ray = Vector3::new(
        (u - finite(&k[2])) / finite(&k[0]),
        (v - finite(&k[5])) / finite(&k[4]),
        1.0,
    )
    .normalize();
    let axis = Unit::new_normalize(Vector3::z().cross(&ray));
    UnitQuaternion::from_axis_angle(&axis, ray.z.acos())
}

fn finite(value: &Value) -> f64 {
    let v = value.as_f64().unwrap_or(f64::NAN);
    assert!(v.is_finite(), "{value}");
    v
}

/// A `scene_reference_gt.json` beside each `scene_gt.json` of the validation split whose set
/// for each instance is its ground-truth pose composed with the identity and each discrete
/// symmetry of `models_info.json` (row-major 4 × 4, millimetres).
fn write_symmetric_sets(data: &Path) {
    let info = read_json(&data.join("models/models_info.json"));
    for scene in std::fs::read_dir(data.join("val")).unwrap() {
        let scene = scene.unwrap().path();
        if !scene.is_dir() {
            continue;
        }
        let gt = read_json(&scene.join("scene_gt.json"));
        let mut sets = serde_json::Map::new();
        for (im, instances) in gt.as_object().unwrap() {
            let instances: Vec<Value> = instances
                .as_array()
                .unwrap()
                .iter()
                .map(|instance| {
                    let obj_id = &instance["obj_id"];
                    let r: Vec<f64> = instance["cam_R_m2c"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(finite)
                        .collect();
                    let mut turns = vec![vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]];
                    if let Some(discrete) =
                        info[obj_id.to_string()]["symmetries_discrete"].as_array()
                    {
                        for matrix in discrete {
                            let m: Vec<f64> =
                                matrix.as_array().unwrap().iter().map(finite).collect();
                            turns.push(vec![m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]]);
                        }
                    }
                    let labels: Vec<Value> = turns
                        .iter()
                        .map(|t| {
                            let product: Vec<f64> = (0..9)
                                .map(|k| (0..3).map(|j| r[k / 3 * 3 + j] * t[j * 3 + k % 3]).sum())
                                .collect();
                            serde_json::json!({
                                "cam_R_m2c": product,
                                "cam_t_m2c": instance["cam_t_m2c"],
                                "score": 0.8,
                            })
                        })
                        .collect();
                    serde_json::json!({"obj_id": obj_id, "labels": labels})
                })
                .collect();
            sets.insert(im.clone(), Value::Array(instances));
        }
        std::fs::write(
            scene.join("scene_reference_gt.json"),
            serde_json::to_vec(&Value::Object(sets)).unwrap(),
        )
        .unwrap();
    }
}

#[test]
fn pose_runs_train_score_and_predict_translations() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    for (split, frames, seed) in [("train", 12, "0"), ("val", 3, "1")] {
        synth(
            &data,
            "box,can",
            frames,
            &["--split", split, "--seed", seed],
        );
    }
    let run = dir.path().join("run");
    // The box's single labels: every training command below starts so.
    let box_run = train_single(&data, "box");
    // The network of every run here (a run folder is refused for another one).
    let network = SMALL_NETWORK;
    let train = |target: &str, out: &Path| {
        let mut words = box_run.to_vec();
        words.extend(["--target", target, "--out", s(out)]);
        words.extend(network);
        words.extend(BRIEF_TRAINING);
        words.extend(["--translation-queries", "64"]);
        ipdf_json(&words)
    };
    let trained = train("pose", &run);
    assert_eq!(trained["rotation"]["target"], "rotation");
    assert_eq!(trained["translation"]["target"], "translation");
    assert!(finite(&trained["translation"]["validation_llh"]) < 0.0);
    // Rotation runs keep their run.json as before; the translation model has its own folder,
    // whose checkpoint records the working volume.
    assert!(read_json(&run.join("run.json")).get("target").is_none());
    let translation_run = run.join("translation");
    assert_eq!(
        read_json(&translation_run.join("run.json"))["target"],
        "translation"
    );
    let volume = &read_json(&translation_run.join("checkpoint.json"))["translation"]["volume"];
    for axis in 0..3 {
        assert!(
            finite(&volume["min"][axis]) < finite(&volume["max"][axis]),
            "{volume}"
        );
    }

    let scores = ipdf_json(&["eval", "--checkpoint", s(&run), "--level", "2"]);
    assert_eq!(scores["truth"], "gt");
    // With --depth-hypotheses, each rendered instance (depth and masks) also has a pose found
    // from the rotation model's hypotheses and its depth, and the summary counts its true poses
    // as the rows say; without it, none.
    let rows = scores["instances"].as_array().unwrap();
    assert!(rows.iter().all(|r| r.get("refined_vsd").is_none()));
    let refined = ipdf_json(&[
        "eval",
        "--checkpoint",
        s(&run),
        "--level",
        "2",
        "--depth-hypotheses",
        "4",
    ]);
    let rows = refined["instances"].as_array().unwrap();
    let true_poses = rows
        .iter()
        .filter(|r| {
            finite(&r["refined_rotation_error_deg"]) < 15.0 || finite(&r["refined_vsd"]) < 0.3
        })
        .count();
    assert!(
        rows.iter()
            .all(|r| finite(&r["refined_translation_error_mm"]) >= 0.0)
    );
    let share = finite(&refined["accuracy"]["refined_acc_15_or_vsd"]);
    assert!(
        (share - true_poses as f64 / rows.len() as f64).abs() < 1e-12,
        "{refined}"
    );
    assert_eq!(refined["llh"], scores["llh"]);
    // Scored against reference sets, which `ipdf label --reference` must have made first; sets
    // that hold the ground truth turned by each symmetry of models_info.json score as the
    // ground truth does.
    let reference = [
        "eval",
        "--checkpoint",
        s(&run),
        "--level",
        "2",
        "--truth",
        "reference",
    ];
    assert_fails(&reference, "--reference");
    let untrained = dir.path().join("reference_run");
    assert_fails(
        &[
            "train",
            "--dataset",
            s(&data),
            "--object",
            "box",
            "--labels",
            "reference",
            "--out",
            s(&untrained),
        ],
        "--split train --reference",
    );
    write_symmetric_sets(&data);
    let against = ipdf_json(&reference);
    assert_eq!(against["truth"], "reference");
    assert_eq!(against["images"], scores["images"]);
    for key in ["llh", "maad_deg", "recall_maad_deg"] {
        let (a, b) = (finite(&against[key]), finite(&scores[key]));
        assert!(
            (a - b).abs() < 1e-6 * (1.0 + b.abs()),
            "{key}: {a} against {b}"
        );
    }
    let translation = &scores["translation"];
    assert_eq!(translation["images"], 3);
    // Format checks (a model of a few steps learns too little for an accuracy bound): an error
    // is a distance, its depth part no larger, the joint LLH the sum of the two.
    assert!(finite(&translation["median_error_mm"]) >= 0.0);
    assert!(
        finite(&translation["median_depth_error_mm"])
            <= finite(&translation["median_error_mm"]) + 1e-9
    );
    let pose = &scores["pose"];
    let joint = finite(&pose["joint_llh"]);
    assert!((joint - finite(&scores["llh"]) - finite(&translation["llh"])).abs() < 1e-9);
    assert!((0.0..=1.0).contains(&finite(&pose["add_s_auc"])), "{pose}");
    // The box's models_info diameter: the largest distance between two of its vertices, the
    // diagonal of a 60 × 158 × 210 mm cuboid (f32 vertices in metres: within 0.01 mm).
    let diagonal = (60f64.powi(2) + 158f64.powi(2) + 210f64.powi(2)).sqrt();
    assert!(
        (finite(&pose["diameter_mm"]) - diagonal).abs() < 0.01,
        "{pose}"
    );
    // The translation model alone scores the same.
    let alone = ipdf_json(&["eval", "--checkpoint", s(&translation_run)]);
    assert_eq!(alone["translation"], *translation);
    assert!(alone.get("llh").is_none());
    // --obj-id scores the model on another object of the dataset (as for a model trained on
    // renders of a mesh and scored on a real dataset that numbers it otherwise): the can's
    // instances, its diameter; an id the dataset lacks fails with one line.
    let box_id = &trained["rotation"]["obj_id"];
    let can_id = if *box_id == 1 { "2" } else { "1" };
    let on_can = ipdf_json(&[
        "eval",
        "--checkpoint",
        s(&run),
        "--level",
        "2",
        "--obj-id",
        can_id,
    ]);
    assert_eq!(on_can["obj_id"].to_string(), can_id);
    assert_eq!(on_can["translation"]["images"], 3);
    assert_ne!(on_can["pose"]["diameter_mm"], pose["diameter_mm"]);
    assert_fails(
        &["eval", "--checkpoint", s(&run), "--obj-id", "7"],
        "7: no such object",
    );

    let scene = data.join("val/000000");
    let (rgb, mask) = (
        scene.join("rgb/000000.png"),
        scene.join("mask_visib/000000_000000.png"),
    );
    let k = &read_json(&scene.join("scene_camera.json"))["0"]["cam_K"];
    let intrinsics = format!("{},{},{},{}", k[0], k[4], k[2], k[5]);
    let out = dir.path().join("pose.npy");
    // `ipdf predict` of `run` on the first validation image.
    let predict = |run: &Path, intrinsics: &str| {
        let extra = ["--level", "1", "--intrinsics", intrinsics];
        ipdf_json(&predict_args(run, &rgb, &mask, &out, &extra))
    };
    let predicted = predict(&run, &intrinsics);
    assert_eq!(predicted["cells"], 576);
    let t = &predicted["argmax"]["cam_t_m2c"];
    assert!(finite(&t[2]) > 0.0, "{predicted}");
    assert_eq!(
        predicted["argmax"]["cam_R_m2c"].as_array().unwrap().len(),
        9
    );
    let (shape, rows) = read_npy(&dir.path().join("pose_translation.npy"));
    assert_eq!(shape[1], 5);
    assert_eq!(
        shape[0],
        predicted["translation"]["cells"].as_u64().unwrap()
    );
    let total: f64 = rows.chunks(5).map(|row| f64::from(row[4])).sum();
    assert!((total - 1.0).abs() < 1e-3, "masses sum to {total}");
    assert_eq!(read_json(&out.with_extension("json")), predicted);
    // The same weights read as a model in the line of sight's frame (its checkpoint says so)
    // answer with the camera-frame model's rotations turned by the crop's line of sight, here
    // written out from the mask's box and cam_K: the shortest turn taking z onto the ray
    // through the box's middle pixel. The distribution's masses are the same, each cell now
    // the grid's rotation turned by `cell_turn_wxyz`; the translation model is unchanged.
    let los = dir.path().join("line_of_sight");
    copy_dir(&run, &los);
    let mut checkpoint = read_json(&los.join("checkpoint.json"));
    checkpoint["model"]["rotation_frame"] = "line-of-sight".into();
    std::fs::write(los.join("checkpoint.json"), checkpoint.to_string()).unwrap();
    let los_out = dir.path().join("line_of_sight.npy");
    let turned = ipdf_json(&predict_args(
        &los,
        &rgb,
        &mask,
        &los_out,
        &["--level", "1", "--intrinsics", &intrinsics],
    ));
    let turn = line_of_sight(&mask, k);
    assert!(turn.angle() > 1e-3, "{turn:?}");
    assert!(quaternion(&predicted["cell_turn_wxyz"]).angle() < 1e-12);
    assert!(quaternion(&turned["cell_turn_wxyz"]).angle_to(&turn) < 1e-9);
    let most_likely = |value: &Value| quaternion(&value["argmax"]["quaternion_wxyz"]);
    let expected = turn * most_likely(&predicted);
    assert!(most_likely(&turned).angle_to(&expected) < 1e-9, "{turned}");
    for (a, b) in turned["densest"]
        .as_array()
        .unwrap()
        .iter()
        .zip(predicted["densest"].as_array().unwrap())
    {
        let expected = turn * quaternion(&b["quaternion_wxyz"]);
        assert!(quaternion(&a["quaternion_wxyz"]).angle_to(&expected) < 1e-9);
        assert_eq!(a["probability"], b["probability"]);
    }
    assert_eq!(read_npy(&los_out), read_npy(&out));
    assert_eq!(
        turned["argmax"]["cam_t_m2c"],
        predicted["argmax"]["cam_t_m2c"]
    );
    // Without the camera it cannot answer in the camera's frame, and says what it needs.
    assert_fails(
        &predict_args(&los, &rgb, &mask, &los_out, &["--level", "1"]),
        "a rotation model in the line-of-sight frame",
    );
    // The same camera as a file (`--camera`, BOP's `cam_K` form) predicts the same pose; a
    // file of another image size is refused, naming it and the field.
    let (width, height) = image::image_dimensions(&rgb).unwrap();
    let camera = dir.path().join("camera.json");
    let camera_json =
        |width: u32| serde_json::json!({"cam_K": k, "width": width, "height": height});
    std::fs::write(&camera, camera_json(width).to_string()).unwrap();
    let extra = ["--level", "1", "--camera", s(&camera)];
    let from_file = ipdf_json(&predict_args(&run, &rgb, &mask, &out, &extra));
    assert_eq!(from_file, predicted);
    std::fs::write(&camera, camera_json(width + 1).to_string()).unwrap();
    assert_fails(
        &predict_args(&run, &rgb, &mask, &out, &extra),
        &format!("{}: width is {}", camera.display(), width + 1),
    );
    // A camera file without intrinsics is refused, naming the file and the field it lacks.
    std::fs::write(&camera, r#"{"width": 640, "height": 480}"#).unwrap();
    assert_fails(
        &predict_args(&run, &rgb, &mask, &out, &extra),
        &format!("{}: fx", camera.display()),
    );
    // With the image's depth (`--camera` gives its units), the most likely translation is also
    // fitted to it inside the box's visible mask: the model's stays as it was, and the fitted
    // one, whatever the rotation (and this briefly trained model places the box 50 cm off),
    // lies within the box's diameter of the truth. The diameter is the bound, not less: the
    // fit moves the model at the most likely rotation, which this model gets wrong, along the
    // line of sight until its surface meets the depth, so the box's centre can end anywhere
    // within its own size of the truth's (58 mm here). The fit's accuracy at the right rotation
    // is `ipdf::depth_fit`'s tests'.
    let gt = &read_json(&scene.join("scene_gt.json"))["0"];
    let index = gt
        .as_array()
        .unwrap()
        .iter()
        .position(|instance| instance["obj_id"] == *box_id)
        .unwrap();
    let box_mask = scene.join(format!("mask_visib/000000_{index:06}.png"));
    // `ipdf viz` draws the line-of-sight model with the dataset's image (whose intrinsics turn
    // it into the camera's frame), and refuses a bare image without them.
    let figure = dir.path().join("line_of_sight.png");
    let instance = index.to_string();
    let drawn = ["--scene", "0", "--image", "0", "--instance", &instance];
    // What is checked here is that viz accepts the line-of-sight model with an image that
    // brings its intrinsics (and, next, refuses one without them); the turn into the camera's
    // frame that the figure draws is predict's, whose answers are checked against the turn
    // above. The figure is a picture of the size viz reports.
    let reported = ipdf_json(&viz_args(&los, &figure, &drawn));
    let drawn_figure = image::open(&figure).unwrap();
    assert_eq!(
        reported["width"].as_u64(),
        Some(u64::from(drawn_figure.width()))
    );
    assert_fails(
        &viz_args(&los, &figure, &["--rgb", s(&rgb), "--mask", s(&box_mask)]),
        "which needs the camera's intrinsics",
    );
    let depth_scale = &read_json(&scene.join("scene_camera.json"))["0"]["depth_scale"];
    let depth_camera = dir.path().join("depth_camera.json");
    let camera_json = serde_json::json!({"cam_K": k, "depth_scale": depth_scale});
    std::fs::write(&depth_camera, camera_json.to_string()).unwrap();
    let depth = scene.join("depth/000000.png");
    let with_depth = [
        "--level",
        "1",
        "--camera",
        s(&depth_camera),
        "--depth",
        s(&depth),
    ];
    let fitted = ipdf_json(&predict_args(&run, &rgb, &box_mask, &out, &with_depth));
    let vector = |value: &Value| Vector3::from_fn(|i, _| finite(&value[i]));
    let (model_t, fitted_t) = (
        vector(&fitted["argmax"]["cam_t_m2c"]),
        vector(&fitted["argmax"]["fitted_cam_t_m2c"]),
    );
    assert_eq!(model_t, vector(&predicted["argmax"]["cam_t_m2c"]));
    let truth = vector(&gt[index]["cam_t_m2c"]);
    let models_info = read_json(&data.join("models/models_info.json"));
    let diameter = finite(&models_info[box_id.to_string()]["diameter"]);
    assert!(
        (fitted_t - truth).norm() < diameter,
        "{fitted} against {truth}"
    );
    // With depth, a pose is also found from the rotation model's 8 hypotheses: each is placed
    // on the mask's depth and refined by ICP, and the one chosen sits on the box's surface as
    // the truth does: its centre within 5 mm of the truth's (0.6 mm here; placed on the depth
    // without ICP it would be off by the hypothesis' error, tens of millimetres), and its
    // rotation matrix is its quaternion's. Without depth there is none.
    assert!(predicted.get("refined_with_depth").is_none(), "{predicted}");
    let refined = &fitted["refined_with_depth"];
    assert!((refined["hypothesis"].as_u64().unwrap()) < 8, "{refined}");
    assert!(finite(&refined["score"]) >= 0.0, "{refined}");
    let refined_t = vector(&refined["cam_t_m2c"]);
    assert!(
        (refined_t - truth).norm() < 5.0,
        "{refined} against {truth}"
    );
    let matrix = quaternion(&refined["quaternion_wxyz"]).to_rotation_matrix();
    for i in 0..9 {
        let entry = finite(&refined["cam_R_m2c"][i]);
        assert!((entry - matrix[(i / 3, i % 3)]).abs() < 1e-9, "{refined}");
    }
    // Compared in a stereo camera's expected errors (`--sensor realsense`), the pose found is
    // still on the box's surface (within 5 mm), and its score is counted in other units than the Kinect's.
    let stereo = [&with_depth[..], &["--sensor", "realsense"]].concat();
    let stereo = ipdf_json(&predict_args(&run, &rgb, &box_mask, &out, &stereo));
    let stereo = &stereo["refined_with_depth"];
    assert!(
        (vector(&stereo["cam_t_m2c"]) - truth).norm() < 5.0,
        "{stereo} against {truth}"
    );
    assert_ne!(stereo["score"], refined["score"], "{stereo} {refined}");
    // Averaged over the crop and its 8 test-time views (`--views 8`), the rotation model's
    // image term is another, so its answer moves; the pose found with depth still lies on the
    // box's surface (within 5 mm).
    let viewed = [&with_depth[..], &["--views", "8"]].concat();
    let viewed = ipdf_json(&predict_args(&run, &rgb, &box_mask, &out, &viewed));
    let one_view = &fitted["argmax"]["quaternion_wxyz"];
    assert_ne!(&viewed["argmax"]["quaternion_wxyz"], one_view, "{viewed}");
    let viewed_t = vector(&viewed["refined_with_depth"]["cam_t_m2c"]);
    assert!((viewed_t - truth).norm() < 5.0, "{viewed} against {truth}");
    // A depth image with no reading inside the mask: predict still answers, with neither the
    // fitted translation nor the refined pose.
    let blank_depth = dir.path().join("blank_depth.png");
    image::ImageBuffer::<image::Luma<u16>, _>::from_pixel(width, height, image::Luma([0u16]))
        .save(&blank_depth)
        .unwrap();
    let with_blank_depth = [
        "--level",
        "1",
        "--camera",
        s(&depth_camera),
        "--depth",
        s(&blank_depth),
    ];
    let blank = ipdf_json(&predict_args(
        &run,
        &rgb,
        &box_mask,
        &out,
        &with_blank_depth,
    ));
    assert!(blank.get("refined_with_depth").is_none(), "{blank}");
    assert!(blank["argmax"].get("fitted_cam_t_m2c").is_none(), "{blank}");
    // A translation run has no rotation to render the mesh at; a box has no mask to fit in.
    assert_fails(
        &predict_args(&translation_run, &rgb, &box_mask, &out, &with_depth),
        "is a translation run",
    );
    // A depth image of another size than the colour image is refused, naming it.
    let small_depth = dir.path().join("small_depth.png");
    image::ImageBuffer::<image::Luma<u16>, _>::from_pixel(8, 6, image::Luma([500u16]))
        .save(&small_depth)
        .unwrap();
    let with_small_depth = [
        "--level",
        "1",
        "--camera",
        s(&depth_camera),
        "--depth",
        s(&small_depth),
    ];
    assert_fails(
        &predict_args(&run, &rgb, &box_mask, &out, &with_small_depth),
        &format!(
            "{}: 8 × 6 pixels, but --rgb is {width} × {height}",
            small_depth.display()
        ),
    );
    let mut boxed = vec!["predict", "--checkpoint", s(&run), "--rgb", s(&rgb)];
    boxed.extend(["--bbox", "10,10,40,40", "--out", s(&out)]);
    boxed.extend(with_depth);
    assert_fails(&boxed, "--mask");
    let only = predict(&translation_run, &intrinsics);
    assert_eq!(only["argmax"]["cam_t_m2c"], *t);
    assert!(only.get("level").is_none());

    // Bad inputs: one line each, nothing half-written.
    // A pose run without intrinsics predicts the orientation only; a translation run needs
    // them.
    let orientation = ipdf_json(&predict_args(&run, &rgb, &mask, &out, &["--level", "1"]));
    assert!(orientation.get("translation").is_none(), "{orientation}");
    assert!(orientation["argmax"].get("cam_t_m2c").is_none());
    assert_fails(
        &predict_args(&translation_run, &rgb, &mask, &out, &[]),
        "--intrinsics",
    );
    for (extra, expected) in [
        (vec!["--intrinsics", "600,600,320"], "intrinsics"),
        (vec!["--intrinsics", "600,600,5000,240"], "outside"),
    ] {
        assert_fails(&predict_args(&run, &rgb, &mask, &out, &extra), expected);
    }
    let fail_train = |extra: &[&str], expected: &str| {
        let mut w = box_run.to_vec();
        w.extend(extra);
        assert_fails(&w, expected);
    };
    fail_train(&["--target", "position", "--out", s(&run)], "position");
    fail_train(
        &[
            "--target",
            "translation",
            "--translation-queries",
            "1",
            "--out",
            s(&run),
        ],
        "translation-queries",
    );
    // A rotation run's folder is not continued as a translation run.
    let mut other_target = vec!["--target", "translation", "--out", s(&run)];
    other_target.extend(network);
    fail_train(&other_target, "other data");
}
