//! Atomic file writes: a reader (or a resumed run) never sees a half-written result. The one
//! writer of every result file of the workspace's dataset, labelling and `ipdf` crates.
use std::io::{BufWriter, Write};
use std::path::Path;

use serde::Serialize;

use crate::FileError;

/// Writes a file through `write` into a temporary sibling (created by `tempfile`), flushes it
/// to disk and renames it over `path`, so that `path` holds either its old content or all of
/// the new one, also if the process is killed. Missing parent folders are created.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), FileError> {
    let error = |e: std::io::Error| FileError::new(path, "file", e.to_string());
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    if path.file_name().is_none() {
        return Err(FileError::new(path, "file", "not a file path"));
    }
    std::fs::create_dir_all(dir).map_err(error)?;
    // The temporary file is removed when `temporary` is dropped unless it was persisted.
    let (file, temporary) = tempfile::NamedTempFile::new_in(dir)
        .map_err(error)?
        .into_parts();
    let mut out = BufWriter::new(file);
    write(&mut out).map_err(error)?;
    let file = out.into_inner().map_err(|e| error(e.into_error()))?;
    file.sync_all().map_err(error)?;
    temporary.persist(path).map_err(|e| error(e.error))
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
    fn parent_folders_are_created() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a/b/c.txt");
        write_atomically(&path, |out| out.write_all(b"x")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"x");
    }
}
