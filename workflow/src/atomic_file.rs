//! Atomic artefact writes through `ingest::write_atomic`: a temporary file in the target's directory, fsync,
//! rename, fsync of the directory. Readers (and a rerun after a crash) see either the old file or the new
//! one, never a torn one.

use std::path::{Path, PathBuf};

/// A failed atomic write; `path` is the file that was to be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write: {source}", path = .path.display())]
pub struct AtomicWriteError {
    pub path: PathBuf,
    #[source]
    pub source: ingest::IngestError,
}

/// Writes `bytes` to `path` atomically (`ingest::write_atomic`), creating the parent directory if needed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), AtomicWriteError> {
    let err = |source| AtomicWriteError { path: path.to_path_buf(), source };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| err(ingest::IngestError::io(dir, e)))?;
    }
    ingest::write_atomic(path, bytes).map_err(err)
}

/// Serialises `value` as pretty JSON and writes it atomically.
pub fn write_json_atomic<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), AtomicWriteError> {
    write_json(path, serde_json::to_vec_pretty(value))
}

/// Serialises `value` as compact JSON (no whitespace) and writes it atomically: for files only the program
/// reads back, such as checkpoints, where indentation would double the size of a large state.
pub fn write_compact_json_atomic<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), AtomicWriteError> {
    write_json(path, serde_json::to_vec(value))
}

fn write_json(path: &Path, text: serde_json::Result<Vec<u8>>) -> Result<(), AtomicWriteError> {
    let text = text.map_err(|e| AtomicWriteError {
        path: path.to_path_buf(),
        source: ingest::IngestError::format(path, e.to_string()),
    })?;
    write_atomic(path, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_content_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("deep/a.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> =
            std::fs::read_dir(dir.path().join("deep")).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["a.txt"]);
    }
}
