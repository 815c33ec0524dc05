//! Command line: `pipeline run`, `pipeline render`, `pipeline synth`, `pipeline bench`. Parsing only; the work is in the
//! library modules. Exit codes: 0 success, 1 a failure while running, 2 bad usage or bad config.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use crate::plan::StageId;

/// Inverse path tracing of indoor scans: recovers per-object materials and emission from photos.
#[derive(Debug, Parser)]
#[command(name = "pipeline", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Runs the stages ingest → preprocess → object → triangle → export, skipping finished ones.
    Run(RunArgs),
    /// Renders the ingested scene of a run with its (or given) materials from the cameras of a .conf file.
    Render(RenderArgs),
    /// Generates a synthetic Matterport-layout scan from a scene description.
    Synth(SynthArgs),
    /// Measures speed against accuracy of the per-object fit (see `pipeline::bench`).
    Bench(BenchArgs),
    /// Writes RUN_DIR/export/{mesh.ply, textured.obj + .mtl + albedo atlas, scene.glb} from the run's
    /// per-triangle result (or its per-object result when the triangle stage wrote none).
    Export(ExportArgs),
}

/// `pipeline export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// A run directory (`output.path` of a run whose `object` stage finished).
    pub run_dir: PathBuf,
}

/// `pipeline bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Sweeps the fit's settings on synthetic scenes: CSV, SVG (error vs time, Pareto front), markdown.
    Tradeoff(BenchTradeoffArgs),
    /// Adam-phase ablations: value paths (paper Fig. 9) and value/gradient budget split (Fig. 10).
    Ablation(BenchAblationArgs),
    /// Mitsuba 3 baseline against our fit on the same scene: time to the same albedo error.
    Mitsuba(BenchMitsubaArgs),
}

/// `pipeline bench tradeoff`.
#[derive(Debug, clap::Args)]
pub struct BenchTradeoffArgs {
    /// Scenes (`data-fixtures/scenes/<name>.toml`), comma-separated; scenes with a textured (checker) object
    /// also run the per-triangle stage at every point.
    #[arg(long, value_delimiter = ',', default_value = "demo,glossy,checker")]
    pub scenes: Vec<String>,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    pub out: PathBuf,
    /// A tiny sweep (smoke test): two points per scene at minimal settings.
    #[arg(long)]
    pub quick: bool,
    /// Run only the sweep points with these labels (comma-separated, e.g. `default,corner:fast`).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Do not run: rebuild the SVG and markdown from the CSV already in `--out`.
    #[arg(long)]
    pub replot: bool,
    /// Workspace root holding `data-fixtures/` (default: the one this binary was built from).
    #[arg(long)]
    pub workspace: Option<PathBuf>,
}

/// `pipeline bench ablation`.
#[derive(Debug, clap::Args)]
pub struct BenchAblationArgs {
    /// Scene (`data-fixtures/scenes/<name>.toml`).
    #[arg(long, default_value = "demo")]
    pub scene: String,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    pub out: PathBuf,
    /// Tiny runs (smoke test).
    #[arg(long)]
    pub quick: bool,
    /// Workspace root holding `data-fixtures/`.
    #[arg(long)]
    pub workspace: Option<PathBuf>,
}

/// `pipeline bench mitsuba`.
#[derive(Debug, clap::Args)]
pub struct BenchMitsubaArgs {
    /// Scene with a committed scan (`data-fixtures/<name>/`).
    #[arg(long, default_value = "demo")]
    pub scene: String,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    pub out: PathBuf,
    /// Wall-time budget of the Mitsuba solve, seconds.
    #[arg(long, default_value_t = 300.0)]
    pub budget_seconds: f64,
    /// Python with Mitsuba 3 (default: `<workspace>/deps/venv/bin/python`).
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Our side at the `--quick` tradeoff settings only (smoke test).
    #[arg(long)]
    pub quick: bool,
    /// Workspace root holding `data-fixtures/` and `tests/validation/`.
    #[arg(long)]
    pub workspace: Option<PathBuf>,
}

/// `pipeline run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// The TOML config (see configs/README.md).
    pub config: PathBuf,
    /// Start at this stage (rerun it even if up to date; earlier stages must have finished).
    #[arg(long, value_parser = parse_stage)]
    pub from: Option<StageId>,
    /// Stop after this stage.
    #[arg(long, value_parser = parse_stage)]
    pub until: Option<StageId>,
    /// Override a config key: `--set object.lr=0.01` (value parsed as TOML, else taken as a string).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// `pipeline render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// A run directory (`output.path` of a run whose `ingest` stage finished).
    pub run_dir: PathBuf,
    /// A Matterport-style cameras file (`intrinsics_matrix` + `scan` lines).
    #[arg(long)]
    pub cameras: PathBuf,
    /// Output directory; one `<color file stem>.exr` per `scan` line.
    #[arg(long)]
    pub output: PathBuf,
    /// Paths per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Materials in the ipt-materials/1 schema (default: RUN_DIR/materials.json).
    #[arg(long)]
    pub materials: Option<PathBuf>,
    /// Largest number of scattering events of a path.
    #[arg(long, default_value_t = 8)]
    pub max_depth: u32,
    /// Image width for every camera (default: the size of the listed colour image, when it exists).
    #[arg(long, requires = "height")]
    pub width: Option<u32>,
    /// Image height for every camera.
    #[arg(long, requires = "width")]
    pub height: Option<u32>,
    /// Seed of the renderer's random numbers.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// `pipeline synth`.
#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// Scene description (TOML).
    pub desc: PathBuf,
    /// Output scan directory.
    pub out_dir: PathBuf,
}

fn parse_stage(s: &str) -> Result<StageId, String> {
    s.parse()
}
