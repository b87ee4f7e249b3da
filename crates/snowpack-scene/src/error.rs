//! Scene errors: every one names the file and the key.

use std::path::{Path, PathBuf};

/// A scene file that cannot be used, with the file and the key at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {}{message}", file.display(), if key.is_empty() { String::new() } else { format!("{key}: ") })]
pub struct SceneError {
    /// The scene file (or the file it refers to).
    pub file: PathBuf,
    /// Key path such as `[[actor]][2].radius_m`; empty for file-level problems.
    pub key: String,
    /// What is wrong, and what would be right.
    pub message: String,
}

impl SceneError {
    /// An error at `key` of `file`.
    #[must_use]
    pub fn new(file: &Path, key: impl Into<String>, message: impl Into<String>) -> Self {
        Self { file: file.to_owned(), key: key.into(), message: message.into() }
    }
}
