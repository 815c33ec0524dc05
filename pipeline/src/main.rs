//! `pipeline`: thin glue over the `workflow` library: parses the command line ([`cli`]), draws progress and
//! writes the run log ([`terminal`]), and turns errors into one line and an exit code.
//! Exit codes: 0 success, 1 failure while running, 2 bad usage or bad config (one line naming the key).

use std::process::ExitCode;

mod cli;
mod terminal;

use clap::Parser;
use cli::{Cli, Command};
use terminal::Terminal;
use workflow::config::ConfigError;
use workflow::plan::StageId;
use workflow::stage_contract::Reporter;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()))
        .with_writer(std::io::stderr)
        .init();
    let signals = terminal::Signals::install();
    match (execute(cli, &signals), signals.received()) {
        (Ok(()), _) => ExitCode::SUCCESS,
        (Err(e), Some((name, code))) => {
            eprintln!(
                "interrupted by {name}: finished stages and the last checkpoint are kept; run the same command \
                 again to resume ({})",
                one_line(&e.to_string())
            );
            ExitCode::from(code)
        }
        (Err(e), None) => {
            let code = if e.chain().any(is_bad_config) { 2 } else { 1 };
            // Our error types print their causes in their own message, so the top level is the whole story.
            eprintln!("error: {}", one_line(&e.to_string()));
            ExitCode::from(code)
        }
    }
}

fn execute(cli: Cli, signals: &terminal::Signals) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(args) => {
            let plan = workflow::plan::Plan::load(&args.config, &args.set)?;
            // Checked before any stage runs; the kernels in use decide how hits round (ARCHITECTURE.md).
            eprintln!("embree: {}", tracer::embree::device_info()?);
            let opts = workflow::runner::RunOptions { from: args.from, until: args.until };
            let terminal = Terminal::new(&plan.output, signals.clone());
            workflow::runner::run(&plan, opts, &mut workflow::stages::Stages, &terminal)?;
            let materials = plan.output.join("materials.json");
            let report = plan.output.join("export").join("report.html");
            if materials.is_file() && report.is_file() {
                eprintln!("results: {} and {}", materials.display(), report.display());
            }
            Ok(())
        }
        Command::Render(args) => {
            let terminal = Terminal::stderr_only();
            let progress = terminal.progress(StageId::Export, "rendering", 0);
            let n = workflow::render::render(&args.request(), progress.as_ref())?;
            drop(progress);
            eprintln!("[render] {n} views written to {}", args.output.display());
            Ok(())
        }
        Command::Export(args) => {
            workflow::stages::export::export_mesh(&args.run_dir, &Terminal::stderr_only(), None)?;
            Ok(())
        }
    }
}

/// A bad config file, `--set` value or `IPT_EMBREE_CONFIG`: exit code 2.
fn is_bad_config(e: &(dyn std::error::Error + 'static)) -> bool {
    e.downcast_ref::<ConfigError>().is_some()
        || matches!(e.downcast_ref::<tracer::embree::EmbreeError>(), Some(tracer::embree::EmbreeError::Config { .. }))
}

fn one_line(s: &str) -> String {
    s.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(" ")
}
