//! Helpers shared by the command-line tests: running the real `ipdf` binary.
#![allow(dead_code)] // each test file uses its own subset

use std::path::Path;
use std::process::{Command, Output};

/// Runs `ipdf` with `args`.
pub fn ipdf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ipdf"))
        .args(args)
        .output()
        .expect("ipdf runs")
}

/// Runs `ipdf … --json`, asserts success and parses its JSON line.
pub fn ipdf_json(args: &[&str]) -> serde_json::Value {
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

/// `path` as a `&str`.
pub fn s(path: &Path) -> &str {
    path.to_str().expect("UTF-8 path")
}

/// Copies the folder `from` into `to`, recursively.
pub fn copy_dir(from: &Path, to: &Path) {
    bop_dataset::copy_dataset(from, to).unwrap();
}
