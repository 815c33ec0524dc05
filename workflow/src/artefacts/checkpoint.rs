//! Optimisation checkpoints of a stage (`<stage>/checkpoint.json`): the optimiser's state together with the
//! hashes of the configuration and inputs it belongs to, the version of the program that wrote it and a
//! digest of the state itself, so that a rerun resumes only the very same computation from an intact state.
//! Written atomically, as compact JSON (only the program reads it); removed by the stage once its results
//! are written. A checkpoint that is unreadable, damaged (its digest differs), from another version, or from
//! another config or other inputs is refused with a message naming the reason, and the stage starts afresh:
//! it can only cost the time to redo it.

use std::path::Path;

use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::atomic_file::{AtomicWriteError, write_compact_json_atomic};
use crate::manifest::sha256_json;
use crate::stage_contract::{StageContext, StageError, remove_if_present};

/// The checkpoint's file name inside the stage directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";

/// The version of the program, recorded in every checkpoint: the optimiser's state layout and its random
/// streams may change between versions, so a checkpoint resumes only under the version that wrote it.
pub const PROGRAM_VERSION: &str = env!("CARGO_PKG_VERSION");

/// `checkpoint.json`; `format` names the stage's state type and version (e.g. `ipt-object-checkpoint/1`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Checkpoint<S> {
    pub format: String,
    pub program_version: String,
    pub config_sha256: String,
    pub inputs_sha256: String,
    /// SHA-256 of the state's canonical JSON (see [`sha256_json`]).
    pub state_sha256: String,
    pub state: S,
}

/// Writes `state` as the checkpoint of the stage run `ctx`, atomically.
pub fn write<S: Serialize>(ctx: &StageContext, format: &str, state: &S) -> Result<(), AtomicWriteError> {
    let path = ctx.dir.join(CHECKPOINT_FILE);
    let value = serde_json::to_value(state).map_err(|e| AtomicWriteError {
        path: path.clone(),
        source: ingest::IngestError::format(&path, e.to_string()),
    })?;
    let cp = Checkpoint {
        format: format.to_owned(),
        program_version: PROGRAM_VERSION.to_owned(),
        config_sha256: ctx.config_sha256.clone(),
        inputs_sha256: ctx.inputs_sha256.clone(),
        state_sha256: sha256_json(&value),
        state: &value,
    };
    write_compact_json_atomic(&path, &cp)
}

/// Why a checkpoint is not resumed.
fn refusal(cp: &Checkpoint<serde_json::Value>, ctx: &StageContext, format: &str) -> Option<String> {
    if cp.format != format {
        return Some(format!("its format is {}, this stage writes {format}", cp.format));
    }
    if cp.program_version != PROGRAM_VERSION {
        return Some(format!("it was written by version {}, this is {PROGRAM_VERSION}", cp.program_version));
    }
    if cp.state_sha256 != sha256_json(&cp.state) {
        return Some("it is damaged (its state digest differs)".to_owned());
    }
    if cp.config_sha256 != ctx.config_sha256 || cp.inputs_sha256 != ctx.inputs_sha256 {
        return Some("it belongs to another config or other inputs".to_owned());
    }
    None
}

/// The checkpointed state of the stage run `ctx` if it has this `format`, this program version, an intact
/// state and the same config and inputs hashes; `None` otherwise, with a message saying why.
#[must_use]
pub fn resumable<S: DeserializeOwned>(ctx: &StageContext, format: &str) -> Option<S> {
    let path = ctx.dir.join(CHECKPOINT_FILE);
    let text = std::fs::read_to_string(&path).ok()?;
    let refused = |why: String| {
        ctx.note(&format!("checkpoint not resumed: {why}; starting afresh"));
        None
    };
    let cp: Checkpoint<serde_json::Value> = match serde_json::from_str(&text) {
        Ok(cp) => cp,
        Err(e) => return refused(format!("{} is unreadable ({e})", path.display())),
    };
    if let Some(why) = refusal(&cp, ctx, format) {
        return refused(why);
    }
    match serde_json::from_value(cp.state) {
        Ok(state) => Some(state),
        Err(e) => refused(format!("its state does not match this stage's ({e})")),
    }
}

/// Removes the checkpoint of `dir`, if any: called once the stage's results are on disk.
pub fn remove(dir: &Path) -> Result<(), StageError> {
    remove_if_present(dir.join(CHECKPOINT_FILE))
}
