//! `ipdf register` through the real binary: PLY clouds in, a JSON pose out, one-line errors.
use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ipdf::cloud_file::write_cloud;
use nalgebra::Isometry3;
use registration::PointCloud;
use synth_data::trials::{egg_mesh, model_cloud, registration_trials};

fn ipdf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ipdf"))
        .args(args)
        .output()
        .expect("ipdf runs")
}

/// The one-line error of a failed run.
fn error_of(out: &Output) -> String {
    assert!(!out.status.success(), "expected failure");
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    stderr
}

struct Clouds {
    dir: tempfile::TempDir,
    source: PathBuf,
    target: PathBuf,
    truth: Isometry3<f64>,
}

/// The trial egg's model and one rendered view of it, as PLY files.
fn clouds() -> Clouds {
    let dir = tempfile::tempdir().unwrap();
    let mesh = egg_mesh().unwrap();
    let trial = registration_trials(&mesh, 1, 3).unwrap().remove(0);
    let (source, target) = (dir.path().join("model.ply"), dir.path().join("view.ply"));
    write_cloud(&source, &model_cloud(&mesh, 40_000, 3).unwrap()).unwrap();
    write_cloud(&target, &trial.view).unwrap();
    Clouds {
        dir,
        source,
        target,
        truth: trial.truth,
    }
}

fn register_args<'a>(source: &'a Path, target: &'a Path) -> Vec<&'a str> {
    vec![
        "register",
        "--source",
        source.to_str().unwrap(),
        "--target",
        target.to_str().unwrap(),
    ]
}

fn transformation(value: &serde_json::Value) -> Isometry3<f64> {
    let m = common::numbers(&value["transformation"]);
    let matrix = nalgebra::Matrix4::from_row_slice(&m);
    let rotation = nalgebra::Rotation3::from_matrix(&matrix.fixed_view::<3, 3>(0, 0).into_owned());
    Isometry3::from_parts(
        nalgebra::Translation3::new(m[3], m[7], m[11]),
        rotation.into(),
    )
}

#[test]
fn registers_a_view_to_its_model_and_writes_json() {
    let clouds = clouds();
    let out = clouds.dir.path().join("result.json");
    let mut args = register_args(&clouds.source, &clouds.target);
    args.extend(["--out", out.to_str().unwrap(), "--json", "--seed", "7"]);
    let run = ipdf(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let printed: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(printed, written);
    for key in ["fitness", "inlier_rmse", "fgr_ms", "icp_ms", "features_ms"] {
        assert!(
            written[key].as_f64().is_some_and(f64::is_finite),
            "{key}: {written}"
        );
    }
    let found = transformation(&written);
    let error = found.inverse() * clouds.truth;
    assert!(error.rotation.angle().to_degrees() < 2.0, "{written}");
    assert!(
        (found.translation.vector - clouds.truth.translation.vector).norm() < 0.005,
        "{written}"
    );

    // Same seed, same pose; the result can seed another run as its initial pose.
    let again: serde_json::Value = serde_json::from_slice(&ipdf(&args).stdout).unwrap();
    assert_eq!(again["transformation"], written["transformation"]);
    let angle_from = |extra: &[&str]| {
        let mut args = register_args(&clouds.source, &clouds.target);
        args.extend(extra);
        args.push("--json");
        let run = ipdf(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let found = transformation(&serde_json::from_slice(&run.stdout).unwrap());
        (found.inverse() * clouds.truth)
            .rotation
            .angle()
            .to_degrees()
    };
    let angle = angle_from(&["--initial", out.to_str().unwrap()]);
    assert!(angle < 2.0, "{angle}° from the initial pose");
    // Point-to-point ICP settles less precisely between 5 mm samples than point-to-plane.
    let angle = angle_from(&["--icp", "point-to-point"]);
    assert!(angle < 5.0, "{angle}° with point-to-point ICP");
}

#[test]
fn bad_inputs_fail_with_one_line_naming_the_cause() {
    let clouds = clouds();
    let dir = clouds.dir.path();
    let missing = dir.join("missing.ply");
    assert!(error_of(&ipdf(&register_args(&missing, &clouds.target))).contains("missing.ply"));

    let truncated = dir.join("truncated.ply");
    let bytes = std::fs::read(&clouds.target).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    assert!(error_of(&ipdf(&register_args(&clouds.source, &truncated))).contains("truncated.ply"));

    let empty = dir.join("empty.ply");
    write_cloud(&empty, &PointCloud::new(Vec::new()).unwrap()).unwrap();
    assert!(error_of(&ipdf(&register_args(&clouds.source, &empty))).contains("empty"));

    let plane = dir.join("plane.ply");
    let flat: Vec<_> = (0..4000)
        .map(|i| nalgebra::Point3::new((i % 64) as f32 * 0.002, (i / 64) as f32 * 0.002, 0.6))
        .collect();
    write_cloud(&plane, &PointCloud::new(flat).unwrap()).unwrap();
    let message = error_of(&ipdf(&register_args(&clouds.source, &plane)));
    assert!(
        message.contains("plane.ply") && message.contains("coplanar"),
        "{message}"
    );

    let mut args = register_args(&clouds.source, &clouds.target);
    args.push("--voxel=0");
    assert!(error_of(&ipdf(&args)).contains("--voxel must be a positive number"));
    let mut args = register_args(&clouds.source, &clouds.target);
    args.push("--scale=0");
    assert!(error_of(&ipdf(&args)).contains("--scale"));
    let mut args = register_args(&clouds.source, &clouds.target);
    args.extend(["--hypotheses", "0"]);
    assert!(error_of(&ipdf(&args)).contains("hypotheses"));

    let initial = dir.join("initial.json");
    std::fs::write(
        &initial,
        r#"{"transformation": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]}"#,
    )
    .unwrap();
    let mut args = register_args(&clouds.source, &clouds.target);
    args.extend(["--initial", initial.to_str().unwrap()]);
    let message = error_of(&ipdf(&args));
    assert!(
        message.contains("initial.json") && message.contains("transformation"),
        "{message}"
    );
}
