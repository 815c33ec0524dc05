//! A configured run over a scan, as a library: configuration, the resolved plan, stage manifests and the
//! stage runner, the stages themselves, and the user-facing outputs (materials.json, report.html, the mesh
//! export, re-renders). It prints nothing and knows no terminal: messages and progress leave through
//! [`stage_contract::Reporter`]; the `pipeline` binary draws them.
//!
//! Code map: [`config`] (TOML as written, `--set`) → [`plan`] (validated, paths resolved, stage list) →
//! [`runner`] (skip/rerun decisions, [`manifest`]s) → [`stages`] (the work) → [`materials`], [`report`],
//! [`export`]. The optimisation itself is the `optim` crate. The runner and the stages meet in
//! [`stage_contract`]; what each stage writes and how it is read back is in [`artefacts`]. [`render`] is
//! `pipeline render`; [`process_stats`] reads what the process costs (CPU time, peak RSS).

pub mod artefacts;
pub mod atomic_file;
pub mod config;
pub mod display;
pub mod export;
pub mod manifest;
pub mod materials;
pub mod plan;
pub mod presets;
pub mod process_stats;
pub mod render;
pub mod report;
pub mod runner;
pub mod stage_contract;
pub mod stages;
pub mod svg;
