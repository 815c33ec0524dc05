//! The contract between the stage runner ([`crate::runner`]) and the stages ([`crate::stages`]): what a stage
//! is given ([`StageContext`]), how it is called ([`StageExecutor`]), how it fails ([`StageError`]) and where
//! its messages and progress go ([`Reporter`]). Both sides import this module; neither imports the other's
//! internals. The library prints nothing: the binary's [`Reporter`] draws progress on a terminal and writes
//! the log.

use std::path::PathBuf;

use crate::atomic_file::AtomicWriteError;
use crate::plan::{Plan, StageId};

/// Where a run's messages and progress go: the one channel from the library to the user.
pub trait Reporter: Sync {
    /// A one-line message of `stage`: a decision (why a stage runs, a checkpoint resumed) or a summary.
    fn note(&self, stage: StageId, line: &str);
    /// A progress indicator for a long step of `stage` with `total` steps; `what` names the step. The step is
    /// over when the returned value is dropped.
    fn progress(&self, stage: StageId, what: &str, total: u64) -> Box<dyn optim::Progress + '_>;
    /// True once the user wants the run to stop (a signal): the runner starts no further stage and the
    /// optimisation stages stop at their next step boundary with a checkpoint.
    fn stop_requested(&self) -> bool {
        false
    }
}

/// Reports nothing (tests, library callers that only want the files).
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Reporter for Silent {
    fn note(&self, _stage: StageId, _line: &str) {}

    fn progress(&self, _stage: StageId, _what: &str, _total: u64) -> Box<dyn optim::Progress + '_> {
        Box::new(optim::NoProgress)
    }
}

/// What a stage needs to know about its own run.
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
    /// Where the stage's messages and progress go.
    pub reporter: &'a dyn Reporter,
}

impl std::fmt::Debug for StageContext<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StageContext")
            .field("stage", &self.stage)
            .field("dir", &self.dir)
            .field("config_sha256", &self.config_sha256)
            .field("inputs_sha256", &self.inputs_sha256)
            .finish_non_exhaustive()
    }
}

impl StageContext<'_> {
    /// A one-line message of this stage.
    pub fn note(&self, line: &str) {
        self.reporter.note(self.stage, line);
    }

    /// True once the user wants the run to stop.
    #[must_use]
    pub fn stop_requested(&self) -> bool {
        self.reporter.stop_requested()
    }

    /// A progress indicator for a long step of this stage.
    #[must_use]
    pub fn progress(&self, what: &str, total: u64) -> Box<dyn optim::Progress + '_> {
        self.reporter.progress(self.stage, what, total)
    }
}

/// Runs stages. The real implementation is `crate::stages::Stages`; tests may use their own.
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
    /// An artefact written in another format version, by another version of the pipeline: a stage's freshness
    /// looks at its config and inputs, not at the program that wrote it, so the error says how to redo it.
    #[error(
        "{path}: format `{found}` is not `{expected}` (written by another version of the pipeline: rerun from that stage with `--from {stage}`)",
        path = .path.display()
    )]
    OldFormat { path: PathBuf, found: String, expected: &'static str, stage: &'static str },
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
    /// The user asked the run to stop (a signal) before the stage finished.
    #[error("interrupted")]
    Interrupted,
}

/// Removes `path`; a file that is already gone is not an error.
pub fn remove_if_present(path: std::path::PathBuf) -> Result<(), StageError> {
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StageError::Io { path, source: e }),
        _ => Ok(()),
    }
}
