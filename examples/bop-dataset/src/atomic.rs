//! Atomic file writes: a reader (or a resumed run) never sees a half-written result. The one
//! writer of every result file of the workspace's dataset, labelling and `ipdf` crates.
//!
//! The new content goes to a hidden sibling named for the file, `.NAME.partial`, which is then
//! renamed over `NAME`. A process killed mid-write leaves that sibling behind, and the next
//! write of the same file (a rerun, a resumed job) takes it over and renames it away: a rerun
//! leaves no temporary behind, and no name but `NAME` and `.NAME.partial` is ever created. A
//! lock on the sibling serialises two processes writing the same file.
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::FileError;

/// What a temporary file's name ends with: `.NAME` + this, beside `NAME`.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The temporary sibling of `path` that [`write_atomically`] writes first: `.NAME.partial`.
/// `None` for a path without a file name.
pub fn partial_path(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    let mut partial = std::ffi::OsString::from(".");
    partial.push(name);
    partial.push(PARTIAL_SUFFIX);
    Some(path.with_file_name(partial))
}

/// Writes a file through `write` into its temporary sibling ([`partial_path`]), flushes it to
/// disk and renames it over `path`, so that `path` holds either its old content or all of the
/// new one, also if the process is killed. A sibling left by a killed writer is reused; one
/// left by a failed `write` is removed. Missing parent folders are created.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), FileError> {
    let error = |e: std::io::Error| FileError::new(path, "file", e.to_string());
    let Some(partial) = partial_path(path) else {
        return Err(FileError::new(path, "file", "not a file path"));
    };
    if let Some(dir) = path.parent().filter(|dir| !dir.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(error)?;
    }
    let file = open_locked(&partial).map_err(error)?;
    let written = (|| {
        let mut out = BufWriter::new(file);
        write(&mut out)?;
        let file = out.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&partial, path)?;
        // The lock is released when `file` closes, after the rename.
        drop(file);
        Ok(())
    })();
    written.map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        error(e)
    })
}

/// `partial` opened for writing, empty, and locked by this process: the lock is taken on the
/// file that the name still holds (a writer that held it before may have renamed it away).
fn open_locked(partial: &Path) -> std::io::Result<File> {
    loop {
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(partial)?;
        file.lock()?;
        let held = file.metadata()?;
        match std::fs::metadata(partial) {
            Ok(named) if named.dev() == held.dev() && named.ino() == held.ino() => {
                file.set_len(0)?;
                return Ok(file);
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
    }
}

/// Writes `value` as pretty-printed JSON (with a final newline) atomically.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<(), FileError> {
    write_atomically(path, |out| {
        serde_json::to_writer_pretty(&mut *out, value)?;
        out.write_all(b"\n")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("result.json");
        write_json(&path, &serde_json::json!({"a": 1})).unwrap();
        let failed = write_atomically(&path, |out| {
            out.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        let message = failed.unwrap_err().to_string();
        assert!(
            message.contains("result.json") && message.contains("disk full"),
            "{message}"
        );
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "{\n  \"a\": 1\n}\n"
        );
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_killed_writers_temporary_is_taken_over_by_the_next_write() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("000001.png");
        let partial = partial_path(&path).unwrap();
        assert_eq!(partial, dir.path().join(".000001.png.partial"));
        // What a writer killed mid-write leaves: a temporary longer than the new content.
        std::fs::write(&partial, vec![7u8; 4096]).unwrap();
        write_atomically(&path, |out| out.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|entry| entry.unwrap().file_name())
            .collect();
        assert_eq!(names, ["000001.png"]);
    }

    #[test]
    fn concurrent_writers_of_one_file_leave_one_whole_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels.json");
        let contents: Vec<Vec<u8>> = (0..8u8).map(|k| vec![b'a' + k; 100_000]).collect();
        std::thread::scope(|scope| {
            for content in &contents {
                let path = &path;
                scope.spawn(move || {
                    for _ in 0..4 {
                        write_atomically(path, |out| out.write_all(content)).unwrap();
                    }
                });
            }
        });
        let written = std::fs::read(&path).unwrap();
        assert!(contents.contains(&written), "a mixed content");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn parent_folders_are_created() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a/b/c.txt");
        write_atomically(&path, |out| out.write_all(b"x")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"x");
    }
}
