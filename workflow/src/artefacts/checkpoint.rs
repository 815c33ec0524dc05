//! Optimisation checkpoints of a stage (`<stage>/checkpoint.json`): the optimiser's state together with the
//! hashes of the configuration and inputs it belongs to, so that a rerun resumes only the very same
//! computation. Written atomically; removed by the stage once its results are written.

use std::path::Path;

use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::atomic_file::{AtomicWriteError, write_json_atomic};
use crate::stage_contract::{StageContext, StageError, remove_if_present};

/// The checkpoint's file name inside the stage directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";

/// `checkpoint.json`; `format` names the stage's state type and version (e.g. `ipt-object-checkpoint/1`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Checkpoint<S> {
    pub format: String,
    pub config_sha256: String,
    pub inputs_sha256: String,
    pub state: S,
}

/// Writes `state` as the checkpoint of the stage run `ctx`, atomically.
pub fn write<S: Serialize>(ctx: &StageContext, format: &str, state: &S) -> Result<(), AtomicWriteError> {
    let cp = Checkpoint {
        format: format.to_owned(),
        config_sha256: ctx.config_sha256.clone(),
        inputs_sha256: ctx.inputs_sha256.clone(),
        state,
    };
    write_json_atomic(&ctx.dir.join(CHECKPOINT_FILE), &cp)
}

/// The checkpointed state in `dir` if it has this `format` and belongs to this exact computation (same config
/// and inputs hashes); `None` otherwise (an unreadable one is logged and ignored: it can only cost a restart).
#[must_use]
pub fn resumable<S: DeserializeOwned>(ctx: &StageContext, format: &str) -> Option<S> {
    let path = ctx.dir.join(CHECKPOINT_FILE);
    let text = std::fs::read_to_string(&path).ok()?;
    let cp: Checkpoint<S> = match serde_json::from_str(&text) {
        Ok(cp) => cp,
        Err(e) => {
            tracing::warn!("{}: unreadable checkpoint ignored: {e}", path.display());
            return None;
        }
    };
    if cp.format != format || cp.config_sha256 != ctx.config_sha256 || cp.inputs_sha256 != ctx.inputs_sha256 {
        ctx.note("checkpoint belongs to another config or other inputs; starting afresh");
        return None;
    }
    Some(cp.state)
}

/// Removes the checkpoint of `dir`, if any: called once the stage's results are on disk.
pub fn remove(dir: &Path) -> Result<(), StageError> {
    remove_if_present(dir.join(CHECKPOINT_FILE))
}
