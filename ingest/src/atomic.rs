//! Atomic file writes: readers never see a half-written file, and a crash leaves either the old file or the
//! new one.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::IngestError;

/// Distinguishes temporary files of concurrent writers within one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: a temporary file in the same directory (so the rename never crosses
/// file systems) is written, fsynced, and renamed over `path`; the directory is then fsynced so the rename
/// itself is durable. On failure the temporary file is removed and `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IngestError> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let file_name = path
        .file_name()
        .ok_or_else(|| IngestError::format(path, "cannot write: path has no file name"))?
        .to_string_lossy()
        .into_owned();
    let tmp = dir.join(format!(".{file_name}.tmp.{}.{}", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed)));
    let result = injected_fault(path)
        .and_then(|()| write_and_sync(&tmp, bytes, path))
        .and_then(|()| fs::rename(&tmp, path).map_err(|e| IngestError::io(path, e)));
    if result.is_err() {
        // Best effort: the temporary file may not even exist if creating it failed.
        let _ = fs::remove_file(&tmp);
        return result;
    }
    // Durability of the rename; some platforms/file systems do not support fsync on directories, and the data
    // itself is already safe, so a failure here is not an error.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Errors name `path`, the file being written, not its temporary sibling.
fn write_and_sync(tmp: &Path, bytes: &[u8], path: &Path) -> Result<(), IngestError> {
    let mut f = OpenOptions::new().write(true).create_new(true).open(tmp).map_err(|e| IngestError::io(path, e))?;
    f.write_all(bytes).map_err(|e| IngestError::io(path, e))?;
    f.sync_all().map_err(|e| IngestError::io(path, e))
}

/// With the `fault-injection` feature: a full disk (ENOSPC) for paths containing `IPT_FAULT_WRITE`.
#[cfg(feature = "fault-injection")]
fn injected_fault(path: &Path) -> Result<(), IngestError> {
    /// ENOSPC on Linux: what a write to a full file system returns.
    const ENOSPC: i32 = 28;
    match std::env::var("IPT_FAULT_WRITE") {
        Ok(s) if !s.is_empty() && path.to_string_lossy().contains(&s) => {
            Err(IngestError::io(path, std::io::Error::from_raw_os_error(ENOSPC)))
        }
        _ => Ok(()),
    }
}

#[cfg(not(feature = "fault-injection"))]
#[allow(clippy::unnecessary_wraps)]
fn injected_fault(_path: &Path) -> Result<(), IngestError> {
    Ok(())
}
