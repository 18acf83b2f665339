//! Real frames as a detector gives them, through the real binary: the LM-O frame of
//! `tests/data/lmo_real` (real RGB, BOP's published ground truth, visible boxes, no masks, no
//! depth) scored per instance; the same scores from masks that fill the same boxes;
//! `ipdf predict --bbox` against `--mask`; published rotations counted, garbled ones and bad
//! boxes refused. The model is barely trained (on the frame's own boxes): formats and equalities
//! are checked, not accuracy.
use crate::common;

use std::path::{Path, PathBuf};

use common::{
    BRIEF_TRAINING, SMALL_NETWORK, assert_fails, copy_dir, ipdf_json, predict_args, read_json, s,
};
use nalgebra::{Matrix3, Quaternion, UnitQuaternion};
use serde_json::Value;

/// The fixture's folder.
fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lmo_real")
}

/// The fixture's scene folder in a copy of it at `root`.
fn scene(root: &Path) -> PathBuf {
    root.join("test/000002")
}

/// The `bbox_visib` of each instance of image 3, as `scene_gt_info.json` has them.
fn boxes(root: &Path) -> Vec<[u32; 4]> {
    let info = read_json(&scene(root).join("scene_gt_info.json"));
    info["3"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            let b = &i["bbox_visib"];
            [0, 1, 2, 3].map(|k| b[k].as_u64().unwrap() as u32)
        })
        .collect()
}

/// A mask of the 640 × 480 frame that fills BOP's box `[x, y, w, h]`: the pixels `x..=x + w`,
/// `y..=y + h` (the BOP toolkit's `calc_2d_bbox` convention).
fn filled_box(bbox: [u32; 4]) -> image::GrayImage {
    let [x, y, w, h] = bbox;
    image::GrayImage::from_fn(640, 480, |u, v| {
        let inside = (x..=x + w).contains(&u) && (y..=y + h).contains(&v);
        image::Luma([if inside { 255 } else { 0 }])
    })
}

/// The words of `ipdf eval` of `run` on the test split of the dataset at `root`, then `extra`.
fn eval_args<'a>(run: &'a Path, root: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut words = vec!["eval", "--checkpoint", s(run), "--dataset", s(root)];
    words.extend(["--split", "test"]);
    words.extend_from_slice(extra);
    words
}

/// `ipdf eval` of `run` (obj 5, the can, unless `extra` says) on the dataset at `root` at
/// level 2, written to `out`.
fn eval(run: &Path, root: &Path, out: &Path, extra: &[&str]) -> Value {
    let mut words = eval_args(run, root, &["--level", "2", "--out", s(out)]);
    words.extend_from_slice(extra);
    ipdf_json(&words)
}

#[test]
fn real_frames_are_scored_per_instance_from_their_boxes_as_from_masks_filling_them() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("lmo");
    copy_dir(&fixture(), &root);
    let run = dir.path().join("run");
    let mut train = vec![
        "train",
        "--dataset",
        s(&root),
        "--split",
        "test",
        "--val-split",
        "none",
        "--obj-id",
        "5",
        "--labels",
        "single",
        "--crop",
        "box",
        "--query-level",
        "1",
        "--out",
        s(&run),
    ];
    train.extend(SMALL_NETWORK);
    train.extend(BRIEF_TRAINING);
    let trained = ipdf_json(&train);
    assert_eq!(trained["train_images"], 1, "{trained}");
    assert_eq!(read_json(&run.join("run.json"))["crop"], "box");

    // No masks: the visible boxes. One can, scene 2, image 3, the second instance.
    let from_boxes = eval(&run, &root, &dir.path().join("boxes.json"), &[]);
    let row = &from_boxes["instances"][0];
    assert_eq!(from_boxes["instances"].as_array().unwrap().len(), 1);
    assert_eq!(
        [&row["scene_id"], &row["im_id"], &row["instance"]],
        [2, 3, 1]
    );
    assert!((row["visib_fract"].as_f64().unwrap() - 0.961_893_764_434_180_2).abs() < 1e-12);
    let error = row["rotation_error_deg"].as_f64().unwrap();
    assert!((0.0..=180.0).contains(&error), "{row}");
    // One crop: its own MAAD and Recall MAAD are the run's.
    for key in ["maad_deg", "recall_maad_deg"] {
        assert_eq!(row[key], from_boxes[key], "{key}: {row}");
    }
    let accuracy = &from_boxes["accuracy"];
    assert_eq!(
        accuracy["acc_15"].as_f64().unwrap(),
        f64::from(u8::from(error < 15.0))
    );
    assert_eq!(
        accuracy["acc_30"].as_f64().unwrap(),
        f64::from(u8::from(error < 30.0))
    );
    assert!(
        (accuracy["uniform_llh"].as_f64().unwrap() + (std::f64::consts::PI.powi(2)).ln()).abs()
            < 1e-12
    );
    // Four of the frame's eight rotations are published orthonormal only to 1.5e-4 .. 1.9e-3
    // (numpy on the file: the worst, 1.944e-3, is the driller's, the fourth instance).
    let repaired = &from_boxes["repaired_rotations"];
    assert_eq!(repaired["count"], 4, "{repaired}");
    assert!((repaired["worst_orthogonality_error"].as_f64().unwrap() - 1.944e-3).abs() < 1e-6);
    assert!(
        repaired["worst_at"]
            .as_str()
            .unwrap()
            .ends_with("scene_gt.json: 3[3].cam_R_m2c")
    );
    let table = std::fs::read_to_string(dir.path().join("boxes.md")).unwrap();
    assert!(table.contains(
        "| scene | image | instance | visible | rotation error (°) | VSD | LLH | MAAD (°) | Recall MAAD (°) |"
    ));
    // The frame has no depth image: no VSD, and no share of true poses by it.
    assert!(row.get("vsd").is_none() && accuracy.get("acc_15_or_vsd").is_none());
    assert!(table.contains("| 2 | 3 | 1 | 96% |"), "{table}");
    assert!(
        table.contains("1 instances (visible fraction ≥ 0.1): Acc@15°"),
        "{table}"
    );

    // A model trained on boxes, scored on boxes: nothing to warn of. The same model as if
    // trained on masked crops (its run.json says so) is scored on the same boxes, for want of
    // masks, with a warning that says so.
    let box_warning = |scores: &Value| {
        let warning = scores["warning"].as_str().unwrap_or_default().to_owned();
        warning.contains("1 of the 1 crops").then_some(warning)
    };
    assert_eq!(box_warning(&from_boxes), None, "{from_boxes}");
    let masked_run = dir.path().join("masked-run");
    copy_dir(&run, &masked_run);
    let mut info = read_json(&masked_run.join("run.json"));
    info["crop"] = "mask".into();
    std::fs::write(masked_run.join("run.json"), info.to_string()).unwrap();
    let mut warned = eval(&masked_run, &root, &dir.path().join("warned.json"), &[]);
    let warning = box_warning(&warned).expect("a warning of box crops");
    assert!(
        warning.contains("bbox_visib") && warning.contains("mask_visib"),
        "{warning}"
    );
    warned.as_object_mut().unwrap().remove("warning");
    let mut unwarned = from_boxes.clone();
    unwarned.as_object_mut().unwrap().remove("warning");
    assert_eq!(warned, unwarned);

    // Masks that fill the same boxes, cropped as masks: the same scores.
    let masks = scene(&root).join("mask_visib");
    std::fs::create_dir_all(&masks).unwrap();
    for (k, bbox) in boxes(&root).into_iter().enumerate() {
        filled_box(bbox)
            .save(masks.join(format!("000003_{k:06}.png")))
            .unwrap();
    }
    let from_masks = eval(
        &run,
        &root,
        &dir.path().join("masks.json"),
        &["--crop", "mask"],
    );
    assert_eq!(from_masks, from_boxes);
    // Masks but no depth image: nothing to refine a pose against, so a pose refined with depth
    // is not scored (no share of true poses at 0%), and the scores are those without the flag.
    let refined = eval(
        &run,
        &root,
        &dir.path().join("hypotheses.json"),
        &["--crop", "mask", "--depth-hypotheses", "8"],
    );
    assert_eq!(refined, from_masks);
    let table = std::fs::read_to_string(dir.path().join("hypotheses.md")).unwrap();
    assert!(!table.contains("refined"), "{table}");

    // --min-visib: the ape is 20% visible.
    let ape = |min: &str| {
        let args = ["--obj-id", "1", "--min-visib", min];
        eval(&run, &root, &dir.path().join("ape.json"), &args)
    };
    assert_eq!(ape("0.1")["accuracy"]["instances"], 1);
    let words = eval_args(&run, &root, &["--obj-id", "1", "--min-visib", "0.5"]);
    assert_fails(&words, "no labelled instance of object 1");
    assert_fails(
        &eval_args(&run, &root, &["--min-visib", "1.5"]),
        "--min-visib 1.5",
    );

    // predict --bbox x,y,w,h (a detector's box: w and h count pixels) against the mask.
    let rgb = scene(&root).join("rgb/000003.png");
    let [x, y, w, h] = boxes(&root)[1];
    let bbox = format!("{x},{y},{},{}", w + 1, h + 1);
    let out = |name: &str| dir.path().join(name);
    let with_mask = ipdf_json(&predict_args(
        &run,
        &rgb,
        &masks.join("000003_000001.png"),
        &out("m.npy"),
        &["--level", "1"],
    ));
    let predict_box = |bbox: &str, to: &Path| -> Vec<String> {
        let mut words = vec![
            "predict",
            "--checkpoint",
            s(&run),
            "--rgb",
            s(&rgb),
            "--bbox",
            bbox,
        ];
        words.extend(["--out", s(to), "--level", "1"]);
        words.into_iter().map(str::to_string).collect()
    };
    let with_box = ipdf_json(&common::strs(&predict_box(&bbox, &out("b.npy"))));
    assert_eq!(with_box, with_mask);

    // --ball 15: predict gives the centre of the heaviest 15° ball beside the argmax, and eval
    // scores it as the estimate (both on level 2 refined to 4): its error is its angle to the
    // published rotation (the can has no symmetry).
    let mask = masks.join("000003_000001.png");
    let ball_args = ["--level", "1", "--ball", "15"];
    let balled = ipdf_json(&predict_args(
        &run,
        &rgb,
        &mask,
        &out("ball.npy"),
        &ball_args,
    ));
    let ball = &balled["heaviest_ball"];
    assert_eq!(ball["radius_deg"], 15.0, "{balled}");
    assert!((1e-9..=1.0 + 1e-9).contains(&ball["mass"].as_f64().unwrap()));
    assert_eq!(balled["argmax"], with_mask["argmax"]);
    let scored = ipdf_json(&eval_args(&run, &root, &["--level", "4", "--ball", "15"]));
    assert_eq!(scored["ball_deg"], 15.0);
    let q: Vec<f64> = (0..4)
        .map(|i| ball["quaternion_wxyz"][i].as_f64().unwrap())
        .collect();
    let estimate = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let r: Vec<f64> = (0..9)
        .map(|i| {
            read_json(&scene(&root).join("scene_gt.json"))["3"][1]["cam_R_m2c"][i]
                .as_f64()
                .unwrap()
        })
        .collect();
    let truth = UnitQuaternion::from_matrix(&Matrix3::from_row_slice(&r));
    let error = scored["instances"][0]["rotation_error_deg"]
        .as_f64()
        .unwrap();
    assert!(
        (estimate.angle_to(&truth).to_degrees() - error).abs() < 0.01,
        "{error}"
    );
    let bad_out = out("bad.npy");
    for bad in ["0", "181", "nan"] {
        assert_fails(&eval_args(&run, &root, &["--ball", bad]), "--ball");
        let args = predict_args(&run, &rgb, &mask, &bad_out, &["--ball", bad]);
        assert_fails(&args, "--ball");
    }
    assert_eq!(
        std::fs::read(out("b.npy")).unwrap(),
        std::fs::read(out("m.npy")).unwrap()
    );
    for (bad, words) in [
        ("600,10,100,20", "outside"),
        ("10,10,0,5", "empty"),
        ("10,10,-5,5", "negative"),
        ("10,10,5", "4 numbers"),
    ] {
        let args = predict_box(bad, &out("bad.npy"));
        assert_fails(&common::strs(&args), "--bbox");
        assert_fails(&common::strs(&args), words);
    }

    // A published box outside the image is refused, naming the file and the field.
    let info_path = scene(&root).join("scene_gt_info.json");
    let mut info = read_json(&info_path);
    info["3"][1]["bbox_visib"] = serde_json::json!([620, 226, 60, 91]);
    std::fs::write(&info_path, info.to_string()).unwrap();
    let words = eval_args(&run, &root, &["--crop", "box"]);
    assert_fails(&words, "scene_gt_info.json: 3[1].bbox_visib");

    // Without boxes and masks a box crop has nothing to cut around: the mask it looked for is
    // named.
    std::fs::remove_file(&info_path).unwrap();
    std::fs::remove_dir_all(&masks).unwrap();
    assert_fails(&words, "000003_000001.png: file: missing: a box crop needs");

    // A rotation off by 0.3 is refused, naming the file and the field.
    let gt_path = scene(&root).join("scene_gt.json");
    let mut gt = read_json(&gt_path);
    let entry = gt["3"][0]["cam_R_m2c"][2].as_f64().unwrap();
    gt["3"][0]["cam_R_m2c"][2] = serde_json::json!(entry + 0.3);
    std::fs::write(&gt_path, gt.to_string()).unwrap();
    assert_fails(&words, "scene_gt.json: 3[0].cam_R_m2c");
}
