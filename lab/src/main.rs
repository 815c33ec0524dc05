//! `lab`: the development commands. `lab synth DESC OUT_DIR` generates a synthetic Matterport-layout scan;
//! `lab bench tradeoff | ablation | mitsuba | scale | realistic` measure the fit's speed against its accuracy (docs/tradeoff/).
//! Exit codes: 0 success, 1 failure, 2 bad usage.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use lab::bench::{self, ablation, mitsuba, realistic, scale, tradeoff};

/// Development tools of ipt: synthetic scans and benchmarks.
#[derive(Debug, Parser)]
#[command(name = "lab", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Generates a synthetic Matterport-layout scan from a scene description.
    Synth(SynthArgs),
    /// Measures speed against accuracy of the per-object fit.
    Bench(BenchArgs),
}

/// `lab bench`.
#[derive(Debug, clap::Args)]
struct BenchArgs {
    #[command(subcommand)]
    what: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
enum BenchCommand {
    /// Sweeps the fit's settings on synthetic scenes: CSV, SVG (error vs time, Pareto front), markdown.
    Tradeoff(BenchTradeoffArgs),
    /// Adam-phase ablations: value paths (paper Fig. 9) and value/gradient budget split (Fig. 10).
    Ablation(BenchAblationArgs),
    /// Mitsuba 3 baseline against our fit on the same scene: time to the same albedo error.
    Mitsuba(BenchMitsubaArgs),
    /// The whole pipeline on scans of growing size: time, CPU, peak RSS per stage, accuracy (docs/scale/).
    Scale(BenchScaleArgs),
    /// The quality presets on the realistic corpus (Mitsuba renders): cost per stage and the corpus scores.
    Realistic(BenchRealisticArgs),
    /// One point of `scale`, in its own process (internal).
    #[command(hide = true)]
    ScalePoint(BenchScalePointArgs),
}

/// `lab bench tradeoff`.
#[derive(Debug, clap::Args)]
struct BenchTradeoffArgs {
    /// Scenes (`data-fixtures/scenes/<name>.toml`), comma-separated; scenes with a textured (checker) object
    /// also run the per-triangle stage at every point.
    #[arg(long, value_delimiter = ',', default_value = "demo,glossy,checker")]
    scenes: Vec<String>,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    out: PathBuf,
    /// A tiny sweep (smoke test): two points per scene at minimal settings.
    #[arg(long)]
    quick: bool,
    /// Run only the sweep points with these labels (comma-separated, e.g. `default,corner:fast`).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Do not run: rebuild the SVG and markdown from the CSV already in `--out`.
    #[arg(long)]
    replot: bool,
    /// Workspace root holding `data-fixtures/` (default: the one this binary was built from).
    #[arg(long)]
    workspace: Option<PathBuf>,
}

/// `lab bench ablation`.
#[derive(Debug, clap::Args)]
struct BenchAblationArgs {
    /// Scene (`data-fixtures/scenes/<name>.toml`).
    #[arg(long, default_value = "demo")]
    scene: String,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    out: PathBuf,
    /// Tiny runs (smoke test).
    #[arg(long)]
    quick: bool,
    /// Workspace root holding `data-fixtures/`.
    #[arg(long)]
    workspace: Option<PathBuf>,
}

/// `lab bench scale`.
#[derive(Debug, clap::Args)]
struct BenchScaleArgs {
    /// Output directory.
    #[arg(long, default_value = "docs/scale")]
    out: PathBuf,
    /// Axes to sweep (comma-separated: triangles, objects, photos, resolution; default all).
    #[arg(long, value_delimiter = ',')]
    axes: Vec<String>,
    /// Two tiny points (smoke test).
    #[arg(long)]
    quick: bool,
    /// Config override for every run (`--set object.holdout_pixels=512`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Keep every point's scan, config and run under this directory (`<axis>-<value>/`), to rerun a point
    /// stage by stage; by default they are deleted once measured.
    #[arg(long, value_name = "DIR")]
    keep: Option<PathBuf>,
    /// Do not run: redraw `scale.svg` from the `scale.csv` already in `--out`.
    #[arg(long)]
    replot: bool,
    /// Workspace root holding `data-fixtures/`.
    #[arg(long)]
    workspace: Option<PathBuf>,
}

/// `lab bench realistic`.
#[derive(Debug, clap::Args)]
struct BenchRealisticArgs {
    /// Directory holding the built corpus scans, one per scene (`make corpus`; default `$CORPUS_DIR`, else
    /// `~/.cache/ipt/corpus`).
    #[arg(long, default_value_os_t = default_corpus())]
    corpus: PathBuf,
    /// Scenes (subdirectories of `--corpus`), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = realistic::DEFAULT_SCENES.map(String::from))]
    scenes: Vec<String>,
    /// Quality presets, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = realistic::DEFAULT_PRESETS.map(String::from))]
    presets: Vec<String>,
    /// Output directory of realistic.{csv,md,svg}.
    #[arg(long, default_value = "docs/realistic/bench")]
    out: PathBuf,
    /// Where the runs are kept (default `<corpus>/bench-runs`); a finished run there is read back, not rerun.
    #[arg(long)]
    runs: Option<PathBuf>,
    /// Run and score again even where a finished run is kept.
    #[arg(long)]
    fresh: bool,
    /// Config override for every run (`--set object.seed=1`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Paths per pixel of the scorer's novel-view re-renders.
    #[arg(long, default_value_t = 128)]
    render_spp: u32,
    /// Python of the validation venv (default `<workspace>/deps/venv/bin/python`).
    #[arg(long)]
    python: Option<PathBuf>,
    /// `pipeline` binary the scorer renders with (default: the one beside this binary).
    #[arg(long)]
    pipeline: Option<PathBuf>,
    /// Workspace root holding `tests/validation/`.
    #[arg(long)]
    workspace: Option<PathBuf>,
}

/// `$CORPUS_DIR`, else `~/.cache/ipt/corpus` (the Makefile's `corpus` target writes there).
fn default_corpus() -> PathBuf {
    if let Some(d) = std::env::var_os("CORPUS_DIR") {
        return PathBuf::from(d);
    }
    std::env::var_os("HOME")
        .map_or_else(|| PathBuf::from(".cache/ipt/corpus"), |h| PathBuf::from(h).join(".cache/ipt/corpus"))
}

/// `lab bench scale-point`.
#[derive(Debug, clap::Args)]
struct BenchScalePointArgs {
    config: PathBuf,
    stats: PathBuf,
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

/// `lab bench mitsuba`.
#[derive(Debug, clap::Args)]
struct BenchMitsubaArgs {
    /// Scene with a committed scan (`data-fixtures/<name>/`).
    #[arg(long, default_value = "demo")]
    scene: String,
    /// Output directory.
    #[arg(long, default_value = "docs/tradeoff")]
    out: PathBuf,
    /// Wall-time budget of the Mitsuba solve, seconds.
    #[arg(long, default_value_t = 300.0)]
    budget_seconds: f64,
    /// Python with Mitsuba 3 (default: `<workspace>/deps/venv/bin/python`).
    #[arg(long)]
    python: Option<PathBuf>,
    /// Our side at the `--quick` tradeoff settings only (smoke test).
    #[arg(long)]
    quick: bool,
    /// Workspace root holding `data-fixtures/` and `tests/validation/`.
    #[arg(long)]
    workspace: Option<PathBuf>,
}

/// `lab synth`.
#[derive(Debug, clap::Args)]
struct SynthArgs {
    /// Scene description (TOML).
    desc: PathBuf,
    /// Output scan directory.
    out_dir: PathBuf,
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    let result = match cli.command {
        Command::Synth(a) => lab::synth::generate(&a.desc, &a.out_dir).map_err(anyhow::Error::from),
        Command::Bench(a) => run_bench(a.what),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run_bench(what: BenchCommand) -> anyhow::Result<()> {
    let ws = |w: Option<PathBuf>| w.unwrap_or_else(bench::default_workspace);
    match what {
        BenchCommand::Tradeoff(a) => {
            let opts = tradeoff::TradeoffOptions {
                workspace: ws(a.workspace),
                scenes: a.scenes,
                out: a.out.clone(),
                quick: a.quick,
                only: a.only,
            };
            if a.replot {
                tradeoff::replot(&opts)?;
            } else {
                tradeoff::run(&opts)?;
            }
            eprintln!("bench: wrote {}/tradeoff.{{csv,svg,md}}", a.out.display());
        }
        BenchCommand::Ablation(a) => {
            let opts = ablation::AblationOptions {
                workspace: ws(a.workspace),
                scene: a.scene,
                out: a.out.clone(),
                quick: a.quick,
            };
            ablation::run(&opts)?;
            eprintln!("bench: wrote {}/ablation_*.csv and ablation.svg", a.out.display());
        }
        BenchCommand::Mitsuba(a) => {
            let workspace = ws(a.workspace);
            let python = a.python.unwrap_or_else(|| workspace.join("deps/venv/bin/python"));
            let opts = mitsuba::MitsubaOptions {
                workspace,
                scene: a.scene,
                out: a.out,
                budget_seconds: a.budget_seconds,
                python,
                quick: a.quick,
            };
            mitsuba::run(&opts)?;
        }
        BenchCommand::Scale(a) => {
            let opts = scale::ScaleOptions {
                workspace: ws(a.workspace),
                out: a.out.clone(),
                axes: a.axes,
                quick: a.quick,
                set: a.set,
                keep: a.keep,
            };
            if a.replot {
                scale::replot(&opts.out)?;
                eprintln!("bench: wrote {}/scale.svg", a.out.display());
            } else {
                scale::run(&opts, |line| eprintln!("bench scale: {line}"))?;
                eprintln!("bench: wrote {}/scale.{{csv,svg,md}}", a.out.display());
            }
        }
        BenchCommand::Realistic(a) => {
            let workspace = ws(a.workspace);
            let beside = std::env::current_exe()?.with_file_name("pipeline");
            let opts = realistic::RealisticOptions {
                python: a.python.unwrap_or_else(|| workspace.join("deps/venv/bin/python")),
                pipeline: a.pipeline.unwrap_or(beside),
                workspace,
                corpus: a.corpus,
                scenes: a.scenes,
                presets: a.presets,
                out: a.out.clone(),
                runs: a.runs,
                set: a.set,
                render_spp: a.render_spp,
                fresh: a.fresh,
            };
            realistic::run(&opts, |line| eprintln!("bench realistic: {line}"))?;
            eprintln!("bench: wrote {}/realistic.{{csv,md,svg}}", a.out.display());
        }
        BenchCommand::ScalePoint(a) => scale::run_point(&a.config, &a.set, &a.stats)?,
    }
    Ok(())
}
