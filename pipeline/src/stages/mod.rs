//! The stages' work (what [`crate::runner`] schedules): one module per stage, each writing its artefacts
//! into `output.path/<stage>/` atomically and returning the list of files it wrote (relative to
//! `output.path`), which the runner hashes into the stage's manifest.

pub mod checkpoint;
pub mod export;
pub mod ingest;
pub mod object;
pub mod object_result;
pub mod preprocess;
pub mod triangle;

use std::path::PathBuf;

use crate::atomic_file::AtomicWriteError;
use crate::plan::StageId;
use crate::runner::{StageContext, StageExecutor};

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

/// The real stages.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stages;

impl StageExecutor for Stages {
    fn is_implemented(&self, _stage: StageId) -> bool {
        true
    }

    fn run(&mut self, ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
        match ctx.stage {
            StageId::Ingest => ingest::run(ctx),
            StageId::Preprocess => preprocess::run(ctx),
            StageId::Object => object::run(ctx),
            StageId::Triangle => triangle::run(ctx),
            StageId::Export => export::run(ctx),
        }
    }
}

/// Removes `path`; a file that is already gone is not an error.
pub(crate) fn remove_if_present(path: std::path::PathBuf) -> Result<(), StageError> {
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StageError::Io { path, source: e }),
        _ => Ok(()),
    }
}
