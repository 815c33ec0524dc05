//! Directory listings the format readers share: sorted, so that every reader sees a scan's files in the
//! same order on every file system.

use std::path::{Path, PathBuf};

use crate::error::IngestError;

/// Sorted files in `dir` whose extension is `ext` (case-insensitive).
pub fn files_with_extension(dir: &Path, ext: &str) -> Result<Vec<PathBuf>, IngestError> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| IngestError::io(dir, e))? {
        let p = entry.map_err(|e| IngestError::io(dir, e))?.path();
        if p.is_file() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}
