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
