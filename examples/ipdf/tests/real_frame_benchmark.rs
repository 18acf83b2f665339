//! `scripts/real-frame-benchmark.sh`, the real YCB-Video fixture as a benchmark, run at a
//! miniature scale (a few renders, two brief epochs, one object) with this build's `ipdf`: it
//! runs `ipdf pipeline --mesh` from synthesis to the merged table, its table has a row per instance of the object in
//! the fixture's ground truth, and its summary is what those rows say. The scores themselves
//! are the full-scale run's (docs/results.md); a model this brief is not expected to be good.
mod common;

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

#[test]
fn the_benchmark_runs_and_its_table_holds_every_instance_of_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let run = Command::new("bash")
        .arg(workspace().join("scripts/real-frame-benchmark.sh"))
        .arg(&out)
        .arg(OBJECT.to_string())
        .envs([
            ("IPDF", env!("CARGO_BIN_EXE_ipdf")),
            ("FRAMES", "12"),
            ("VAL_FRAMES", "4"),
            ("EPOCHS", "2"),
            ("STEPS", "2"),
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "the benchmark failed ({}): {}",
        run.status,
        String::from_utf8_lossy(&run.stderr)
    );

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
