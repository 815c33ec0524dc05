//! The contract between the stage runner ([`crate::runner`]) and the stages ([`crate::stages`]): what a stage
//! is given ([`StageContext`]), how it is called ([`StageExecutor`]) and how it fails ([`StageError`]). Both
//! sides import this module; neither imports the other's internals.

use std::path::PathBuf;

use crate::atomic_file::AtomicWriteError;
use crate::plan::{Plan, StageId};

/// What a stage needs to know about its own run.
#[derive(Debug)]
pub struct StageContext<'a> {
    pub plan: &'a Plan,
    pub stage: StageId,
    /// `output.path/<stage>/` (exists when the stage is called).
    pub dir: PathBuf,
    /// Hash of the stage's config section.
    pub config_sha256: String,
    /// Hash of the stage's inputs; together with `config_sha256` it identifies the computation (the object
    /// stage only resumes a checkpoint with the same pair).
    pub inputs_sha256: String,
}

/// Runs stages. The binary's implementation is `crate::stages::Stages`; tests may use their own.
pub trait StageExecutor {
    /// False for a stage whose issue has not landed: it is skipped with a message and writes no manifest.
    fn is_implemented(&self, stage: StageId) -> bool;
    /// Runs a stage; returns its output files relative to `plan.output` (hashed into the manifest).
    fn run(&mut self, ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError>;
}

/// Why a stage failed.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Write(#[from] AtomicWriteError),
    /// An artefact of an earlier stage (or the config) is not what this stage needs.
    #[error("{path}: {message}", path = .path.display())]
    Artefact { path: PathBuf, message: String },
    #[error(transparent)]
    Scan(#[from] ::ingest::IngestError),
    #[error(transparent)]
    Photo(#[from] ::ingest::photo::PhotoError),
    #[error("tracer: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error(transparent)]
    Fit(#[from] optim::fit::FitError),
    #[error(transparent)]
    Materials(#[from] crate::materials::MaterialsError),
    #[error(transparent)]
    Triangle(optim::triangle::TriangleError),
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
}

/// Removes `path`; a file that is already gone is not an error.
pub fn remove_if_present(path: std::path::PathBuf) -> Result<(), StageError> {
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StageError::Io { path, source: e }),
        _ => Ok(()),
    }
}
