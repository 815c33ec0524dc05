//! The stage runner: decides for each stage whether it is up to date (skip), must run (and says why), or
//! lies outside `--from`/`--until`; runs it through a [`StageExecutor`]; writes its manifest last.
//!
//! **Invariant:** a stage directory holds a manifest only if the stage finished with exactly the config and
//! inputs the manifest records. The runner deletes the old manifest before a stage runs and writes the new
//! one after every output is on disk.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::manifest::{self, Freshness, Manifest, ManifestError};
use crate::plan::{Plan, StageId};
use crate::stage_contract::{Reporter, StageContext, StageError, StageExecutor};

/// `--from` / `--until`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RunOptions {
    /// Start here: earlier stages are not run (their finished outputs are used) and this one reruns even
    /// if up to date.
    pub from: Option<StageId>,
    /// Stop after this stage.
    pub until: Option<StageId>,
}

/// What happened to one stage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StageOutcome {
    /// Up to date; not run.
    Skipped(String),
    /// Ran, for this reason.
    Ran(String),
    /// Outside `--from`/`--until`.
    NotSelected(String),
    /// Placeholder stage.
    NotImplemented,
}

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("stage `{stage}` needs the output of `{upstream}`, which has not finished; run without --from")]
    MissingUpstream { stage: StageId, upstream: StageId },
    #[error(
        "{path}: another pipeline run (process {pid}) is using this output directory; delete the file if it is not"
    )]
    Locked { path: PathBuf, pid: u32 },
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("--from {from} comes after --until {until}")]
    EmptyRange { from: StageId, until: StageId },
    #[error("stage `{stage}`: {source}")]
    Manifest {
        stage: StageId,
        #[source]
        source: ManifestError,
    },
    #[error("interrupted before stage `{stage}`")]
    Interrupted { stage: StageId },
    #[error("stage `{stage}` failed: {source}")]
    Stage {
        stage: StageId,
        #[source]
        source: StageError,
    },
}

/// Runs the plan's stages; returns each stage's outcome in order.
pub fn run(
    plan: &Plan,
    opts: RunOptions,
    exec: &mut dyn StageExecutor,
    reporter: &dyn Reporter,
) -> Result<Vec<(StageId, StageOutcome)>, RunError> {
    if let (Some(from), Some(until)) = (opts.from, opts.until)
        && from > until
    {
        return Err(RunError::EmptyRange { from, until });
    }
    let _lock = RunLock::acquire(&plan.output)?;
    let mut outcomes = Vec::new();
    // The first stage that ran in this invocation: everything after it reruns.
    let mut reran: Option<StageId> = None;
    for stage in StageId::ALL {
        let dir = plan.stage_dir(stage);
        if opts.from.is_some_and(|f| stage < f) {
            let note = match Manifest::read(&dir) {
                None => "before --from; not finished".to_owned(),
                Some(m) => {
                    let config_sha256 = manifest::sha256_json(&plan.stage_config(stage));
                    let stale = stage_inputs(plan, stage, exec)
                        .map(|inputs| m.freshness(&config_sha256, &inputs, &plan.output))
                        .unwrap_or(Freshness::Stale("its inputs are missing".to_owned()));
                    match stale {
                        Freshness::UpToDate => "before --from; its finished outputs are used".to_owned(),
                        Freshness::Stale(r) => format!("before --from; its outputs are used although {r}"),
                    }
                }
            };
            announce(reporter, stage, "not run", &note);
            outcomes.push((stage, StageOutcome::NotSelected(note)));
            continue;
        }
        if opts.until.is_some_and(|u| stage > u) {
            announce(reporter, stage, "not run", "after --until");
            outcomes.push((stage, StageOutcome::NotSelected("after --until".to_owned())));
            continue;
        }
        if !exec.is_implemented(stage) {
            announce(reporter, stage, "skipped", &format!("{stage} stage not implemented yet"));
            outcomes.push((stage, StageOutcome::NotImplemented));
            continue;
        }
        if reporter.stop_requested() {
            return Err(RunError::Interrupted { stage });
        }
        let config_sha256 = manifest::sha256_json(&plan.stage_config(stage));
        let inputs = stage_inputs(plan, stage, exec)?;
        let reason = if opts.from == Some(stage) {
            Some("--from starts here".to_owned())
        } else if let Some(up) = reran {
            Some(format!("upstream stage `{up}` reran"))
        } else {
            match Manifest::read(&dir) {
                None => Some("no finished run".to_owned()),
                Some(m) => match m.freshness(&config_sha256, &inputs, &plan.output) {
                    Freshness::UpToDate => None,
                    Freshness::Stale(r) => Some(r),
                },
            }
        };
        let Some(reason) = reason else {
            announce(reporter, stage, "skipped", "up to date (config and inputs unchanged)");
            outcomes.push((stage, StageOutcome::Skipped("up to date".to_owned())));
            continue;
        };
        announce(reporter, stage, "running", &reason);
        let manifest_err = |source| RunError::Manifest { stage, source };
        match std::fs::remove_file(dir.join(manifest::MANIFEST_FILE)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(manifest_err(ManifestError::Io { path: dir.join(manifest::MANIFEST_FILE), source: e }));
            }
            _ => {}
        }
        std::fs::create_dir_all(&dir)
            .map_err(|source| manifest_err(ManifestError::Io { path: dir.clone(), source }))?;
        remove_stale_temporaries(&dir);
        let inputs_sha256 = manifest::sha256_map(&inputs);
        let ctx = StageContext {
            plan,
            stage,
            dir: dir.clone(),
            config_sha256: config_sha256.clone(),
            inputs_sha256,
            reporter,
        };
        let started = std::time::Instant::now();
        let cpu_before = crate::process_stats::cpu_time_s().unwrap_or(0.0);
        let outputs = exec.run(&ctx).map_err(|source| RunError::Stage { stage, source })?;
        let m = Manifest::build(stage.name(), config_sha256, inputs, &plan.output, &outputs).map_err(manifest_err)?;
        m.write(&dir).map_err(manifest_err)?;
        tracing::info!(stage = stage.name(), outputs = outputs.len(), "stage finished");
        let cost = StageCost {
            wall_s: started.elapsed().as_secs_f64(),
            cpu_s: crate::process_stats::cpu_time_s().map(|c| c - cpu_before),
            peak_rss_mb: crate::process_stats::peak_rss_bytes().map(|b| b as f64 / 1e6),
        };
        reporter.note(stage, &cost.done_message(outputs.len()));
        reran.get_or_insert(stage);
        outcomes.push((stage, StageOutcome::Ran(reason)));
    }
    Ok(outcomes)
}

/// The inputs of `stage`: the scan's files for `ingest`, otherwise the output digests of its implemented
/// upstream stages.
fn stage_inputs(plan: &Plan, stage: StageId, exec: &dyn StageExecutor) -> Result<BTreeMap<String, String>, RunError> {
    if stage == StageId::Ingest {
        return manifest::digest_tree(&plan.scan.path, Some(&plan.output))
            .map_err(|source| RunError::Manifest { stage, source });
    }
    let mut inputs = BTreeMap::new();
    for &up in stage.upstream() {
        if !exec.is_implemented(up) {
            continue;
        }
        let m = Manifest::read(&plan.stage_dir(up)).ok_or(RunError::MissingUpstream { stage, upstream: up })?;
        inputs.insert(format!("stage:{up}"), m.outputs_sha256);
    }
    Ok(inputs)
}

/// `output.path/.lock`: holds the pid of the run using the directory, so two runs never write the same
/// stages at once. A lock whose process is gone (killed) is taken over; liveness is read from `/proc`, so
/// on systems without it every lock counts as stale.
#[derive(Debug)]
struct RunLock {
    path: PathBuf,
}

impl RunLock {
    fn acquire(output: &std::path::Path) -> Result<Self, RunError> {
        let path = output.join(".lock");
        let io = |source| RunError::Io { path: path.clone(), source };
        std::fs::create_dir_all(output).map_err(io)?;
        let me = std::process::id();
        if let Some(pid) = std::fs::read_to_string(&path).ok().and_then(|t| t.trim().parse::<u32>().ok())
            && pid != me
            && std::path::Path::new("/proc").join(pid.to_string()).exists()
        {
            return Err(RunError::Locked { path, pid });
        }
        std::fs::write(&path, me.to_string()).map_err(io)?;
        Ok(Self { path })
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Removes temporaries of atomic writes that a killed run left in `dir` (`.<name>.tmp.<pid>.<n>`; the
/// finished files they were meant to replace are untouched).
fn remove_stale_temporaries(dir: &std::path::Path) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.contains(".tmp.") {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// What a stage cost, as the process measured itself: wall time, CPU time of the whole process during the stage
/// (all threads), and the process's peak RSS so far (`VmHWM`). Reported as the stage's last message, which
/// [`StageCost::parse_done_message`] reads back from a run log (the benchmarks' per-stage costs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageCost {
    pub wall_s: f64,
    pub cpu_s: Option<f64>,
    pub peak_rss_mb: Option<f64>,
}

impl StageCost {
    /// `done (2 outputs, 186.6 s, CPU 295.8 s, peak RSS 179 MB)`.
    #[must_use]
    pub fn done_message(&self, outputs: usize) -> String {
        let cpu = self.cpu_s.map(|c| format!(", CPU {c:.1} s")).unwrap_or_default();
        let rss = self.peak_rss_mb.map(|m| format!(", peak RSS {m:.0} MB")).unwrap_or_default();
        format!("done ({outputs} outputs, {:.1} s{cpu}{rss})", self.wall_s)
    }

    /// The cost in a message written by [`Self::done_message`] (anything before `done (` is ignored, so a
    /// whole run-log line may be given); `None` for any other message.
    #[must_use]
    pub fn parse_done_message(line: &str) -> Option<Self> {
        let (_, rest) = line.split_once("done (")?;
        let inner = rest.strip_suffix(')')?;
        let mut parts = inner.split(", ");
        parts.next()?.strip_suffix(" outputs")?.parse::<usize>().ok()?;
        let wall_s = parts.next()?.strip_suffix(" s")?.parse().ok()?;
        let (mut cpu_s, mut peak_rss_mb) = (None, None);
        for p in parts {
            if let Some(v) = p.strip_prefix("CPU ").and_then(|v| v.strip_suffix(" s")) {
                cpu_s = Some(v.parse().ok()?);
            } else if let Some(v) = p.strip_prefix("peak RSS ").and_then(|v| v.strip_suffix(" MB")) {
                peak_rss_mb = Some(v.parse().ok()?);
            } else {
                return None;
            }
        }
        Some(Self { wall_s, cpu_s, peak_rss_mb })
    }
}

fn announce(reporter: &dyn Reporter, stage: StageId, what: &str, why: &str) {
    tracing::info!(stage = stage.name(), what, why, "stage decision");
    reporter.note(stage, &format!("{what}: {why}"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_done_message_reads_back_as_its_cost() {
        let c = StageCost { wall_s: 186.6, cpu_s: Some(295.8), peak_rss_mb: Some(179.0) };
        let line = format!("1795626138 [object] {}", c.done_message(2));
        assert_eq!(line, "1795626138 [object] done (2 outputs, 186.6 s, CPU 295.8 s, peak RSS 179 MB)");
        assert_eq!(StageCost::parse_done_message(&line), Some(c));
        let bare = StageCost { wall_s: 0.5, cpu_s: None, peak_rss_mb: None };
        assert_eq!(StageCost::parse_done_message(&bare.done_message(0)), Some(bare));
        assert_eq!(StageCost::parse_done_message("[object] fit: 37/212, 1m12s left"), None);
        assert_eq!(StageCost::parse_done_message("done (two outputs, 1 s)"), None);
    }

    /// Writes one file per stage whose content is a function of the stage's config and inputs (as a real
    /// stage's would be), and counts calls.
    struct Recorder {
        ran: Vec<StageId>,
        implemented_triangle: bool,
    }

    impl StageExecutor for Recorder {
        fn is_implemented(&self, stage: StageId) -> bool {
            stage != StageId::Triangle || self.implemented_triangle
        }

        fn run(&mut self, ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
            self.ran.push(ctx.stage);
            let rel = PathBuf::from(ctx.stage.name()).join("out.txt");
            let text = format!("{} {}", ctx.config_sha256, ctx.inputs_sha256);
            crate::atomic_file::write_atomic(&ctx.plan.output.join(&rel), text.as_bytes())?;
            Ok(vec![rel])
        }
    }

    fn setup() -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("scan")).unwrap();
        std::fs::write(dir.path().join("scan/mesh.ply"), b"v1").unwrap();
        let cfg = dir.path().join("run.toml");
        std::fs::write(&cfg, "[scan]\npath = \"scan\"\n[output]\npath = \"out\"\n").unwrap();
        (dir, cfg)
    }

    fn go(cfg: &std::path::Path, sets: &[&str], opts: RunOptions) -> Vec<StageId> {
        let sets: Vec<String> = sets.iter().map(|s| (*s).to_owned()).collect();
        let plan = Plan::load(cfg, &sets).unwrap();
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        run(&plan, opts, &mut rec, &crate::stage_contract::Silent).unwrap();
        rec.ran
    }

    use StageId::{Export, Ingest, Object, Preprocess};

    #[test]
    fn second_run_skips_everything_and_a_stage_key_reruns_that_stage_and_later() {
        let (_d, cfg) = setup();
        assert_eq!(go(&cfg, &[], RunOptions::default()), [Ingest, Preprocess, Object, Export]);
        assert_eq!(go(&cfg, &[], RunOptions::default()), []);
        assert_eq!(go(&cfg, &["object.lr=0.5"], RunOptions::default()), [Object, Export]);
        assert_eq!(go(&cfg, &["object.lr=0.5"], RunOptions::default()), []);
        assert_eq!(
            go(&cfg, &["object.lr=0.5", "images.downscale=2"], RunOptions::default()),
            [Preprocess, Object, Export]
        );
    }

    #[test]
    fn temporaries_of_a_killed_write_are_removed_when_the_stage_reruns() {
        let (d, cfg) = setup();
        go(&cfg, &[], RunOptions::default());
        let stale = d.path().join("out/object/.materials.json.tmp.999.0");
        std::fs::write(&stale, b"half").unwrap();
        std::fs::remove_file(d.path().join("out/object/manifest.json")).unwrap();
        assert_eq!(go(&cfg, &[], RunOptions::default()), [Object, Export]);
        assert!(!stale.exists());
    }

    #[test]
    fn a_live_lock_refuses_the_run_and_a_dead_one_is_taken_over() {
        let (d, cfg) = setup();
        let plan = Plan::load(&cfg, &[]).unwrap();
        std::fs::create_dir_all(&plan.output).unwrap();
        // pid 1 (init) is alive on every Linux system.
        std::fs::write(plan.output.join(".lock"), "1").unwrap();
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        if std::path::Path::new("/proc/1").exists() {
            let e = run(&plan, RunOptions::default(), &mut rec, &crate::stage_contract::Silent).unwrap_err();
            assert!(matches!(e, RunError::Locked { pid: 1, .. }), "{e}");
        }
        // A pid above Linux's pid_max (2^22) never belongs to a live process.
        std::fs::write(plan.output.join(".lock"), "4194305").unwrap();
        run(&plan, RunOptions::default(), &mut rec, &crate::stage_contract::Silent).unwrap();
        assert!(!d.path().join("out/.lock").exists(), "lock not released");
    }

    #[test]
    fn changed_scan_file_reruns_from_ingest() {
        let (d, cfg) = setup();
        go(&cfg, &[], RunOptions::default());
        std::fs::write(d.path().join("scan/mesh.ply"), b"v2").unwrap();
        assert_eq!(go(&cfg, &[], RunOptions::default()), [Ingest, Preprocess, Object, Export]);
    }

    #[test]
    fn deleted_output_reruns_its_stage() {
        let (d, cfg) = setup();
        go(&cfg, &[], RunOptions::default());
        std::fs::remove_file(d.path().join("out/preprocess/out.txt")).unwrap();
        assert_eq!(go(&cfg, &[], RunOptions::default()), [Preprocess, Object, Export]);
    }

    #[test]
    fn until_stops_and_later_stages_catch_up_next_time() {
        let (_d, cfg) = setup();
        let until = RunOptions { from: None, until: Some(Preprocess) };
        assert_eq!(go(&cfg, &[], until), [Ingest, Preprocess]);
        assert_eq!(go(&cfg, &[], RunOptions::default()), [Object, Export]);
        // Preprocess reran alone under --until: object's recorded input no longer matches.
        assert_eq!(go(&cfg, &["images.every=2"], until), [Preprocess]);
        assert_eq!(go(&cfg, &["images.every=2"], RunOptions::default()), [Object, Export]);
    }

    #[test]
    fn from_forces_that_stage_and_needs_finished_upstream() {
        let (_d, cfg) = setup();
        let plan = Plan::load(&cfg, &[]).unwrap();
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        let e = run(&plan, RunOptions { from: Some(Object), until: None }, &mut rec, &crate::stage_contract::Silent)
            .unwrap_err();
        assert!(matches!(e, RunError::MissingUpstream { stage: Object, upstream: Ingest }), "{e}");
        go(&cfg, &[], RunOptions::default());
        assert_eq!(go(&cfg, &[], RunOptions { from: Some(Object), until: None }), [Object, Export]);
        // A stale earlier stage is reported, not rerun.
        let plan = Plan::load(&cfg, &["images.every=3".to_owned()]).unwrap();
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        let out = run(&plan, RunOptions { from: Some(Export), until: None }, &mut rec, &crate::stage_contract::Silent)
            .unwrap();
        assert_eq!(rec.ran, [Export]);
        assert!(matches!(&out[1].1, StageOutcome::NotSelected(n) if n.contains("config section changed")), "{out:?}");
        let bad = RunOptions { from: Some(Export), until: Some(Ingest) };
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        assert!(matches!(run(&plan, bad, &mut rec, &crate::stage_contract::Silent), Err(RunError::EmptyRange { .. })));
    }

    #[test]
    fn placeholder_stage_keeps_its_slot_and_joins_the_inputs_once_implemented() {
        let (_d, cfg) = setup();
        let plan = Plan::load(&cfg, &[]).unwrap();
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: false };
        let out = run(&plan, RunOptions::default(), &mut rec, &crate::stage_contract::Silent).unwrap();
        assert_eq!(out[3], (StageId::Triangle, StageOutcome::NotImplemented));
        assert!(!plan.stage_dir(StageId::Triangle).exists());
        let mut rec = Recorder { ran: Vec::new(), implemented_triangle: true };
        run(&plan, RunOptions::default(), &mut rec, &crate::stage_contract::Silent).unwrap();
        assert_eq!(rec.ran, [StageId::Triangle, Export]);
    }
}
