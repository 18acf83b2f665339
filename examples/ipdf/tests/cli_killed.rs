//! Writers killed in the middle of a write, then run again: the folder ends byte for byte as an
//! uninterrupted run's, with no extra file. The kill comes from the file-size limit
//! (`RLIMIT_FSIZE`, bash's `ulimit -f`): the kernel sends `SIGXFSZ`, whose default action ends
//! the process, to a write that would take a file past the limit. So the process dies inside a
//! write of the first file that grows past the size the test picks, at a point that no timer or
//! machine load moves.
use crate::common;

use std::collections::BTreeMap;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{ipdf_json, s, synth, synth_args};

/// `SIGXFSZ` on Linux (x86-64 and aarch64).
const SIGXFSZ: i32 = 25;

/// Runs `ipdf args` with files limited to `limit_kib` KiB and asserts that the limit killed it.
fn killed_while_writing(args: &[&str], limit_kib: u32) {
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!("ulimit -f {limit_kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_ipdf"))
        .args(args)
        .output()
        .unwrap();
    assert_eq!(
        out.status.signal(),
        Some(SIGXFSZ),
        "ipdf {args:?} under {limit_kib} KiB: {:?} {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every file under `dir` (hidden ones too), by path relative to `dir`, with its bytes.
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, folder: &Path, files: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for entry in std::fs::read_dir(folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(root, &path, files);
                continue;
            }
            let bytes = std::fs::read(&path).unwrap();
            files.insert(path.strip_prefix(root).unwrap().to_path_buf(), bytes);
        }
    }
    let mut files = BTreeMap::new();
    walk(dir, dir, &mut files);
    files
}

/// The files of `tree` whose names mark an unfinished write.
fn partial_files(tree: &BTreeMap<PathBuf, Vec<u8>>) -> Vec<&PathBuf> {
    let partial = |path: &&PathBuf| {
        let name = path.file_name().unwrap().to_string_lossy();
        name.starts_with('.') && name.ends_with(bop_dataset::PARTIAL_SUFFIX)
    };
    tree.keys().filter(partial).collect()
}

/// `killed` equals `whole` file by file, naming the first difference.
fn assert_same_files(killed: &Path, whole: &Path) {
    let (killed, whole) = (tree(killed), tree(whole));
    let names = |tree: &BTreeMap<PathBuf, Vec<u8>>| tree.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(&killed), names(&whole), "the files after the rerun");
    for (path, bytes) in &whole {
        assert!(killed[path] == *bytes, "{}: other bytes", path.display());
    }
}

#[test]
fn a_synth_run_killed_mid_write_reruns_to_the_same_files() {
    let words = |out: &Path| {
        let mut words = synth_args(out, "can,box", "4", &["--frames-per-scene", "2"]);
        words.extend(["--sensor", "kinect", "--seed", "3"]);
        words.into_iter().map(str::to_string).collect::<Vec<_>>()
    };
    let whole = tempfile::tempdir().unwrap();
    let args = words(whole.path());
    ipdf_json(&args.iter().map(String::as_str).collect::<Vec<_>>());
    // The limits land the kill in the first mask, depth or colour image past each size, in
    // whichever of the frames rendered in parallel writes it first.
    for limit_kib in [2, 24, 96] {
        let killed = tempfile::tempdir().unwrap();
        let args = words(killed.path());
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        killed_while_writing(&args, limit_kib);
        let left = tree(killed.path());
        assert!(
            !partial_files(&left).is_empty(),
            "under {limit_kib} KiB the kill came outside a write: {:?}",
            left.keys().collect::<Vec<_>>()
        );
        ipdf_json(&args);
        assert_same_files(killed.path(), whole.path());
    }
}

#[test]
fn a_labelling_run_killed_mid_write_reruns_to_the_same_files() {
    let data = tempfile::tempdir().unwrap();
    synth(data.path(), "box", 4, &["--frames-per-scene", "2"]);
    let whole = tempfile::tempdir().unwrap();
    common::copy_dir(data.path(), whole.path());
    ipdf_json(&["label", "--dataset", s(whole.path())]);
    // A scene's `scene_pseudo_gt.json` (the labels of 2 instances and their scores, about
    // 2.4 KiB) is the first file past 2 KiB that labelling writes (`label_options.json` is
    // under 0.5 KiB): the kill lands while the first scene's labels are written.
    let killed = tempfile::tempdir().unwrap();
    common::copy_dir(data.path(), killed.path());
    let args = ["label", "--dataset", s(killed.path())];
    killed_while_writing(&args, 2);
    let left = tree(killed.path());
    let partial = partial_files(&left);
    assert!(
        partial
            .iter()
            .any(|path| path.ends_with(".scene_pseudo_gt.json.partial")),
        "{partial:?}"
    );
    ipdf_json(&args);
    assert_same_files(killed.path(), whole.path());
}
