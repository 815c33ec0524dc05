//! The stages' work (what [`crate::runner`] schedules): one module per stage, each writing its artefacts
//! into `output.path/<stage>/` atomically and returning the list of files it wrote (relative to
//! `output.path`), which the runner hashes into the stage's manifest. A stage imports the contract
//! ([`crate::stage_contract`]) and the artefact types it reads ([`crate::artefacts`]), never another stage.

pub mod export;
pub mod ingest;
pub mod object;
pub mod preprocess;
pub mod triangle;

use std::path::PathBuf;

use crate::plan::StageId;
use crate::stage_contract::{StageContext, StageError, StageExecutor};

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
