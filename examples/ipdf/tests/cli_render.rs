//! `ipdf render` through the real binary: BOP inputs in, BOP PNGs out, one-line errors.
use std::path::{Path, PathBuf};
use std::process::Command;

fn ipdf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ipdf"))
        .args(args)
        .output()
        .expect("ipdf runs")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A 40 mm cube centred at the origin, as a BOP-style ASCII PLY in millimetres.
fn cube_ply() -> String {
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
         property float z\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for i in 0..8 {
        let c = |bit: usize| if i >> bit & 1 == 1 { 20 } else { -20 };
        text += &format!("{} {} {}\n", c(0), c(1), c(2));
    }
    for face in [
        "0 4 6 2", "1 3 7 5", "0 1 5 4", "2 6 7 3", "0 2 3 1", "4 5 7 6",
    ] {
        text += &format!("4 {face}\n");
    }
    text
}

const CAMERA: &str = r#"{"cam_K": [500, 0, 80, 0, 500, 60, 0, 0, 1], "width": 160, "height": 120}"#;
const POSE: &str = r#"{"cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 500]}"#;

struct Inputs {
    dir: tempfile::TempDir,
    mesh: PathBuf,
    camera: PathBuf,
    pose: PathBuf,
}

fn inputs() -> Inputs {
    let dir = tempfile::tempdir().unwrap();
    let mesh = write(dir.path(), "obj_000001.ply", &cube_ply());
    let camera = write(dir.path(), "cam.json", CAMERA);
    let pose = write(dir.path(), "pose.json", POSE);
    Inputs {
        dir,
        mesh,
        camera,
        pose,
    }
}

/// `ipdf render` of `mesh` at `pose` seen by `camera`, depth to `out`.
fn render_args<'a>(
    mesh: &'a Path,
    camera: &'a Path,
    pose: &'a Path,
    out: &'a Path,
) -> Vec<&'a str> {
    vec![
        "render",
        "--mesh",
        mesh.to_str().unwrap(),
        "--camera",
        camera.to_str().unwrap(),
        "--pose",
        pose.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]
}

#[test]
fn renders_bop_depth_rgb_and_mask() {
    let input = inputs();
    let out = |name: &str| input.dir.path().join(name);
    let (depth, rgb, mask) = (out("depth.png"), out("rgb.png"), out("mask.png"));
    let mut args = render_args(&input.mesh, &input.camera, &input.pose, &depth);
    args.extend([
        "--rgb",
        rgb.to_str().unwrap(),
        "--mask",
        mask.to_str().unwrap(),
        "--depth-scale",
        "0.1",
        "--json",
    ]);
    let result = ipdf(&args);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    // The front face (z = 480 mm) spans ±20 mm: ±20.83 px around the principal point → 41².
    assert_eq!(summary["pixels"], 41 * 41);
    assert_eq!(summary["bbox"], serde_json::json!([60, 40, 101, 81]));

    let depth = image::open(out("depth.png")).unwrap().into_luma16();
    let mask = image::open(out("mask.png")).unwrap().into_luma8();
    let rgb = image::open(out("rgb.png")).unwrap().into_rgb8();
    assert_eq!(depth.dimensions(), (160, 120));
    // 480 mm in units of 0.1 mm.
    assert_eq!(depth.get_pixel(80, 60).0[0], 4800);
    assert_eq!(depth.get_pixel(0, 0).0[0], 0);
    for (d, m) in depth.pixels().zip(mask.pixels()) {
        assert_eq!(d.0[0] > 0, m.0[0] == 255);
    }
    assert!(rgb.get_pixel(80, 60).0[0] > 0 && rgb.get_pixel(0, 0).0 == [0, 0, 0]);
}

#[test]
fn bad_inputs_exit_non_zero_with_the_file_and_field() {
    let input = inputs();
    let depth = input.dir.path().join("depth.png");
    let run = |mesh: &Path, camera: &Path, pose: &Path, extra: &[&str]| {
        let mut args = render_args(mesh, camera, pose, &depth);
        args.extend_from_slice(extra);
        let out = ipdf(&args);
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        stderr
    };
    let dir = input.dir.path();
    let skewed = write(
        dir,
        "skewed.json",
        r#"{"cam_R_m2c": [1, 0.1, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 500]}"#,
    );
    let e = run(&input.mesh, &input.camera, &skewed, &[]);
    assert!(e.contains("skewed.json") && e.contains("cam_R_m2c"), "{e}");
    let short = write(
        dir,
        "short.json",
        r#"{"cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0]}"#,
    );
    let e = run(&input.mesh, &input.camera, &short, &[]);
    assert!(e.contains("short.json") && e.contains("cam_t_m2c"), "{e}");
    let flat = write(
        dir,
        "flat.json",
        r#"{"cam_K": [0, 0, 80, 0, 500, 60, 0, 0, 1], "width": 160, "height": 120}"#,
    );
    let e = run(&input.mesh, &flat, &input.pose, &[]);
    assert!(e.contains("flat.json") && e.contains("cam_K"), "{e}");
    let sizeless = write(
        dir,
        "sizeless.json",
        r#"{"cam_K": [500, 0, 80, 0, 500, 60, 0, 0, 1], "width": 0, "height": 120}"#,
    );
    let e = run(&input.mesh, &sizeless, &input.pose, &[]);
    assert!(e.contains("sizeless.json") && e.contains("width"), "{e}");
    let garbage = write(dir, "garbage.json", "{not json");
    let e = run(&input.mesh, &input.camera, &garbage, &[]);
    assert!(e.contains("garbage.json"), "{e}");
    let truncated = write(dir, "truncated.ply", &cube_ply()[..200]);
    let e = run(&truncated, &input.camera, &input.pose, &[]);
    assert!(e.contains("truncated.ply"), "{e}");
    let e = run(&dir.join("missing.ply"), &input.camera, &input.pose, &[]);
    assert!(e.contains("missing.ply"), "{e}");
    // 480 mm in units of 0.001 mm overflows uint16.
    let e = run(
        &input.mesh,
        &input.camera,
        &input.pose,
        &["--depth-scale", "0.001"],
    );
    assert!(e.contains("depth.png") && e.contains("uint16"), "{e}");
    let e = run(
        &input.mesh,
        &input.camera,
        &input.pose,
        &["--depth-scale", "0"],
    );
    assert!(e.contains("--depth-scale"), "{e}");
    let e = run(
        &input.mesh,
        &input.camera,
        &input.pose,
        &["--mesh-scale=-1"],
    );
    assert!(e.contains("obj_000001.ply") && e.contains("scale"), "{e}");
    assert!(!depth.exists(), "no partial output");
}

#[test]
fn a_sensor_changes_depth_deterministically_per_seed() {
    let input = inputs();
    let render = |seed: &str, name: &str| {
        let path = input.dir.path().join(name);
        let mut args = render_args(&input.mesh, &input.camera, &input.pose, &path);
        args.extend([
            "--depth-scale",
            "0.1",
            "--sensor",
            "realsense",
            "--seed",
            seed,
        ]);
        let out = ipdf(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        image::open(path).unwrap().into_luma16().into_raw()
    };
    let (a, b, c) = (
        render("1", "a.png"),
        render("1", "b.png"),
        render("2", "c.png"),
    );
    assert_eq!(a, b);
    assert_ne!(a, c);
    // In the RealSense's 1 mm units (10 units of 0.1 mm), within a few σ of 480 mm.
    let centre = a[60 * 160 + 80];
    assert!(
        centre % 10 == 0 && (4700..=4900).contains(&centre),
        "{centre}"
    );
}

#[test]
fn a_messy_mesh_renders_as_the_clean_one_with_one_warning_line() {
    let input = inputs();
    // Two unused vertices and two faces with a repeated corner.
    let messy = cube_ply()
        .replace("element vertex 8", "element vertex 10")
        .replace("element face 6", "element face 8")
        .replace("end_header\n", "end_header\n0 0 900\n5 5 900\n")
        .replace("\n4 0 4 6 2", "\n3 1 1 4\n3 2 2 5\n4 0 4 6 2");
    // The two extra vertices shift the cube's indices by 2.
    let mut lines: Vec<String> = messy.lines().map(String::from).collect();
    let header_end = lines.iter().position(|l| l == "end_header").unwrap();
    for line in lines.iter_mut().skip(header_end + 11) {
        let numbers: Vec<u32> = line.split(' ').map(|w| w.parse().unwrap()).collect();
        let shifted: Vec<String> = std::iter::once(numbers[0].to_string())
            .chain(numbers[1..].iter().map(|i| (i + 2).to_string()))
            .collect();
        *line = shifted.join(" ");
    }
    let messy = write(input.dir.path(), "messy.ply", &(lines.join("\n") + "\n"));
    let (clean_depth, messy_depth) = (
        input.dir.path().join("clean.png"),
        input.dir.path().join("messy.png"),
    );
    let clean = ipdf(&render_args(
        &input.mesh,
        &input.camera,
        &input.pose,
        &clean_depth,
    ));
    assert!(clean.status.success() && clean.stderr.is_empty());
    let mut args = render_args(&messy, &input.camera, &input.pose, &messy_depth);
    args.push("--json");
    let out = ipdf(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("warning: ")
            && stderr.contains(
                "messy.ply: dropped 2 zero-area triangles, dropped 2 unreferenced vertices"
            ),
        "{stderr}"
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        summary["mesh_repairs"],
        serde_json::json!({"degenerate_triangles": 2, "unreferenced_vertices": 2, "normals": 0})
    );
    assert_eq!(
        std::fs::read(&clean_depth).unwrap(),
        std::fs::read(&messy_depth).unwrap()
    );
}
