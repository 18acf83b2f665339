//! Helpers shared by the command-line tests: running the real `ipdf` binary.
#![allow(dead_code)] // each test file uses its own subset

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

/// The training flags of a barely trained run (two epochs of three steps of four crops): the
/// tests that check files, shapes and ranges, not accuracy.
pub const BRIEF_TRAINING: [&str; 6] = [
    "--epochs",
    "2",
    "--steps-per-epoch",
    "3",
    "--batch-size",
    "4",
];

/// The network of the barely trained runs: a small CNN on 32-pixel crops, a 16,16 head.
pub const SMALL_NETWORK: [&str; 6] = [
    "--encoder",
    "small-cnn",
    "--input-size",
    "32",
    "--head",
    "16,16",
];

/// The shape of a float32 `.npy` file and its values in order.
pub fn read_npy(path: &Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    (shape, npy.into_vec::<f32>().unwrap())
}

/// Runs `ipdf` with `args`.
pub fn ipdf(args: &[&str]) -> Output {
    ipdf_in(Path::new("."), args)
}

/// Runs `ipdf` with `args` in the folder `dir`.
pub fn ipdf_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ipdf"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("ipdf runs")
}

/// Runs `ipdf … --json`, asserts success and parses its JSON line.
pub fn ipdf_json(args: &[&str]) -> Value {
    let mut args = args.to_vec();
    args.push("--json");
    let out = ipdf(&args);
    assert!(
        out.status.success(),
        "ipdf {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one line of JSON")
}

/// Asserts that `ipdf args` fails with one line on standard error containing `expected`.
pub fn assert_fails(args: &[&str], expected: &str) {
    let out = ipdf(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "ipdf {args:?} succeeded");
    assert!(stderr.contains(expected), "ipdf {args:?}: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
}

/// The words of `ipdf synth` of `objects` (comma-separated) into `out`, `frames` frames of
/// each, then `extra`.
pub fn synth_args<'a>(
    out: &'a Path,
    objects: &'a str,
    frames: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        "synth",
        "--out",
        s(out),
        "--objects",
        objects,
        "--frames",
        frames,
    ];
    args.extend_from_slice(extra);
    args
}

/// `ipdf synth` of `objects` into `out` with `extra` flags (see [`synth_args`]): its JSON line.
pub fn synth(out: &Path, objects: &str, frames: usize, extra: &[&str]) -> Value {
    let frames = frames.to_string();
    ipdf_json(&synth_args(out, objects, &frames, extra))
}

/// The words of `ipdf train` on the dataset at `data` with `labels` labels, then `extra`.
pub fn train_args<'a>(data: &'a Path, labels: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["train", "--dataset", s(data), "--labels", labels];
    args.extend_from_slice(extra);
    args
}

/// The words of `ipdf command`: each flag of `files` followed by its file, then `extra`.
pub fn command_args<'a>(
    command: &'a str,
    files: &[(&'a str, &'a Path)],
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![command];
    for &(flag, path) in files {
        args.extend([flag, s(path)]);
    }
    args.extend_from_slice(extra);
    args
}

/// The words of `ipdf predict` of the model at `run` on the object in `mask` of the image
/// `rgb`, into `out`, then `extra`.
pub fn predict_args<'a>(
    run: &'a Path,
    rgb: &'a Path,
    mask: &'a Path,
    out: &'a Path,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let files = [("--checkpoint", run), ("--rgb", rgb), ("--mask", mask)];
    command_args("predict", &[&files[..], &[("--out", out)]].concat(), extra)
}

/// The words of `ipdf viz` of the model at `run` into `out`, then `extra` (the scene and image).
pub fn viz_args<'a>(run: &'a Path, out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    command_args("viz", &[("--checkpoint", run), ("--out", out)], extra)
}

/// The start of `ipdf train` on `object`'s single labels of the dataset at `data`.
pub fn train_single<'a>(data: &'a Path, object: &'a str) -> Vec<&'a str> {
    let data = s(data);
    vec![
        "train",
        "--dataset",
        data,
        "--object",
        object,
        "--labels",
        "single",
    ]
}

/// The JSON file at `path`, naming it when it cannot be read or parsed.
pub fn read_json(path: &Path) -> Value {
    serde_json::from_slice(
        &std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The numbers of a JSON array (a BOP `cam_R_m2c`, a 4 × 4 matrix), in order.
pub fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {value}"))
        .iter()
        .map(|v| v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")))
        .collect()
}

/// Owned arguments as the `&str`s the helpers take.
pub fn strs(words: &[String]) -> Vec<&str> {
    words.iter().map(String::as_str).collect()
}

/// `path` as a `&str`.
pub fn s(path: &Path) -> &str {
    path.to_str().expect("UTF-8 path")
}

/// Copies the folder `from` into `to`, recursively.
pub fn copy_dir(from: &Path, to: &Path) {
    bop_dataset::copy_dataset(from, to).unwrap();
}
