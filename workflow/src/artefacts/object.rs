//! The `object` stage's artefacts and their readers (`crate::stages::object` writes them).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::materials::MaterialsFile;
use crate::stage_contract::StageError;

pub use super::checkpoint::CHECKPOINT_FILE;
/// The result's file name (ipt-materials/1).
pub const MATERIALS_FILE: &str = "materials.json";
/// The trajectory's file name.
pub const HISTORY_FILE: &str = "history.json";
/// Format tag of `checkpoint.json`.
pub const CHECKPOINT_FORMAT: &str = "ipt-object-checkpoint/1";
/// Format tag of `history.json`.
pub const HISTORY_FORMAT: &str = "ipt-object-history/1";

/// `history.json`: the fit's trajectory (entries as the fit records them), per-object model decisions and the
/// fit's path-sample counts (`materials.json` is a fixed schema, so the per-stage numbers live here).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryFile {
    pub format: String,
    pub history: Vec<serde_json::Value>,
    /// Per object (materials.json order): why the fit chose its model.
    pub why: Vec<String>,
    /// Path samples the fit traced (`FitOutcome::traced_paths`); 0 in files written before the count existed.
    #[serde(default)]
    pub traced_paths: u64,
    /// Of these, the samples the tracer discarded as non-finite (`FitOutcome::discarded_samples`).
    #[serde(default)]
    pub discarded_samples: u64,
    /// Training and held-out pixels of the fit (`FitOutcome::train_pixels`, `holdout_pixels`); 0 in files
    /// written before the counts existed.
    #[serde(default)]
    pub train_pixels: usize,
    #[serde(default)]
    pub holdout_pixels: usize,
}

/// Reads `run_dir/object/materials.json`.
pub fn read_result(run_dir: &Path) -> Result<MaterialsFile, StageError> {
    Ok(MaterialsFile::read(&run_dir.join("object").join(MATERIALS_FILE))?)
}

/// Reads `run_dir/object/history.json`.
pub fn read_history(run_dir: &Path) -> Result<HistoryFile, StageError> {
    let path = run_dir.join("object").join(HISTORY_FILE);
    let text = std::fs::read_to_string(&path).map_err(|source| StageError::Io { path: path.clone(), source })?;
    serde_json::from_str(&text).map_err(|e| StageError::Artefact { path, message: e.to_string() })
}
