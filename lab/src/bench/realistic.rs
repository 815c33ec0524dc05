//! `lab bench realistic`: the quality presets measured on the realistic corpus (docs/realistic/README.md:
//! Mitsuba 3 renders of scenes our model does not describe exactly, built by `make corpus` into a directory
//! outside git). For every scan and preset it writes a config (the scan, the preset, the object seed), runs
//! `pipeline run` on it as a user would (its `run.log` shows progress and ETA; the stages' `done` lines give
//! wall time, CPU time and peak RSS per stage, [`workflow::runner::StageCost`], cross-checked by
//! `/usr/bin/time -v`), scores the run with the corpus scorer (`python -m corpus
//! score`: per-pixel albedo PSNR on held-out views, albedo L1 by kind, emitter IoU, emission error, novel-view
//! PSNR) and writes three files: `realistic.csv` (long form, one schema for costs and scores), `realistic.md`
//! (one row per scene and preset, the targets beside them) and `realistic.svg` (accuracy against CPU time per
//! scene: the presets as points of a front).
//!
//! Runs are kept under `--runs` (default `<corpus>/bench-runs/<scene>/<preset>/`) and a finished run is not
//! run again (its costs and scores are read back) unless `fresh` is set, so an interrupted benchmark resumes
//! where it stopped and a new scene or preset costs only its own runs.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use workflow::svg::{self, Panel, Series};

use super::BenchError;
use super::scale::{ProcessRun, StageCost};

/// The scenes measured by default, in this order (`tests/validation/corpus/scenes.py`).
pub const DEFAULT_SCENES: [&str; 4] = ["room-textured", "room-two-lights", "room-daylight", "modern-hall"];
/// The presets measured by default (`configs/README.md`, `quality`).
pub const DEFAULT_PRESETS: [&str; 3] = ["preview", "balanced", "final"];
/// The CSV columns: the scorer's columns with the preset after the scene. Costs are rows too: metric
/// `wall_s`, `cpu_s`, `peak_rss_mb` with the stage (or `total`) as subset; `time_v_peak_rss_mb` and
/// `load_avg_1m` with subset `total`.
pub const CSV_COLUMNS: [&str; 6] = ["scene", "preset", "metric", "subset", "value", "count"];

/// What to run.
#[derive(Debug, Clone)]
pub struct RealisticOptions {
    pub workspace: PathBuf,
    /// Directory holding one built scan per scene (`make corpus`).
    pub corpus: PathBuf,
    pub scenes: Vec<String>,
    pub presets: Vec<String>,
    pub out: PathBuf,
    /// Where the runs are kept (default `<corpus>/bench-runs`).
    pub runs: Option<PathBuf>,
    /// Config overrides for every run (`key=value`, as `pipeline run --set`).
    pub set: Vec<String>,
    /// Paths per pixel of the novel-view re-renders that the scorer compares with Mitsuba's.
    pub render_spp: u32,
    /// Python of the validation venv (default `<workspace>/deps/venv/bin/python`).
    pub python: PathBuf,
    /// `pipeline` binary the scorer renders with (default: beside this binary).
    pub pipeline: PathBuf,
    /// Run and score again even where a finished run is kept.
    pub fresh: bool,
}

/// One row of the CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub scene: String,
    pub preset: String,
    pub metric: String,
    pub subset: String,
    pub value: f64,
    pub count: u64,
}

/// Runs every (scene, preset) and writes `realistic.{csv,md,svg}` into `opts.out` (the CSV after each run, so
/// a long benchmark's finished part is on disk). `on_event` receives one line per run started and finished.
pub fn run(opts: &RealisticOptions, mut on_event: impl FnMut(&str)) -> Result<(), BenchError> {
    let runs_root = opts.runs.clone().unwrap_or_else(|| opts.corpus.join("bench-runs"));
    // Every scan is checked before the first run starts: a typo must not surface an hour in.
    let mut scans = Vec::new();
    for scene in &opts.scenes {
        let scan = opts.corpus.join(scene);
        if !scan.join("ground_truth.json").is_file() {
            return Err(BenchError::Io {
                path: scan,
                message: "not a built corpus scan (no ground_truth.json); `make corpus` or `scripts/corpus build` \
                          makes it"
                    .into(),
            });
        }
        scans.push((scene.clone(), canonical(&scan)?));
    }
    if opts.presets.is_empty() || scans.is_empty() {
        return Err(BenchError::Other("nothing to run: no scene or no preset".into()));
    }
    // The scorer runs in the validation tree: the binaries it is given must not depend on the working directory.
    // Not canonicalised: a venv's python is a symbolic link, and resolving it leaves the venv.
    let python = if opts.python.components().count() > 1 {
        std::path::absolute(&opts.python)
            .map_err(|e| BenchError::Io { path: opts.python.clone(), message: e.to_string() })?
    } else {
        opts.python.clone()
    };
    let opts = &RealisticOptions { pipeline: canonical(&opts.pipeline)?, python, ..opts.clone() };
    let total = scans.len() * opts.presets.len();
    let started = std::time::Instant::now();
    let mut rows = Vec::new();
    let mut done = 0usize;
    for (scene, scan) in &scans {
        for preset in &opts.presets {
            let dir = runs_root.join(scene).join(preset);
            on_event(&format!(
                "{scene} / {preset}: run {}/{total}{}",
                done + 1,
                eta(started.elapsed().as_secs_f64(), done, total)
            ));
            let r = run_one(opts, scene, preset, scan, &dir)?;
            on_event(&format!("{scene} / {preset}: {}", headline(&r)));
            rows.extend(r);
            done += 1;
            super::write_file(&opts.out.join("realistic.csv"), csv(&rows).as_bytes())?;
        }
    }
    super::write_file(&opts.out.join("realistic.md"), summary(&rows, &opts.set, opts.render_spp).as_bytes())?;
    super::write_file(&opts.out.join("realistic.svg"), plot(&rows).as_bytes())?;
    Ok(())
}

/// ", about 1h02m left" from the mean time of the runs done so far (nothing before the first is done).
fn eta(elapsed_s: f64, done: usize, total: usize) -> String {
    if done == 0 {
        return String::new();
    }
    let minutes = ((elapsed_s / done as f64 * (total - done) as f64).round() as u64).div_ceil(60);
    format!(", about {}h{:02}m left", minutes / 60, minutes % 60)
}

fn canonical(p: &Path) -> Result<PathBuf, BenchError> {
    std::fs::canonicalize(p).map_err(|e| BenchError::Io { path: p.to_path_buf(), message: e.to_string() })
}

/// The run's config: the scan, the preset and the seed; everything else at its default.
fn config_text(scan: &Path, run: &Path, preset: &str) -> String {
    format!(
        "quality = {preset:?}\n\n[scan]\npath = {:?}\nformat = \"matterport\"\ngroup_by = \"segment\"\n\n\
         [output]\npath = {:?}\n\n[object]\nseed = 0\n",
        scan.to_string_lossy(),
        run.to_string_lossy()
    )
}

/// Runs (or reads back) one scene at one preset, scores it, and returns its rows.
fn run_one(
    opts: &RealisticOptions,
    scene: &str,
    preset: &str,
    scan: &Path,
    dir: &Path,
) -> Result<Vec<Row>, BenchError> {
    let io = |path: &Path, e: std::io::Error| BenchError::Io { path: path.to_path_buf(), message: e.to_string() };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let dir = canonical(dir)?;
    let (run_dir, cost_file, scores) = (dir.join("run"), dir.join("cost.json"), dir.join("scores.csv"));
    let config = dir.join("config.toml");
    let kept = !opts.fresh && cost_file.is_file() && run_dir.join("materials.json").is_file();
    let cost = if kept {
        read_cost(&cost_file)?
    } else {
        // A fresh run: what an earlier run left would be resumed, not measured.
        for stale in [&run_dir, &scores] {
            if stale.is_dir() {
                std::fs::remove_dir_all(stale).map_err(|e| io(stale, e))?;
            } else if stale.is_file() {
                std::fs::remove_file(stale).map_err(|e| io(stale, e))?;
            }
        }
        super::write_file(&config, config_text(scan, &run_dir, preset).as_bytes())?;
        let r = run_pipeline(&opts.pipeline, &config, &run_dir, &opts.set)?;
        write_cost(&cost_file, &r)?;
        r
    };
    if opts.fresh || !scores.is_file() {
        score(opts, scan, &run_dir, &dir.join("renders"), &scores)?;
    }
    let mut rows = cost_rows(scene, preset, &cost);
    let text = std::fs::read_to_string(&scores).map_err(|e| io(&scores, e))?;
    let scored = parse_scores(&text, preset).map_err(|m| BenchError::Io { path: scores.clone(), message: m })?;
    // The scorer names the scene by its ground truth; the benchmark by the corpus directory.
    rows.extend(scored.into_iter().map(|r| Row { scene: scene.into(), ..r }));
    Ok(rows)
}

/// `pipeline run CONFIG` under `/usr/bin/time -v` when it exists; the per-stage costs from the run log.
fn run_pipeline(pipeline: &Path, config: &Path, run_dir: &Path, set: &[String]) -> Result<ProcessRun, BenchError> {
    let mut args: Vec<std::ffi::OsString> = vec!["run".into(), config.into()];
    for s in set {
        args.push("--set".into());
        args.push(s.into());
    }
    let run = super::scale::run_timed(pipeline, &args)?;
    if !run.output.status.success() {
        // The pipeline's own one-line error, not `/usr/bin/time`'s statistics after it.
        let stderr = String::from_utf8_lossy(&run.output.stderr);
        let why = stderr.lines().rev().find(|l| l.starts_with("error")).unwrap_or("no error line");
        return Err(BenchError::Io { path: config.to_path_buf(), message: format!("pipeline run failed: {why}") });
    }
    let log_path = run_dir.join("run.log");
    let log = std::fs::read_to_string(&log_path)
        .map_err(|e| BenchError::Io { path: log_path.clone(), message: e.to_string() })?;
    let costs = stage_costs(&log);
    if costs.is_empty() {
        return Err(BenchError::Io { path: log_path, message: "no stage finished (no `done` line)".into() });
    }
    Ok(ProcessRun {
        costs,
        wall_s: run.wall_s,
        time_v_peak_rss_mb: run.time_v_peak_rss_mb,
        load_avg_1m: run.load_avg_1m,
    })
}

/// Every `[stage] done (...)` line of a run log, in order, as (stage, cost).
fn stage_costs(log: &str) -> Vec<(String, StageCost)> {
    log.lines()
        .filter_map(|line| {
            let stage = line.split_once('[')?.1.split_once(']')?.0;
            let c = workflow::runner::StageCost::parse_done_message(line)?;
            Some((
                stage.to_owned(),
                StageCost {
                    wall_s: c.wall_s,
                    cpu_s: c.cpu_s.unwrap_or(f64::NAN),
                    peak_rss_mb: c.peak_rss_mb.unwrap_or(f64::NAN),
                },
            ))
        })
        .collect()
}

fn write_cost(path: &Path, r: &ProcessRun) -> Result<(), BenchError> {
    let v = serde_json::json!({
        "costs": r.costs,
        "wall_s": r.wall_s,
        "time_v_peak_rss_mb": finite_or_null(r.time_v_peak_rss_mb),
        "load_avg_1m": finite_or_null(r.load_avg_1m),
    });
    super::write_file(path, serde_json::to_string_pretty(&v).unwrap_or_default().as_bytes())
}

fn finite_or_null(x: f64) -> serde_json::Value {
    if x.is_finite() { serde_json::json!(x) } else { serde_json::Value::Null }
}

fn read_cost(path: &Path) -> Result<ProcessRun, BenchError> {
    let bad = |m: String| BenchError::Io { path: path.to_path_buf(), message: m };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let costs: Vec<(String, StageCost)> =
        serde_json::from_value(v["costs"].clone()).map_err(|e| bad(format!("costs: {e}")))?;
    let num = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    Ok(ProcessRun {
        costs,
        wall_s: num("wall_s"),
        time_v_peak_rss_mb: num("time_v_peak_rss_mb"),
        load_avg_1m: num("load_avg_1m"),
    })
}

/// `python -m corpus score SCAN RUN OUT.csv` in the validation tree.
fn score(opts: &RealisticOptions, scan: &Path, run: &Path, renders: &Path, out: &Path) -> Result<(), BenchError> {
    let validation = opts.workspace.join("tests/validation");
    let output = Command::new(&opts.python)
        .current_dir(&validation)
        .env("PYTHONPATH", &validation)
        .args(["-m", "corpus", "score"])
        .args([scan, run, out])
        .arg("--renders")
        .arg(renders)
        .arg("--pipeline")
        .arg(&opts.pipeline)
        .arg("--render-spp")
        .arg(opts.render_spp.to_string())
        .output()
        .map_err(|e| BenchError::Io { path: opts.python.clone(), message: format!("cannot run the scorer: {e}") })?;
    if !output.status.success() || !out.is_file() {
        let err = String::from_utf8_lossy(&output.stderr);
        let last = err.lines().last().unwrap_or("no message");
        return Err(BenchError::Io { path: run.to_path_buf(), message: format!("scoring failed: {last}") });
    }
    // The scorer only logs a failed novel-view render (its scores are still valid without them); a benchmark
    // without them is not: the scores are removed so that the next invocation scores again.
    let stdout = String::from_utf8_lossy(&output.stdout);
    if let Some(line) = stdout.lines().find(|l| l.starts_with("pipeline render failed")) {
        let _ = std::fs::remove_file(out);
        return Err(BenchError::Io { path: run.to_path_buf(), message: line.to_owned() });
    }
    Ok(())
}

fn cost_rows(scene: &str, preset: &str, r: &ProcessRun) -> Vec<Row> {
    let row = |metric: &str, subset: &str, value: f64| Row {
        scene: scene.into(),
        preset: preset.into(),
        metric: metric.into(),
        subset: subset.into(),
        value,
        count: 1,
    };
    let mut rows = Vec::new();
    for (stage, c) in &r.costs {
        rows.push(row("wall_s", stage, c.wall_s));
        rows.push(row("cpu_s", stage, c.cpu_s));
        rows.push(row("peak_rss_mb", stage, c.peak_rss_mb));
    }
    rows.push(row("wall_s", "total", r.wall_s));
    rows.push(row("cpu_s", "total", r.costs.iter().map(|(_, c)| c.cpu_s).sum()));
    rows.push(row("peak_rss_mb", "total", r.costs.iter().map(|(_, c)| c.peak_rss_mb).fold(0.0, f64::max)));
    rows.push(row("time_v_peak_rss_mb", "total", r.time_v_peak_rss_mb));
    rows.push(row("load_avg_1m", "total", r.load_avg_1m));
    rows
}

/// The scorer's CSV (`scene,metric,subset,value,count`) as rows of `preset`. Subsets may hold commas
/// (object labels), quoted as the `csv` module writes them.
fn parse_scores(text: &str, preset: &str) -> Result<Vec<Row>, String> {
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some("scene,metric,subset,value,count") {
        return Err("not the scorer's CSV (header scene,metric,subset,value,count)".into());
    }
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let f = split_csv(line);
        if f.len() != 5 {
            return Err(format!("line {}: {} fields, expected 5", i + 2, f.len()));
        }
        let value: f64 = f[3].parse().map_err(|_| format!("line {}: value {:?} is not a number", i + 2, f[3]))?;
        let count: u64 = f[4].parse().map_err(|_| format!("line {}: count {:?} is not an integer", i + 2, f[4]))?;
        rows.push(Row {
            scene: f[0].clone(),
            preset: preset.into(),
            metric: f[1].clone(),
            subset: f[2].clone(),
            value,
            count,
        });
    }
    Ok(rows)
}

/// Splits one CSV line (RFC 4180 quoting, no newlines inside fields).
fn split_csv(line: &str) -> Vec<String> {
    let (mut out, mut cur, mut quoted) = (Vec::new(), String::new(), false);
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            _ => cur.push(c),
        }
    }
    out.push(cur);
    out
}

fn quote(s: &str) -> String {
    if s.contains([',', '"']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_owned() }
}

/// The CSV text of `rows`.
#[must_use]
pub fn csv(rows: &[Row]) -> String {
    let mut s = CSV_COLUMNS.join(",");
    s.push('\n');
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{:.6},{}",
            quote(&r.scene),
            r.preset,
            r.metric,
            quote(&r.subset),
            r.value,
            r.count
        );
    }
    s
}

/// The value of `metric` for (scene, preset), in `subset` when one is named, else the first row of the metric.
fn lookup(rows: &[Row], scene: &str, preset: &str, metric: &str, subset: Option<&str>) -> Option<f64> {
    rows.iter()
        .find(|r| r.scene == scene && r.preset == preset && r.metric == metric && subset.is_none_or(|s| r.subset == s))
        .map(|r| r.value)
}

/// The albedo PSNR over one of the scorer's subsets of surfaces (`diffuse`, `textured`, ...): its row
/// `export <name>`, or `per-object <name>` for a run without an export.
fn subset_psnr(rows: &[Row], scene: &str, preset: &str, name: &str) -> Option<f64> {
    rows.iter()
        .find(|r| {
            r.scene == scene
                && r.preset == preset
                && r.metric == "albedo_psnr"
                && r.subset.strip_suffix(name).is_some_and(|head| head == "export " || head == "per-object ")
        })
        .map(|r| r.value)
}

fn value(rows: &[Row], scene: &str, preset: &str, metric: &str, subset: &str) -> Option<f64> {
    lookup(rows, scene, preset, metric, Some(subset))
}

/// The scenes in the order they ran.
fn scenes(rows: &[Row]) -> Vec<String> {
    let mut scenes: Vec<String> = Vec::new();
    for (scene, _) in pairs(rows) {
        if !scenes.contains(&scene) {
            scenes.push(scene);
        }
    }
    scenes
}

/// The (scene, preset) pairs in the order they ran.
fn pairs(rows: &[Row]) -> Vec<(String, String)> {
    let mut v: Vec<(String, String)> = Vec::new();
    for r in rows {
        if r.metric == "albedo_l1" && !v.iter().any(|(s, p)| *s == r.scene && *p == r.preset) {
            v.push((r.scene.clone(), r.preset.clone()));
        }
    }
    v
}

/// "preview: 12.3 dB albedo, IoU 0.50, 41 s CPU" for the progress line.
fn headline(rows: &[Row]) -> String {
    let get = |m: &str, s: &str| rows.iter().find(|r| r.metric == m && r.subset == s).map_or(f64::NAN, |r| r.value);
    let psnr = rows.iter().find(|r| r.metric == "albedo_psnr").map_or(f64::NAN, |r| r.value);
    format!(
        "albedo PSNR {psnr:.2} dB, albedo L1 {:.3}, emitter IoU {:.2}, novel PSNR {:.2} dB; {:.0} s wall, {:.0} s CPU",
        get("albedo_l1", "all"),
        get("emitter_iou", "objects"),
        get("novel_psnr", "run"),
        get("wall_s", "total"),
        get("cpu_s", "total")
    )
}

/// The targets the corpus is measured against (docs/realistic/README.md), per scene.
fn targets(scene: &str) -> &'static str {
    match scene {
        "modern-hall" => {
            "albedo PSNR ≥ 28 dB on diffuse surfaces, emitter IoU = 1, emission error ≤ 0.1 per light, \
                          novel-view PSNR ≥ 30 dB"
        }
        "room-daylight" => "the windows and nothing else emit (IoU = 1), novel-view PSNR ≥ 28 dB",
        s if s.starts_with("room-") => {
            "every light within 3 % per channel, albedo L1 ≤ 0.01 on untextured objects, \
                                         textured-surface albedo PSNR ≥ 30 dB"
        }
        _ => "none stated",
    }
}

fn summary(rows: &[Row], set: &[String], render_spp: u32) -> String {
    let mut s = String::from("# The presets on the realistic corpus\n\n");
    let load: Vec<f64> =
        rows.iter().filter(|r| r.metric == "load_avg_1m" && r.value.is_finite()).map(|r| r.value).collect();
    let (lo, hi) = load.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let _ = writeln!(
        s,
        "Measured by `lab bench realistic` ({cores} logical cores; 1-minute load average {lo:.1}–{hi:.1} when the \
         runs started). Each run: the whole pipeline on the scan with `quality` = the preset and `object.seed = 0`{}; \
         scored by `scripts/corpus score` with novel views rendered at {render_spp} paths per pixel. Data: \
         `realistic.csv`; plot: `realistic.svg`. Albedo PSNR is per pixel on the held-out views (export atlas), over all \
         non-emitting surfaces, over those whose true material is diffuse and over textured ones (the subsets the \
         targets name; an object is textured when its true base colour varies over the held-out views); \
         emission error is the mean over the true lights of ‖Δe‖₁/‖e‖₁ (a missed light counts 1).\n",
        if set.is_empty() { String::new() } else { format!(", overrides `{}`", set.join("`, `")) }
    );
    let _ = writeln!(
        s,
        "| scene | preset | wall | CPU | peak RSS | albedo PSNR all / diffuse / textured | albedo L1 diffuse / glossy / metal / untextured / all | emitter IoU \
         (object stage / export) | emission error (object / export) | novel PSNR run / truth materials |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---|---|---|---|");
    let f = |x: Option<f64>, d: usize| x.filter(|v| v.is_finite()).map_or("–".to_owned(), |v| format!("{v:.d$}"));
    for (scene, preset) in pairs(rows) {
        let v = |m: &str, sub: &str| value(rows, &scene, &preset, m, sub);
        let psnr = lookup(rows, &scene, &preset, "albedo_psnr", None);
        let (diffuse, textured) =
            (subset_psnr(rows, &scene, &preset, "diffuse"), subset_psnr(rows, &scene, &preset, "textured"));
        let _ = writeln!(
            s,
            "| {scene} | {preset} | {} s | {} s | {} MB | {} / {} / {} dB | {} / {} / {} / {} / {} | {} / {} | {} / {} | {} / {} dB |",
            f(v("wall_s", "total"), 0),
            f(v("cpu_s", "total"), 0),
            f(v("time_v_peak_rss_mb", "total").or(v("peak_rss_mb", "total")), 0),
            f(psnr, 2),
            f(diffuse, 2),
            f(textured, 2),
            f(v("albedo_l1", "diffuse"), 3),
            f(v("albedo_l1", "glossy"), 3),
            f(v("albedo_l1", "metal"), 3),
            f(v("albedo_l1", "untextured"), 3),
            f(v("albedo_l1", "all"), 3),
            f(v("emitter_iou", "objects"), 2),
            f(v("emitter_iou", "export"), 2),
            f(v("emission_rel_error", "mean"), 3),
            f(v("emission_rel_error", "export mean"), 3),
            f(v("novel_psnr", "run"), 2),
            f(v("novel_psnr", "truth-materials"), 2),
        );
    }
    let _ = writeln!(s, "\nTargets (default config):\n");
    for scene in &scenes(rows) {
        let _ = writeln!(s, "- {scene}: {}", targets(scene));
    }
    let _ = writeln!(
        s,
        "\nNovel-view PSNR is limited by the Monte Carlo noise of both renderers at these path counts: compare the \
         run with the truth materials through the same renderer, not with the target alone."
    );
    s
}

fn plot(rows: &[Row]) -> String {
    let mut panels = Vec::new();
    for scene in &scenes(rows) {
        let presets: Vec<String> = pairs(rows).into_iter().filter(|(s, _)| s == scene).map(|(_, p)| p).collect();
        let series_of = |name: &str, color: &str, y: &dyn Fn(&str) -> Option<f64>| {
            let points = presets
                .iter()
                .filter_map(|p| {
                    let cpu = value(rows, scene, p, "cpu_s", "total")?;
                    let y = y(p)?;
                    (cpu.is_finite() && y.is_finite()).then_some((cpu, y))
                })
                .collect();
            Series { name: name.into(), color: color.into(), points, line: true, markers: true }
        };
        let series = |name: &str, color: &str, metric: &str, subset: Option<&str>| {
            series_of(name, color, &|p| lookup(rows, scene, p, metric, subset))
        };
        let surfaces =
            |name: &str, color: &str, subset: &str| series_of(name, color, &|p| subset_psnr(rows, scene, p, subset));
        panels.push(Panel {
            title: format!("{scene}: PSNR against CPU time ({})", presets.join(" → ")),
            x_label: "CPU s (whole pipeline)".into(),
            y_label: "dB".into(),
            log_x: true,
            log_y: false,
            series: vec![
                series("albedo PSNR (held-out views)", svg::PALETTE[0], "albedo_psnr", None),
                surfaces("albedo PSNR, diffuse surfaces", svg::PALETTE[4], "diffuse"),
                surfaces("albedo PSNR, textured surfaces", svg::PALETTE[5], "textured"),
                series("novel-view PSNR", svg::PALETTE[1], "novel_psnr", Some("run")),
            ],
        });
        panels.push(Panel {
            title: format!("{scene}: albedo L1 and emitter IoU against CPU time"),
            x_label: "CPU s (whole pipeline)".into(),
            y_label: "L1 / IoU".into(),
            log_x: true,
            log_y: false,
            series: vec![
                series("albedo L1 (seen objects)", svg::PALETTE[2], "albedo_l1", Some("all")),
                series("emitter IoU", svg::PALETTE[3], "emitter_iou", Some("objects")),
            ],
        });
    }
    svg::render("The presets on the realistic corpus", &panels, 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scorers_csv_is_read_with_quoted_labels() {
        let text = "scene,metric,subset,value,count\nhall,albedo_psnr,export,19.36,1200\n\
                    hall,emission_rel_error,\"light, disk \"\"19\"\"\",0.25,1\n";
        let rows = parse_scores(text, "final").unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].subset, "light, disk \"19\"");
        assert_eq!(rows[1].preset, "final");
        assert!((rows[0].value - 19.36).abs() < 1e-12);
        // Written back, the label keeps its quoting and the row reads again.
        let line = csv(&rows[1..]).lines().nth(1).unwrap().to_owned();
        assert_eq!(split_csv(&line)[3], "light, disk \"19\"");
        assert!(parse_scores("scene,metric\n", "x").is_err());
        assert!(parse_scores("scene,metric,subset,value,count\nh,m,s,notanumber,1\n", "x").is_err());
    }

    #[test]
    fn costs_become_rows_with_a_total() {
        let c = |w, cpu, rss| StageCost { wall_s: w, cpu_s: cpu, peak_rss_mb: rss };
        let r = ProcessRun {
            costs: vec![("object".into(), c(10.0, 19.0, 100.0)), ("triangle".into(), c(5.0, 9.0, 150.0))],
            wall_s: 16.0,
            time_v_peak_rss_mb: 155.0,
            load_avg_1m: 1.5,
        };
        let rows = cost_rows("hall", "preview", &r);
        assert_eq!(value(&rows, "hall", "preview", "cpu_s", "total"), Some(28.0));
        assert_eq!(value(&rows, "hall", "preview", "peak_rss_mb", "total"), Some(150.0));
        assert_eq!(value(&rows, "hall", "preview", "wall_s", "triangle"), Some(5.0));
        assert_eq!(eta(100.0, 2, 6), ", about 0h04m left");
        assert_eq!(eta(100.0, 0, 6), "");
    }

    #[test]
    fn stage_costs_are_read_from_the_run_log() {
        let log = "1795626000 [ingest] running: no finished run\n\
                   1795626001 [ingest] done (3 outputs, 0.4 s, CPU 0.3 s, peak RSS 30 MB)\n\
                   1795626010 [object] fit: 37/212, 1m12s left\n\
                   1795626138 [object] done (2 outputs, 186.6 s, CPU 295.8 s, peak RSS 179 MB)\n";
        let c = stage_costs(log);
        assert_eq!(c.len(), 2);
        assert_eq!(c[1].0, "object");
        assert_eq!((c[1].1.wall_s, c[1].1.cpu_s, c[1].1.peak_rss_mb), (186.6, 295.8, 179.0));
    }
}
