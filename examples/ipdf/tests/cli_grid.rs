//! `ipdf grid` through the real binary.
use std::process::Command;

fn ipdf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ipdf"))
        .args(args)
        .output()
        .expect("ipdf runs")
}

#[test]
fn level_4_json_summary() {
    let out = ipdf(&["grid", "--level", "4", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["level"], 4);
    assert_eq!(summary["count"], 294_912);
    let volume = summary["cell_volume"].as_f64().unwrap();
    assert!((volume * 294_912.0 - std::f64::consts::PI.powi(2)).abs() < 1e-9);
}

#[test]
fn writes_quaternions_and_matrices_as_npy() {
    let dir = tempfile::tempdir().unwrap();
    let quat = dir.path().join("grid.npy");
    let matrix = dir.path().join("sub/grid_matrix.npy");
    for (path, format) in [(&quat, "quat"), (&matrix, "matrix")] {
        let out = ipdf(&[
            "grid",
            "--level",
            "2",
            "--out",
            path.to_str().unwrap(),
            "--format",
            format,
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (quat_bytes, matrix_bytes) = (
        std::fs::read(&quat).unwrap(),
        std::fs::read(&matrix).unwrap(),
    );
    let quats = npyz::NpyFile::new(quat_bytes.as_slice()).unwrap();
    assert_eq!(quats.shape(), &[4608, 4]);
    let q: Vec<f32> = quats.into_vec().unwrap();
    let mats = npyz::NpyFile::new(matrix_bytes.as_slice()).unwrap();
    assert_eq!(mats.shape(), &[4608, 3, 3]);
    let m: Vec<f32> = mats.into_vec().unwrap();
    for (q, m) in q.chunks(4).zip(m.chunks(9)) {
        assert!(q[0] >= 0.0 && (q.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-5);
        // The matrix's trace is 4w² − 1.
        assert!((m[0] + m[4] + m[8] - (4.0 * q[0] * q[0] - 1.0)).abs() < 1e-4);
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn bad_flags_fail_with_a_one_line_cause() {
    for args in [
        &["grid", "--level", "9"][..],
        &["grid"][..],
        &["grid", "--level", "2", "--format", "euler"][..],
        &["grid", "--level", "1", "--out", "/proc/forbidden/grid.npy"][..],
    ] {
        let out = ipdf(args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.trim_start().starts_with("error"),
            "{args:?}: {stderr}"
        );
    }
}

/// The flags whose values name a library enum (parsed by the CLI's one `choice` parser).
#[test]
fn unknown_names_of_library_values_name_the_flag() {
    for (args, flag, bad) in [
        (
            &["grid", "--level", "1", "--format", "euler"][..],
            "--format",
            "euler",
        ),
        (
            &["synth", "--out", "x", "--objects", "can,teapot"][..],
            "--objects",
            "teapot",
        ),
        (
            &["synth", "--out", "x", "--variant", "glossy"][..],
            "--variant",
            "glossy",
        ),
        (
            &["label", "--dataset", "x", "--strategy", "guess"][..],
            "--strategy",
            "guess",
        ),
        (
            &["train", "--dataset", "x", "--out", "y", "--labels", "gt"][..],
            "--labels",
            "gt",
        ),
        (
            &["pipeline", "--out", "x", "--preset", "huge"][..],
            "--preset",
            "huge",
        ),
        (
            &["synth", "--out", "x", "--placement", "upside-down"][..],
            "--placement",
            "upside-down",
        ),
        (
            &[
                "pipeline",
                "--out",
                "x",
                "--mesh",
                "m.ply",
                "--placement",
                "propped",
            ][..],
            "--placement",
            "propped",
        ),
        (
            &["eval", "--checkpoint", "x", "--sensor", "lidar"][..],
            "--sensor",
            "lidar",
        ),
        (
            &["predict", "--checkpoint", "x", "--sensor", "lidar"][..],
            "--sensor",
            "lidar",
        ),
        (
            &["eval", "--checkpoint", "x", "--views", "9"][..],
            "--views",
            "9",
        ),
        (
            &["predict", "--checkpoint", "x", "--views", "twelve"][..],
            "--views",
            "twelve",
        ),
        (
            &[
                "train",
                "--dataset",
                "d",
                "--labels",
                "single",
                "--out",
                "o",
                "--rotation-frame",
                "object",
            ][..],
            "--rotation-frame",
            "object",
        ),
        (
            &["pipeline", "--out", "o", "--rotation-frame", "world"][..],
            "--rotation-frame",
            "world",
        ),
        (
            &["pipeline", "--out", "o", "--rotation-members", "9"][..],
            "--rotation-members",
            "9",
        ),
        (
            &["pipeline", "--out", "o", "--rotation-members", "two"][..],
            "--rotation-members",
            "two",
        ),
    ] {
        let out = ipdf(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        let expected = format!("invalid value '{bad}' for '{flag} <");
        assert!(stderr.contains(&expected), "{args:?}: {stderr}");
    }
    // The built-in objects are listed with their sizes.
    let help = ipdf(&["synth", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("box:") && help.contains("60 × 158 × 210 mm"),
        "{help}"
    );
}
