//! The guide's command blocks, run in order as a newcomer would, on a miniature scale:
//! `docs/guide.md`, the command-line walk the README links to, is the program's contract, and
//! this test keeps the two from drifting apart.
//!
//! Each block is split into commands (comments dropped, `\` continuations joined) and run with
//! `bash` in a fresh folder where `target/release/ipdf` is this build's binary, `tless` a
//! copy of the T-LESS layout fixture and `lmo` one of the real LM-O frame. Only sizes are shrunk ([`MINIATURE`]); every flag, path
//! and file the guide names is used as written.
use crate::common;

use std::path::Path;
use std::process::Command;

use common::copy_dir;

/// Flag values replaced, so that the walk takes seconds: (flag, value).
const MINIATURE: [(&str, &str); 5] = [
    ("--frames", "2"),
    ("--epochs", "1"),
    ("--steps-per-epoch", "1"),
    ("--batch-size", "2"),
    ("--input-size", "32"),
];

/// The commands of every `sh` block of `guide`, in order.
fn guide_commands(guide: &str) -> Vec<String> {
    let mut commands = Vec::new();
    let mut in_block = false;
    let mut pending = String::new();
    for line in guide.lines() {
        if line.starts_with("```") {
            in_block = line == "```sh";
            continue;
        }
        let line = line.trim();
        if !in_block || line.is_empty() || line.starts_with('#') {
            continue;
        }
        match line.strip_suffix('\\') {
            Some(part) => pending.push_str(part),
            None => {
                pending.push_str(line);
                commands.push(std::mem::take(&mut pending));
            }
        }
    }
    commands
}

/// `command` with the values of [`MINIATURE`]'s flags replaced.
fn miniature(command: &str) -> String {
    let words: Vec<&str> = command.split_whitespace().collect();
    let mut out: Vec<&str> = Vec::with_capacity(words.len());
    let mut k = 0;
    while k < words.len() {
        out.push(words[k]);
        if let Some((_, value)) = MINIATURE.iter().find(|(flag, _)| *flag == words[k])
            && k + 1 < words.len()
        {
            out.push(value);
            k += 1;
        }
        k += 1;
    }
    out.join(" ")
}

#[test]
fn the_readme_commands_run_in_order() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let guide = std::fs::read_to_string(root.join("docs/guide.md")).unwrap();
    let commands = guide_commands(&guide);
    assert!(commands.len() >= 15, "{commands:#?}");

    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("target/release")).unwrap();
    std::os::unix::fs::symlink(
        env!("CARGO_BIN_EXE_ipdf"),
        dir.path().join("target/release/ipdf"),
    )
    .unwrap();
    copy_dir(
        &root.join("examples/bop-dataset/tests/data/tless_layout"),
        &dir.path().join("tless"),
    );
    copy_dir(
        &root.join("examples/ipdf/tests/data/lmo_real"),
        &dir.path().join("lmo"),
    );
    copy_dir(
        &root.join("examples/pseudo-label/tests/data/ycbv_real"),
        &dir.path().join("ycbv"),
    );
    for command in &commands {
        let small = miniature(command);
        let out = Command::new("bash")
            .args(["-c", &small])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "guide command failed: {command}\nrun as: {small}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // What the guide says the commands write.
    for file in [
        "grid.npy",
        "grid_matrix.npy",
        "data/uniform/labels.json",
        "data/uniform/labels.md",
        "data/mugs/labels.md",
        "data/mugs/train/000000/scene_reference_gt.json",
        "depth.png",
        "rgb.png",
        "mask.png",
        "result.json",
        "runs/box_pseudo/train_log.csv",
        "eval.json",
        "pred.npy",
        "pred.json",
        "box.png",
        "box_curves.png",
        "tless_obj1.json",
        "lmo_eval.json",
        "lmo_eval.md",
        "lmo_pred.npy",
        "mustard/report.md",
        "mustard/eval_real.md",
    ] {
        assert!(dir.path().join(file).is_file(), "{file} was not written");
    }
    check_rendered_box(dir.path());
    // The figures the guide shows are drawn: each a picture, not a blank canvas.
    for figure in ["data/uniform/labels.png", "box.png", "box_curves.png"] {
        let path = dir.path().join(figure);
        let image = image::open(&path)
            .unwrap_or_else(|e| panic!("{figure}: {e}"))
            .to_rgb8();
        let drawn = image.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        let colours: std::collections::HashSet<[u8; 3]> = image.pixels().map(|p| p.0).collect();
        assert!(
            drawn * 50 > image.pixels().len() && colours.len() > 20,
            "{figure}: {drawn} drawn pixels, {} colours",
            colours.len()
        );
    }
}

/// The guide's `ipdf render` of the box: its mask is where its depth is, and the depth at the
/// pixel of the box's centre is the closed form's. The pose turns the box about x (cos 0.8,
/// sin 0.6) and sets it 700 mm ahead, so the ray through the centre leaves the box along the
/// model direction `Rᵀ·(0, 0, −1) = (0, −0.6, −0.8)`, at `min(e_y / 0.6, e_z / 0.8)` from the
/// centre for half-extents `e`.
fn check_rendered_box(dir: &Path) {
    let depth = image::open(dir.join("depth.png")).unwrap().to_luma16();
    let mask = image::open(dir.join("mask.png")).unwrap().to_luma8();
    assert_eq!(depth.dimensions(), mask.dimensions());
    for (d, m) in depth.pixels().zip(mask.pixels()) {
        assert_eq!(d.0[0] > 0, m.0[0] > 0, "the mask is where the depth is");
    }
    let read = |file: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.join(file)).unwrap()).unwrap()
    };
    let box_info = &read("data/uniform/models/models_info.json")["2"];
    let half = |axis: &str| box_info[format!("size_{axis}")].as_f64().unwrap() / 2.0;
    let exit = (half("y") / 0.6).min(half("z") / 0.8);
    let k = &read("data/uniform/camera.json");
    let (cx, cy) = (k["cx"].as_f64().unwrap(), k["cy"].as_f64().unwrap());
    let centre = depth.get_pixel(cx.round() as u32, cy.round() as u32).0[0];
    // The camera file's depth_scale: 0.1 mm per unit.
    let centre_mm = f64::from(centre) * k["depth_scale"].as_f64().unwrap();
    assert!(
        (centre_mm - (700.0 - exit)).abs() < 1.0,
        "depth {centre_mm} mm at the centre, expected {}",
        700.0 - exit
    );
}

#[test]
fn the_walk_shrinks_sizes_only() {
    let command = "ipdf train --frames 1000 --epochs 50 --object box --batch-size 64";
    assert_eq!(
        miniature(command),
        "ipdf train --frames 2 --epochs 1 --object box --batch-size 2"
    );
    let guide = "# Guide\n```sh\n# a comment\na --x \\\n    --y\n```\ntext\n```rust\nb\n```\n```text\nmake demo\n```\n## Next\n```sh\nc\n```\n";
    assert_eq!(guide_commands(guide), ["a --x --y", "c"]);
}
