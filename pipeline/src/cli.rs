//! Command line: `pipeline run`, `pipeline render`, `pipeline export`. Parsing only; the work is in the
//! `workflow` library. Exit codes: 0 success, 1 a failure while running, 2 bad usage or bad config.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use workflow::plan::StageId;

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
    /// Largest number of scattering events of a path (the config's default `tracer.max_depth`).
    #[arg(long, default_value_t = workflow::config::DEFAULT_MAX_DEPTH)]
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

fn parse_stage(s: &str) -> Result<StageId, String> {
    s.parse()
}

impl RenderArgs {
    /// The library's request.
    pub fn request(&self) -> workflow::render::RenderRequest {
        workflow::render::RenderRequest {
            run_dir: self.run_dir.clone(),
            cameras: self.cameras.clone(),
            output: self.output.clone(),
            spp: self.spp,
            materials: self.materials.clone(),
            max_depth: self.max_depth,
            size: self.width.zip(self.height),
            seed: self.seed,
        }
    }
}
