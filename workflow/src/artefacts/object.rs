//! The `object` stage's artefacts and their readers (`crate::stages::object` writes them).
//!
//! `photometric.json` (`ipt-photometric/3`, only when the photos' tone-curve exponent was left open by their
//! calibration): the per-channel exponent the stage measured against its renders and applied to the prepared
//! photos; every later stage reads the photos through [`read_prepared`], which applies it too.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::preprocess::Prepared;
use crate::materials::MaterialsFile;
use crate::stage_contract::StageError;

pub use super::checkpoint::CHECKPOINT_FILE;
/// The result's file name (ipt-materials/1).
pub const MATERIALS_FILE: &str = "materials.json";
/// The trajectory's file name.
pub const HISTORY_FILE: &str = "history.json";
/// Format tag of `checkpoint.json` (3: 15 parameters per object, the ground half of an emission split at the
/// horizon and the zenith of its sky among them; a checkpoint of 1 or 2 is not resumed).
pub const CHECKPOINT_FORMAT: &str = "ipt-object-checkpoint/3";
/// The measured tone-curve exponent's file name.
pub const PHOTOMETRIC_FILE: &str = "photometric.json";
/// Format tag of `photometric.json`.
pub const PHOTOMETRIC_FORMAT: &str = "ipt-photometric/3";
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

/// `photometric.json`: the exponent applied to the prepared photos' linear values, per channel, and each
/// measurement that led to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotometricFile {
    pub format: String,
    /// Applied as `value^exponent[c]` to every prepared photo.
    pub exponent: [f64; 3],
    /// The first whole fit's emitters and which of them the trials' comparison fits let emit.
    pub emitters: Vec<SearchEmitter>,
    /// One entry per trial fit, in the order tried.
    pub rounds: Vec<ExponentRound>,
}

/// One emitter of the first whole fit, as the exponent search judged it (`optim::photometric::comparison_emitters`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchEmitter {
    pub id: i64,
    pub label: String,
    /// Its emission over the radiance the photos hold on it (means over channels); `null` when the photos do
    /// not measure it.
    pub share: Option<f64>,
    /// Whether the comparison fits let it emit.
    pub light: bool,
}

/// One trial of the exponent search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExponentRound {
    /// The exponent the fit's photos were raised to (every channel).
    pub exponent: f64,
    /// Its held-out log misfit per channel in the photos' original log units (`optim::photometric`).
    pub misfit: [f64; 3],
    /// What the search minimises: the mean over channels of each channel's misfit relative to its misfit in
    /// the first trial.
    pub criterion: f64,
    /// (Pixel, channel) pairs measured.
    pub terms: usize,
}

/// Reads `run_dir/object/photometric.json`; `None` when the stage did not measure an exponent.
pub fn read_photometric(run_dir: &Path) -> Result<Option<PhotometricFile>, StageError> {
    let path = run_dir.join("object").join(PHOTOMETRIC_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|source| StageError::Io { path: path.clone(), source })?;
    let file: PhotometricFile =
        serde_json::from_str(&text).map_err(|e| StageError::Artefact { path: path.clone(), message: e.to_string() })?;
    if file.format != PHOTOMETRIC_FORMAT || !file.exponent.iter().all(|e| e.is_finite() && *e > 0.0) {
        return Err(StageError::Artefact {
            path,
            message: format!("not `{PHOTOMETRIC_FORMAT}` with positive finite exponents"),
        });
    }
    Ok(Some(file))
}

/// The prepared photos as the stages after `object` use them: with the exponent of `photometric.json`
/// applied when there is one.
pub fn read_prepared(run_dir: &Path) -> Result<Prepared, StageError> {
    let mut prepared = Prepared::read(run_dir)?;
    if let Some(p) = read_photometric(run_dir)? {
        prepared.apply_exponent(p.exponent);
    }
    Ok(prepared)
}
