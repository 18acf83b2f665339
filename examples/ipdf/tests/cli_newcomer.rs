//! What a newcomer trips over, through the real binary: each error says what to do (the
//! nearest command, the subcommand's `--help`, the flag that fixes a scale or a models folder,
//! the splits and scenes that exist), outputs are refused under a name of another format, and
//! reruns with changed settings are refused or repaired rather than silently mixed.
use crate::common;

use std::path::Path;

use common::{
    assert_fails, command_args, ipdf, ipdf_json, s, synth, synth_args, train_single, viz_args,
};

/// A copy of `ply` (binary PLY of `ipdf synth`, float xyz, uchar-int faces) with coordinates
/// multiplied by `factor`, written as ASCII PLY.
fn rescaled_ply(ply: &Path, factor: f32, out: &Path) {
    let bytes = std::fs::read(ply).unwrap();
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..header_end]).to_string();
    let count = |element: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (vertices, faces) = (count("vertex"), count("face"));
    let body = &bytes[header_end..];
    let float = |k: usize| f32::from_le_bytes(body[4 * k..4 * k + 4].try_into().unwrap());
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
         property float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    );
    for v in 0..vertices {
        let p: Vec<String> = (0..3)
            .map(|a| (float(3 * v + a) * factor).to_string())
            .collect();
        text.push_str(&format!("{}\n", p.join(" ")));
    }
    let mut at = 12 * vertices;
    for _ in 0..faces {
        let n = body[at] as usize;
        let index =
            |k: usize| i32::from_le_bytes(body[at + 1 + 4 * k..at + 5 + 4 * k].try_into().unwrap());
        let list: Vec<String> = (0..n).map(|k| index(k).to_string()).collect();
        text.push_str(&format!("{n} {}\n", list.join(" ")));
        at += 1 + 4 * n;
    }
    std::fs::write(out, text).unwrap();
}

/// `dir/pose.json`: rotation `rotation` (row-major), `z_mm` straight ahead of the camera.
fn pose_file(dir: &Path, rotation: &str, z_mm: u32) -> std::path::PathBuf {
    let path = dir.join("pose.json");
    let text = format!(r#"{{"cam_R_m2c": {rotation}, "cam_t_m2c": [0, 0, {z_mm}]}}"#);
    std::fs::write(&path, text).unwrap();
    path
}

/// A two-object dataset of 2 frames each, its can's mesh rescaled to metres beside it.
fn dataset(dir: &Path) -> std::path::PathBuf {
    let data = dir.join("data");
    synth(&data, "can,box", 2, &[]);
    rescaled_ply(
        &data.join("models/obj_000001.ply"),
        0.001,
        &dir.join("can_m.ply"),
    );
    data
}

#[test]
fn usage_errors_name_the_nearest_command_and_the_subcommands_help() {
    assert_fails(&["labels"], "a similar subcommand exists: 'label'");
    assert_fails(&["labels"], "(see ipdf --help)");
    assert_fails(
        &["label", "--dataset", "x", "--pixel-stride", "9"],
        "ipdf label --help",
    );
    assert_fails(&["--seed", "1", "train", "--datset", "x"], "'--dataset'");
    assert_fails(
        &["--seed", "1", "train", "--datset", "x"],
        "ipdf train --help",
    );
    // A flag that needs another names the one missing.
    assert_fails(
        &[
            "train",
            "--dataset",
            "x",
            "--labels",
            "single",
            "--out",
            "y",
            "--encoder",
            "efficientnet-lite0",
            "--freeze-encoder",
            "2",
        ],
        "not provided: --pretrained <PRETRAINED> (see ipdf train --help)",
    );
}

#[test]
fn missing_folders_splits_and_models_say_what_exists() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let missing = dir.path().join("nowhere");
    assert_fails(&["label", "--dataset", s(&missing)], "does not exist");
    assert_fails(
        &["label", "--dataset", s(&data), "--split", "test"],
        "split \"test\" does not exist; the dataset's splits: train",
    );
    // A T-LESS layout: its meshes are in models_cad, and `train` names the flag as `label` does.
    let tless = dir.path().join("tless");
    std::fs::create_dir_all(tless.join("models_cad")).unwrap();
    std::fs::create_dir_all(tless.join("test_primesense/000001")).unwrap();
    std::fs::write(tless.join("models_cad/models_info.json"), "{}").unwrap();
    let run = dir.path().join("run");
    for command in ["train", "label"] {
        let mut args = vec![
            command,
            "--dataset",
            s(&tless),
            "--split",
            "test_primesense",
        ];
        if command == "train" {
            args.extend(["--labels", "single", "--out", s(&run)]);
        }
        assert_fails(&args, "--models-dir models_cad");
    }
}

#[test]
fn a_mesh_or_cloud_at_the_wrong_scale_is_refused_naming_the_flag_that_fixes_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let metres = dir.path().join("can_m.ply");
    let pose = pose_file(dir.path(), "[1, 0, 0, 0, 1, 0, 0, 0, 1]", 700);
    let camera = data.join("camera.json");
    let depth = dir.path().join("depth.png");
    let files: [(&str, &Path); 4] = [
        ("--mesh", &metres),
        ("--camera", &camera),
        ("--pose", &pose),
        ("--out", &depth),
    ];
    assert_fails(
        &command_args("render", &files, &[]),
        "--mesh-scale 1 makes it",
    );
    assert!(!depth.exists());
    let fixed = ipdf_json(&command_args("render", &files, &["--mesh-scale", "1"]));
    assert!(fixed["pixels"].as_u64().unwrap() > 1000, "{fixed}");
    let out = dir.path().join("synth_m");
    assert_fails(
        &[
            "synth",
            "--out",
            s(&out),
            "--mesh",
            s(&metres),
            "--frames",
            "1",
        ],
        "--mesh-scale 1",
    );
    assert!(!out.exists(), "nothing written");
    // Millimetre clouds read as metres.
    let mesh_mm = data.join("models/obj_000001.ply");
    assert_fails(
        &["register", "--source", s(&mesh_mm), "--target", s(&mesh_mm)],
        "--scale 0.001",
    );
    // A dataset whose mesh is in metres: refused before any instance is labelled.
    std::fs::copy(&metres, data.join("models/obj_000001.ply")).unwrap();
    assert_fails(&["label", "--dataset", s(&data)], "--mesh-scale 1");
    assert!(!data.join("train/000000/scene_pseudo_gt.json").exists());
}

#[test]
fn outputs_named_for_another_format_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let mesh = data.join("models/obj_000001.ply");
    let pose = pose_file(dir.path(), "[1, 0, 0, 0, 1, 0, 0, 0, 1]", 700);
    let camera = data.join("camera.json");
    let view: [(&str, &Path); 3] = [("--mesh", &mesh), ("--camera", &camera), ("--pose", &pose)];
    let jpg = dir.path().join("depth.jpg");
    assert_fails(
        &command_args("render", &view, &["--out", s(&jpg)]),
        "must end in .png",
    );
    let png = dir.path().join("depth.png");
    let rgb = dir.path().join("rgb.jpg");
    assert_fails(
        &command_args("render", &view, &["--out", s(&png), "--rgb", s(&rgb)]),
        "--rgb",
    );
    let json = dir.path().join("p.json");
    assert_fails(
        &[
            "predict",
            "--checkpoint",
            "run",
            "--rgb",
            "a.png",
            "--mask",
            "b.png",
            "--out",
            s(&json),
        ],
        "must end in .npy",
    );
    assert_fails(
        &[
            "viz",
            "--train-log",
            "run",
            "--out",
            s(&dir.path().join("curves.svg")),
        ],
        "must end in .png",
    );
    for path in [jpg, png, rgb, json] {
        assert!(!path.exists(), "{}", path.display());
    }
}

#[test]
fn render_reports_the_depth_it_writes_and_honours_the_camera_files_depth_scale() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let mesh = data.join("models/obj_000002.ply");
    let pose = pose_file(dir.path(), "[1, 0, 0, 0, 0.8, -0.6, 0, 0.6, 0.8]", 900);
    let camera = dir.path().join("camera.json");
    std::fs::write(
        &camera,
        r#"{"cam_K": [572.4, 0, 320, 0, 573.6, 240, 0, 0, 1], "width": 640, "height": 480, "depth_scale": 0.1}"#,
    )
    .unwrap();
    let depth = dir.path().join("depth.png");
    let files: [(&str, &Path); 4] = [
        ("--mesh", &mesh),
        ("--camera", &camera),
        ("--pose", &pose),
        ("--out", &depth),
    ];
    let args = |extra: &[&'static str]| command_args("render", &files, extra);
    let clean = ipdf_json(&args(&[]));
    assert_eq!(clean["depth_scale"], 0.1, "the file's depth_scale");
    // The run's figures are those of the depth file it wrote (units of 0.1 mm).
    let matches_file = |run: &serde_json::Value| {
        let image = image::open(&depth).unwrap().into_luma16();
        let values: Vec<f64> = image
            .pixels()
            .filter(|p| p[0] > 0)
            .map(|p| f64::from(p[0]) * 0.1 / 1e3)
            .collect();
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(0.0, f64::max);
        for (key, value) in [("depth_min_m", min), ("depth_max_m", max)] {
            assert!(
                (run[key].as_f64().unwrap() - value).abs() < 1e-4,
                "{run} {key} {value}"
            );
        }
    };
    matches_file(&clean);
    // With --sensor the figures are those of the depth the sensor reads, as written.
    let noisy = ipdf_json(&args(&["--sensor", "kinect"]));
    matches_file(&noisy);
    assert_ne!(noisy["depth_max_m"], clean["depth_max_m"]);
    // The same value as the file is accepted; another is refused.
    ipdf_json(&args(&["--depth-scale", "0.1"]));
    assert_fails(
        &args(&["--depth-scale", "1"]),
        "contradicts depth_scale 0.1",
    );
}

#[test]
fn a_label_rerun_with_other_options_is_refused_and_relabel_replaces_the_labels() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let first = ipdf_json(&["label", "--dataset", s(&data)]);
    assert_eq!(first["instances"], 4);
    assert_fails(
        &["label", "--dataset", s(&data), "--strategy", "trials"],
        "strategy",
    );
    assert_fails(
        &["label", "--dataset", s(&data), "--strategy", "trials"],
        "recorded \"reseed\", this run asks for \"trials\"",
    );
    let same = ipdf_json(&["label", "--dataset", s(&data)]);
    assert_eq!(same["scenes_skipped"], 2);
    let trials = [
        "label",
        "--dataset",
        s(&data),
        "--strategy",
        "trials",
        "--labels",
        "2",
    ];
    let relabelled = ipdf_json(&[&trials[..], &["--relabel"]].concat());
    assert_eq!(
        (&relabelled["instances"], &relabelled["scenes_skipped"]),
        (&4.into(), &0.into())
    );
    // The new options are the recorded ones now.
    let again = ipdf_json(&trials);
    assert_eq!(again["scenes_skipped"], 2);
}

#[test]
fn synth_renders_again_a_finished_scene_whose_files_were_deleted_or_truncated() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let args = synth_args(&data, "can,box", "2", &[]);
    ipdf_json(&args);
    let rgb = data.join("train/000000/rgb/000001.png");
    let expected = std::fs::read(&rgb).unwrap();
    std::fs::remove_file(&rgb).unwrap();
    let depth = data.join("train/000001/depth/000000.png");
    let depth_bytes = std::fs::read(&depth).unwrap();
    std::fs::write(&depth, &depth_bytes[..depth_bytes.len() / 2]).unwrap();
    let repaired = ipdf_json(&args);
    assert_eq!(
        (&repaired["repaired"], &repaired["rendered"]),
        (&2.into(), &4.into())
    );
    assert_eq!(
        std::fs::read(&rgb).unwrap(),
        expected,
        "the same frame again"
    );
    assert_eq!(std::fs::read(&depth).unwrap(), depth_bytes);
    let again = ipdf_json(&args);
    assert_eq!(
        (&again["repaired"], &again["rendered"]),
        (&0.into(), &0.into())
    );
}

#[test]
fn viz_names_the_scenes_that_hold_the_models_object_and_resume_names_encoders_rightly() {
    let dir = tempfile::tempdir().unwrap();
    let data = dataset(dir.path());
    let run = dir.path().join("run");
    let train = |encoder: &'static str| {
        let mut words = train_single(&data, "box");
        words.extend([
            "--out",
            s(&run),
            "--val-split",
            "train",
            "--encoder",
            encoder,
        ]);
        words.extend([
            "--input-size",
            "32",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "1",
        ]);
        words.extend(["--batch-size", "2", "--query-level", "0", "--head", "16"]);
        words
    };
    ipdf_json(&train("small-cnn"));
    let out = ipdf(&train("resnet18"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("the checkpoint has encoder = small-cnn, this run asks for resnet18"),
        "{stderr}"
    );
    // The box (object 2) is in scene 1 only.
    let figure = dir.path().join("box.png");
    assert_fails(
        &viz_args(
            &run,
            &figure,
            &["--split", "train", "--scene", "0", "--image", "0"],
        ),
        "holds it in scene 1 (e.g. --scene 1 --image 0 --instance 0)",
    );
    assert!(!figure.exists());
}
