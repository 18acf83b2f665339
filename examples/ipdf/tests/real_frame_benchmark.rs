//! `scripts/real-frame-benchmark.sh`, a real BOP dataset as a benchmark, run at a miniature scale
//! (a few renders, two brief epochs, one object) with this build's `ipdf`. On the real YCB-Video
//! fixture (its default) it runs `ipdf pipeline --mesh` from synthesis to the merged table, its
//! table has a row per instance of the object in the fixture's ground truth, and its summary is
//! what those rows say; on the LM-O fixture (`DATASET`: RGB only, boxes without masks, meshes
//! without colour) its camera is the frame's and nothing is scored against depth. The scores
//! themselves are the full-scale run's (docs/results.md); a model this brief is not expected to
//! be good.
use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::read_json;
use serde_json::Value;

/// The mustard bottle: two instances, 60% and 74% visible.
const OBJECT: u64 = 5;

/// The workspace's root.
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `(scene, image, instance)` of every ground-truth instance of `obj_id` in the fixture,
/// read from its `scene_gt.json` files.
fn fixture_instances(obj_id: u64) -> Vec<(u64, u64, u64)> {
    let test = workspace().join("examples/pseudo-label/tests/data/ycbv_real/test");
    let mut found = Vec::new();
    for scene in std::fs::read_dir(&test).unwrap() {
        let scene = scene.unwrap().path();
        let scene_id: u64 = scene
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .parse()
            .unwrap();
        let gt = read_json(&scene.join("scene_gt.json"));
        for (image, entries) in gt.as_object().unwrap() {
            for (k, entry) in entries.as_array().unwrap().iter().enumerate() {
                if entry["obj_id"].as_u64() == Some(obj_id) {
                    found.push((scene_id, image.parse().unwrap(), k as u64));
                }
            }
        }
    }
    found.sort();
    found
}

/// The number under `key` of a JSON object.
fn number(value: &Value, key: &str) -> f64 {
    value[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {key} in {value}"))
}

/// The script run at a miniature scale into `out` for `object`, with `env` beside it.
fn run_benchmark(out: &Path, object: u64, env: &[(&str, &Path)]) {
    let run = Command::new("bash")
        .arg(workspace().join("scripts/real-frame-benchmark.sh"))
        .arg(out)
        .arg(object.to_string())
        .envs([
            ("IPDF", env!("CARGO_BIN_EXE_ipdf")),
            ("FRAMES", "12"),
            ("VAL_FRAMES", "4"),
            ("EPOCHS", "2"),
            ("STEPS", "2"),
        ])
        .envs(env.iter().copied())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "the benchmark failed ({}): {}",
        run.status,
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
fn the_benchmark_runs_and_its_table_holds_every_instance_of_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    run_benchmark(&out, OBJECT, &[]);

    let expected = fixture_instances(OBJECT);
    assert!(!expected.is_empty());
    let merged = read_json(&out.join("real_frames.json"));
    let rows = merged["instances"].as_array().unwrap();
    let found: Vec<_> = rows
        .iter()
        .map(|r| ["scene_id", "im_id", "instance"].map(|k| r[k].as_u64().unwrap()))
        .map(|[scene, image, instance]| (scene, image, instance))
        .collect();
    assert_eq!(found, expected);
    // Each row is the object's own row of its run's real-frame scores.
    let report = read_json(&out.join(format!("obj_{OBJECT}/report.json")));
    let eval = &report["real"];
    for (row, own) in rows.iter().zip(eval["instances"].as_array().unwrap()) {
        assert_eq!(row["obj_id"].as_u64(), Some(OBJECT));
        for key in [
            "rotation_error_deg",
            "vsd",
            "llh",
            "translation_error_mm",
            "add_mm",
            "fitted_translation_error_mm",
            "fitted_add_mm",
            "refined_rotation_error_deg",
            "refined_vsd",
            "refined_translation_error_mm",
            "refined_add_mm",
        ] {
            assert_eq!(number(row, key), number(own, key), "{key}");
        }
    }

    // The summary is what the rows say, counted here.
    let summary = &merged["summary"];
    let n = rows.len() as f64;
    let share = |pass: &dyn Fn(&Value) -> bool| rows.iter().filter(|r| pass(r)).count() as f64 / n;
    let uniform = -(std::f64::consts::PI.powi(2)).ln();
    let diameter = number(&eval["pose"], "diameter_mm");
    assert_eq!(number(summary, "instances"), n);
    let checks = [
        ("acc_15", share(&|r| number(r, "rotation_error_deg") < 15.0)),
        ("acc_30", share(&|r| number(r, "rotation_error_deg") < 30.0)),
        (
            "acc_15_or_vsd",
            share(&|r| number(r, "rotation_error_deg") < 15.0 || number(r, "vsd") < 0.3),
        ),
        ("above_uniform", share(&|r| number(r, "llh") > uniform)),
        (
            "add_accuracy",
            share(&|r| number(r, "add_mm") < 0.1 * diameter),
        ),
        (
            "fitted_add_accuracy",
            share(&|r| number(r, "fitted_add_mm") < 0.1 * diameter),
        ),
        (
            "refined_acc_15_or_vsd",
            share(&|r| {
                number(r, "refined_rotation_error_deg") < 15.0 || number(r, "refined_vsd") < 0.3
            }),
        ),
        (
            "refined_add_accuracy",
            share(&|r| number(r, "refined_add_mm") < 0.1 * diameter),
        ),
        (
            "translation_over_50mm",
            n * share(&|r| number(r, "translation_error_mm") > 50.0),
        ),
        (
            "fitted_translation_over_50mm",
            n * share(&|r| number(r, "fitted_translation_error_mm") > 50.0),
        ),
    ];
    for (key, expected) in checks {
        assert!((number(summary, key) - expected).abs() < 1e-12, "{key}");
    }

    // The Markdown table: a header, a rule, a row per instance, then the summary line.
    let table = std::fs::read_to_string(out.join("real_frames.md")).unwrap();
    let lines: Vec<&str> = table.lines().collect();
    assert!(
        lines[0].starts_with("| scene | image | obj | visible |"),
        "{table}"
    );
    let columns = lines[0].matches('|').count();
    let body = &lines[2..2 + rows.len()];
    assert!(
        body.iter().all(|l| l.matches('|').count() == columns),
        "{table}"
    );
    assert!(body.iter().all(|l| l.starts_with("| ")), "{table}");
    assert!(lines[2 + rows.len()].is_empty(), "{table}");
    let last = lines[3 + rows.len()];
    assert!(
        last.starts_with(&format!("{} instances: Acc@15°", rows.len())),
        "{table}"
    );
}

#[test]
fn a_dataset_without_depth_is_scored_on_its_frames_camera_without_depth_scores() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let lmo = workspace().join("examples/ipdf/tests/data/lmo_real");
    // The duck: one instance, 96% visible, in the frame of scene 2, image 3.
    run_benchmark(&out, 9, &[("DATASET", &lmo)]);

    // No camera.json at the dataset's root: the renders' camera is the frame's cam_K and
    // depth_scale, and its colour image's size.
    let camera = read_json(&out.join("camera.json"));
    let frame = &read_json(&lmo.join("test/000002/scene_camera.json"))["3"];
    let k = &frame["cam_K"];
    for (key, at) in [("fx", 0), ("fy", 4), ("cx", 2), ("cy", 5)] {
        assert_eq!(camera[key], k[at], "{key}");
    }
    assert_eq!(camera["depth_scale"], frame["depth_scale"]);
    let (width, height) = image::image_dimensions(lmo.join("test/000002/rgb/000003.png")).unwrap();
    assert_eq!([&camera["width"], &camera["height"]], [width, height]);

    let merged = read_json(&out.join("real_frames.json"));
    let rows = merged["instances"].as_array().unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!([&rows[0]["scene_id"], &rows[0]["im_id"]], [2, 3]);
    assert!(rows[0].get("vsd").is_none(), "{}", rows[0]);
    let summary = &merged["summary"];
    for key in [
        "acc_15_or_vsd",
        "median_fitted_translation_error_mm",
        "fitted_add_accuracy",
        "refined_acc_15_or_vsd",
        "refined_add_accuracy",
    ] {
        assert!(summary[key].is_null(), "{key}: {summary}");
    }
    let error = number(&rows[0], "rotation_error_deg");
    assert_eq!(number(summary, "acc_15"), f64::from(u8::from(error < 15.0)));
    let table = std::fs::read_to_string(out.join("real_frames.md")).unwrap();
    assert!(
        table.contains("no depth under the visible masks"),
        "{table}"
    );
}

#[test]
fn a_dataset_it_cannot_read_is_refused_naming_what_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let refused = |ids: &[&str]| -> String {
        let run = Command::new("bash")
            .arg(workspace().join("scripts/real-frame-benchmark.sh"))
            .arg(dir.path().join("out"))
            .args(ids)
            .env("IPDF", env!("CARGO_BIN_EXE_ipdf"))
            .env("DATASET", &data)
            .output()
            .unwrap();
        assert!(!run.status.success());
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    std::fs::create_dir_all(data.join("models")).unwrap();
    let error = refused(&[]);
    assert!(error.contains("models holds no obj_NNNNNN.ply"), "{error}");
    // An object named, but no camera: neither camera.json nor a scene_camera.json.
    let error = refused(&["3"]);
    assert!(
        error.contains("no camera.json") && error.contains("test/*/scene_camera.json"),
        "{error}"
    );
    let scene = data.join("test/000001");
    std::fs::create_dir_all(scene.join("rgb")).unwrap();
    std::fs::write(
        scene.join("scene_camera.json"),
        r#"{"5": {"cam_K": [600, 0, 320, 0, 600, 240, 0, 0, 1]}}"#,
    )
    .unwrap();
    let error = refused(&["3"]);
    assert!(
        error.contains("no image") && error.contains("000005"),
        "{error}"
    );
    std::fs::write(scene.join("rgb/000005.jpg"), b"not an image").unwrap();
    let error = refused(&["3"]);
    assert!(
        error.contains("rgb/000005.jpg: neither a PNG nor a JPEG"),
        "{error}"
    );
}
