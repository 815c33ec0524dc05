//! The `triangle` stage's artefacts (`crate::stages::triangle` writes them) and their reader, [`read_result`].
//!
//! In `output.path/triangle/`: `result.json` — `{"format": "ipt-triangle/1", "state": TriangleState}` — and,
//! while the stage runs, `checkpoint.json` (format `ipt-triangle-checkpoint/1`, [`super::checkpoint`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::stage_contract::StageError;
use optim::triangle::{RESULT_FORMAT, TriangleState};

/// The result's file name.
pub const RESULT_FILE: &str = "result.json";
pub use super::checkpoint::CHECKPOINT_FILE;
/// Format tag of the checkpoint.
pub const CHECKPOINT_FORMAT: &str = "ipt-triangle-checkpoint/1";

/// `result.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResultFile {
    pub format: String,
    pub state: TriangleState,
}

/// Reads `run_dir/triangle/result.json`; `Ok(None)` when the stage wrote none (disabled or not run).
pub fn read_result(run_dir: &Path) -> Result<Option<TriangleState>, StageError> {
    let path = run_dir.join("triangle").join(RESULT_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(StageError::Io { path, source }),
    };
    let r: ResultFile =
        serde_json::from_str(&text).map_err(|e| StageError::Artefact { path: path.clone(), message: e.to_string() })?;
    if r.format != RESULT_FORMAT {
        return Err(StageError::OldFormat { path, found: r.format, expected: RESULT_FORMAT, stage: "triangle" });
    }
    Ok(Some(r.state))
}
