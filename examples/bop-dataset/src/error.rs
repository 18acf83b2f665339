//! The error of every reader and writer of on-disk data: it names the file and the field.
use std::path::{Path, PathBuf};

/// A file that cannot be read or written, or whose content is invalid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {field}: {reason}", path.display())]
pub struct FileError {
    /// The file.
    pub path: PathBuf,
    /// The JSON key, image property or element at fault (`file` for the file as a whole).
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

impl FileError {
    /// An error about `field` of `path`.
    pub fn new(path: &Path, field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            path: path.to_path_buf(),
            field: field.into(),
            reason: reason.into(),
        }
    }
}
