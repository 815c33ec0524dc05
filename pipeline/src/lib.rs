//! Library behind the `pipeline` binary: configuration, the resolved plan, stage manifests and the stage
//! runner, the stages themselves, and the user-facing outputs (materials.json, report.html).
//!
//! Code map: [`config`] (TOML as written, `--set`) → [`plan`] (validated, paths resolved, stage list) →
//! [`runner`] (skip/rerun decisions, [`manifest`]s) → [`stages`] (the work) → [`materials`], [`report`].
//! The optimisation itself is the `optim` crate ([`progress`] renders its progress); [`synth`] is the
//! synthetic-scan generator. The runner and the stages meet in [`stage_contract`]; what each stage writes and
//! how it is read back is in [`artefacts`].

pub mod artefacts;
pub mod atomic_file;
pub mod bench;
pub mod cli;
pub mod config;
pub mod display;
pub mod export;
pub mod manifest;
pub mod materials;
pub mod plan;
pub mod presets;
pub mod progress;
pub mod render_cmd;
pub mod report;
pub mod runner;
pub mod stage_contract;
pub mod stages;
pub mod svg;
pub mod synth;
