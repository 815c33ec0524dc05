//! `lab bench scale`: how the pipeline's cost grows with the scan. From the default scene's description
//! (`data-fixtures/scenes/demo.toml`) it varies one size at a time — triangles (every object subdivided
//! further), objects (small boxes added on the floor), photos (more cameras, jittered copies of the scene's),
//! resolution — generates each scan with our renderer, and runs the whole pipeline on it in a fresh process
//! (`lab bench scale-point`, so every point's peak memory is its own). Per point and stage it records wall
//! time, CPU time and peak RSS as the process measures them itself (`workflow::process_stats`: `/proc`'s
//! CPU ticks and `VmHWM`, i.e. `getrusage`'s `ru_maxrss`), cross-checked by `/usr/bin/time -v` when it
//! exists; the training and held-out pixel counts of the object fit; and the accuracy reached against the
//! scene's truth. Writes `scale.csv`, `scale.svg` (total wall time and peak RSS against each size, log–log)
//! and `scale.md` (the fitted exponent of each axis).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use workflow::plan::{Plan, StageId};
use workflow::stage_contract::{Silent, StageContext, StageError, StageExecutor};
use workflow::svg::{self, Panel, Series};

use super::BenchError;
use crate::synth::{self, desc::CameraSpec, desc::ObjectSpec, desc::SceneDesc, desc::Shape};

/// Photo paths per pixel of the generated scans: the scale sweep times the pipeline, not the photos' noise
/// (64 paths leave ~5 % per-pixel noise on the default scene, below the fit's own Monte Carlo noise).
const PHOTO_SPP: u32 = 64;

/// The CSV columns, in order: one row per (point, stage) and one per point with stage `total`.
pub const CSV_COLUMNS: [&str; 18] = [
    "axis",
    "value",
    "triangles",
    "objects",
    "photos",
    "width",
    "height",
    "pixels",
    "stage",
    "wall_s",
    "cpu_s",
    "peak_rss_mb",
    "time_v_peak_rss_mb",
    "load_avg_1m",
    "train_pixels",
    "holdout_pixels",
    "albedo_l1",
    "emission_rel_err",
];

/// What to run.
#[derive(Debug, Clone)]
pub struct ScaleOptions {
    pub workspace: PathBuf,
    pub out: PathBuf,
    /// Axes to sweep (`triangles`, `objects`, `photos`, `resolution`); empty = all.
    pub axes: Vec<String>,
    /// Two small points of the photo axis at tiny settings (a smoke test of the columns).
    pub quick: bool,
    /// Config overrides for every run (`key=value`, as `pipeline run --set`).
    pub set: Vec<String>,
    /// Keep each point's scan and run under this directory instead of deleting them.
    pub keep: Option<PathBuf>,
}

/// One point of the sweep: which size it varies and the scene description at that size.
#[derive(Debug, Clone)]
struct Point {
    axis: &'static str,
    value: u32,
    desc: SceneDesc,
}

/// The values of each axis (the first of each is the default scene's own size, except for objects and
/// triangles, whose first value adds nothing). Each axis reaches the house-sized scan of the corpus
/// (`scripts/corpus build house`) on that axis alone: 525 k triangles (subdivision +115), 213 objects (+204
/// boxes), 180 photos, 1280 pixels wide (a Matterport photo's width); the triangles go on to 1.02 M
/// (subdivision +161), the top of a Matterport house's 10⁵–10⁶, where the per-triangle stage must still fit
/// in memory.
fn axis_values(axis: &str, quick: bool) -> Vec<u32> {
    match (axis, quick) {
        (_, true) => vec![4, 8],
        ("triangles", _) => vec![0, 12, 36, 115, 161],
        ("objects", _) => vec![0, 24, 72, 204],
        ("photos", _) => vec![8, 32, 90, 180],
        ("resolution", _) => vec![48, 192, 640, 1280],
        _ => Vec::new(),
    }
}

/// Deterministic jitter in [-1, 1] from two integers (a sweep must not depend on a random-number crate's
/// version).
fn jitter(a: u64, b: u64) -> f32 {
    let mut x = a.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ b.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 31;
    x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 29;
    (x >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
}

fn point(base: &SceneDesc, axis: &'static str, value: u32, quick: bool) -> Point {
    let mut d = base.clone();
    d.spp = if quick { 8 } else { PHOTO_SPP };
    if quick {
        (d.width, d.height) = (32, 24);
    }
    match axis {
        "triangles" => d.objects.iter_mut().for_each(|o| o.subdivisions += value),
        "objects" => {
            let id0 = d.objects.iter().map(|o| o.id).max().unwrap_or(0) + 1;
            // A grid of boxes on the floor's inner part (2.8 m × 2.0 m), seeded colours: 20 cm boxes, smaller
            // where the grid's cells are (each box at most 80 % of its cell, so boxes never touch).
            let cols = (value as f32).sqrt().ceil().max(1.0) as u32;
            let half = 0.1_f32.min(0.4 * 2.0 / cols as f32);
            for i in 0..value {
                let (cx, cy) = (i % cols, i / cols);
                let x = 0.6 + 2.8 * (cx as f32 + 0.5) / cols as f32;
                let y = 0.5 + 2.0 * (cy as f32 + 0.5) / cols as f32;
                let c = |k: u64| 0.45 + 0.35 * jitter(u64::from(i), k);
                d.objects.push(ObjectSpec {
                    id: id0 + i as i32,
                    label: format!("box {i}"),
                    category_id: 39,
                    shape: Shape::Box { min: [x - half, y - half, 0.0], max: [x + half, y + half, 2.0 * half] },
                    subdivisions: 0,
                    base_color: [c(1), c(2), c(3)],
                    roughness: 0.5,
                    metallic: 0.0,
                    specular: 0.0,
                    emission: [0.0; 3],
                    emission_ground: None,
                    hidden: false,
                    checker: None,
                });
            }
        }
        "photos" => {
            let original = d.cameras.clone();
            d.cameras = (0..value as usize)
                .map(|k| {
                    let c = original[k % original.len()];
                    let round = (k / original.len()) as u64;
                    if round == 0 {
                        return c;
                    }
                    // Copies of the scene's cameras moved up to 25 cm sideways: new views of the same room.
                    let j = |axis: u64| 0.25 * jitter(k as u64, axis + 10 * round);
                    CameraSpec { eye: [c.eye[0] + j(0), c.eye[1] + j(1), c.eye[2]], ..c }
                })
                .collect();
        }
        "resolution" => {
            let aspect = base.height as f32 / base.width as f32;
            d.width = value;
            d.height = (value as f32 * aspect).round() as u32;
        }
        _ => {}
    }
    Point { axis, value, desc: d }
}

/// Per-stage costs measured inside the point's process.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct StageCost {
    pub wall_s: f64,
    pub cpu_s: f64,
    pub peak_rss_mb: f64,
}

/// Runs the real stages and records what each costs.
struct Measuring {
    costs: Vec<(String, StageCost)>,
}

impl StageExecutor for Measuring {
    fn is_implemented(&self, _stage: StageId) -> bool {
        true
    }

    fn run(&mut self, ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
        let (t0, c0) = (Instant::now(), workflow::process_stats::cpu_time_s().unwrap_or(f64::NAN));
        let out = workflow::stages::Stages.run(ctx)?;
        let cost = StageCost {
            wall_s: t0.elapsed().as_secs_f64(),
            cpu_s: workflow::process_stats::cpu_time_s().unwrap_or(f64::NAN) - c0,
            peak_rss_mb: workflow::process_stats::peak_rss_bytes().map_or(f64::NAN, |b| b as f64 / 1e6),
        };
        self.costs.push((ctx.stage.name().to_owned(), cost));
        Ok(out)
    }
}

/// `lab bench scale-point CONFIG STATS`: runs every stage of CONFIG in this process and writes each stage's
/// cost to STATS (JSON).
pub fn run_point(config: &Path, set: &[String], stats: &Path) -> Result<(), BenchError> {
    let plan = Plan::load(config, set).map_err(|e| BenchError::Io { path: config.into(), message: e.to_string() })?;
    let mut exec = Measuring { costs: Vec::new() };
    workflow::runner::run(&plan, workflow::runner::RunOptions::default(), &mut exec, &Silent)
        .map_err(|e| BenchError::Io { path: config.into(), message: e.to_string() })?;
    let text = serde_json::to_vec_pretty(&exec.costs).unwrap_or_default();
    super::write_file(stats, &text)
}

/// One measured point.
#[derive(Debug, Clone)]
struct Measured {
    point: Point,
    triangles: usize,
    costs: Vec<(String, StageCost)>,
    wall_s: f64,
    time_v_peak_rss_mb: f64,
    load_avg_1m: f64,
    train_pixels: usize,
    holdout_pixels: usize,
    albedo_l1: f64,
    emission_rel_err: f64,
}

/// `/usr/bin/time -v`'s "Maximum resident set size (kbytes)", in MB.
fn time_v_peak_rss_mb(stderr: &str) -> Option<f64> {
    let line = stderr.lines().find(|l| l.contains("Maximum resident set size (kbytes)"))?;
    let kb: f64 = line.rsplit(':').next()?.trim().parse().ok()?;
    Some(kb * 1024.0 / 1e6)
}

/// What running one config through every stage in its own process cost.
#[derive(Debug, Clone)]
pub(crate) struct ProcessRun {
    /// Per stage, as the process measured itself.
    pub costs: Vec<(String, StageCost)>,
    /// Wall time of the whole process, start-up included.
    pub wall_s: f64,
    /// `/usr/bin/time -v`'s peak RSS (NaN where it is not installed).
    pub time_v_peak_rss_mb: f64,
    /// 1-minute load average when the process started.
    pub load_avg_1m: f64,
}

/// A process run under `/usr/bin/time -v` (when it exists): its output, its wall time, the 1-minute load
/// average when it started, and `time -v`'s peak RSS (NaN without it).
pub(crate) struct Timed {
    pub output: std::process::Output,
    pub wall_s: f64,
    pub load_avg_1m: f64,
    pub time_v_peak_rss_mb: f64,
}

/// Runs `exe args…` under `/usr/bin/time -v` when it exists.
pub(crate) fn run_timed(exe: &Path, args: &[std::ffi::OsString]) -> Result<Timed, BenchError> {
    let time_v = Path::new("/usr/bin/time");
    let mut cmd = if time_v.is_file() {
        let mut c = Command::new(time_v);
        c.arg("-v").arg(exe);
        c
    } else {
        Command::new(exe)
    };
    let load_avg_1m = workflow::process_stats::load_average_1m().unwrap_or(f64::NAN);
    let t0 = Instant::now();
    let output = cmd
        .args(args)
        .output()
        .map_err(|e| BenchError::Io { path: exe.to_path_buf(), message: format!("cannot run: {e}") })?;
    let wall_s = t0.elapsed().as_secs_f64();
    let time_v_peak_rss_mb = time_v_peak_rss_mb(&String::from_utf8_lossy(&output.stderr)).unwrap_or(f64::NAN);
    Ok(Timed { output, wall_s, load_avg_1m, time_v_peak_rss_mb })
}

/// Runs `lab bench scale-point CONFIG STATS` (this binary) under `/usr/bin/time -v` when it exists and reads
/// the per-stage costs it wrote to `stats`.
pub(crate) fn run_in_process(config: &Path, stats: &Path, set: &[String]) -> Result<ProcessRun, BenchError> {
    let exe = std::env::current_exe().map_err(|e| BenchError::Io { path: "lab".into(), message: e.to_string() })?;
    let mut args: Vec<std::ffi::OsString> = vec!["bench".into(), "scale-point".into(), config.into(), stats.into()];
    for s in set {
        args.push("--set".into());
        args.push(s.into());
    }
    let run = run_timed(&exe, &args)?;
    if !run.output.status.success() {
        let stderr = String::from_utf8_lossy(&run.output.stderr);
        return Err(BenchError::Io { path: config.into(), message: format!("point failed: {}", stderr.trim()) });
    }
    let costs: Vec<(String, StageCost)> = serde_json::from_slice(
        &std::fs::read(stats).map_err(|e| BenchError::Io { path: stats.into(), message: e.to_string() })?,
    )
    .map_err(|e| BenchError::Io { path: stats.into(), message: e.to_string() })?;
    Ok(ProcessRun {
        costs,
        wall_s: run.wall_s,
        time_v_peak_rss_mb: run.time_v_peak_rss_mb,
        load_avg_1m: run.load_avg_1m,
    })
}

fn measure(p: Point, opts: &ScaleOptions, work: &Path) -> Result<Measured, BenchError> {
    let dir = work.join(format!("{}-{}", p.axis, p.value));
    let scan = dir.join("scan");
    let desc_path = opts.workspace.join("data-fixtures/scenes/demo.toml");
    let built = synth::build(p.desc.clone(), &desc_path)?;
    synth::write_scan(&built, &scan)?;
    let config = dir.join("run.toml");
    // At the scene's own path depth, so that the sweep measures the cost of scale, not of a depth mismatch.
    let text = synth::run_config(&scan, &built.desc);
    super::write_file(&config, text.as_bytes())?;
    let ProcessRun { costs, wall_s, time_v_peak_rss_mb, load_avg_1m } =
        run_in_process(&config, &dir.join("stats.json"), &opts.set)?;
    let out = dir.join("out");
    let history = workflow::artefacts::object::read_history(&out)
        .map_err(|e| BenchError::Io { path: out.clone(), message: e.to_string() })?;
    let materials = workflow::artefacts::object::read_result(&out)
        .map_err(|e| BenchError::Io { path: out.clone(), message: e.to_string() })?;
    let ids: Vec<i64> = built.desc.objects.iter().map(|o| i64::from(o.id)).collect();
    let params = materials
        .params_for(&ids, &out.join("object").join("materials.json"))
        .map_err(|e| BenchError::Io { path: out.clone(), message: e.to_string() })?;
    let acc = super::metrics::accuracy(&built, &params);
    let triangles = built.mesh.triangles.len();
    // The scan and run are large at the big points: only the numbers are kept, unless asked otherwise.
    match &opts.keep {
        Some(keep) => {
            let to = keep.join(format!("{}-{}", p.axis, p.value));
            let _ = std::fs::remove_dir_all(&to);
            std::fs::create_dir_all(keep)
                .and_then(|()| std::fs::rename(&dir, &to))
                .map_err(|e| BenchError::Io { path: to.clone(), message: e.to_string() })?;
        }
        None => {
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    Ok(Measured {
        point: p,
        triangles,
        costs,
        wall_s,
        time_v_peak_rss_mb,
        load_avg_1m,
        train_pixels: history.train_pixels,
        holdout_pixels: history.holdout_pixels,
        albedo_l1: acc.albedo_l1,
        emission_rel_err: acc.emission_rel_err,
    })
}

/// Runs the sweep; writes `scale.csv`, `scale.svg`, `scale.md` into `opts.out`.
pub fn run(opts: &ScaleOptions, mut on_point: impl FnMut(&str)) -> Result<(), BenchError> {
    let base = synth::load_desc(&opts.workspace.join("data-fixtures/scenes/demo.toml"))?;
    let axes: Vec<&'static str> = if opts.quick {
        vec!["photos"]
    } else {
        ["triangles", "objects", "photos", "resolution"]
            .into_iter()
            .filter(|a| opts.axes.is_empty() || opts.axes.iter().any(|x| x == a))
            .collect()
    };
    let work = tempfile_dir(&opts.out)?;
    let (mut rows, mut table) = (Vec::new(), String::new());
    for axis in axes {
        for value in axis_values(axis, opts.quick) {
            let m = measure(point(&base, axis, value, opts.quick), opts, &work)?;
            on_point(&format!(
                "{axis} = {value}: {} triangles, {} objects, {} photos of {}x{}: {:.1} s, peak RSS {:.0} MB",
                m.triangles,
                m.point.desc.objects.len(),
                m.point.desc.cameras.len(),
                m.point.desc.width,
                m.point.desc.height,
                m.wall_s,
                m.time_v_peak_rss_mb
            ));
            rows.push(m);
            table = csv(&rows);
            super::write_file(&opts.out.join("scale.csv"), table.as_bytes())?;
        }
    }
    let _ = std::fs::remove_dir_all(&work);
    // The plot is drawn from the CSV as written, so that `replot` redraws it exactly.
    let path = opts.out.join("scale.csv");
    let points = plot_points(&table).map_err(|message| BenchError::Io { path, message })?;
    super::write_file(&opts.out.join("scale.svg"), plot(&points).as_bytes())?;
    super::write_file(&opts.out.join("scale.md"), summary(&rows).as_bytes())?;
    Ok(())
}

/// Redraws `out/scale.svg` from `out/scale.csv` without running anything (the markdown, which names the
/// machine it ran on, stays as the run wrote it).
pub fn replot(out: &Path) -> Result<(), BenchError> {
    let path = out.join("scale.csv");
    let bad = |message: String| BenchError::Io { path: path.clone(), message };
    let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
    let points = plot_points(&text).map_err(bad)?;
    super::write_file(&out.join("scale.svg"), plot(&points).as_bytes())
}

fn tempfile_dir(out: &Path) -> Result<PathBuf, BenchError> {
    let dir = out.join(".scale-work");
    std::fs::create_dir_all(&dir).map_err(|e| BenchError::Io { path: dir.clone(), message: e.to_string() })?;
    // Absolute: the run configs written below it name their scan by this path.
    dir.canonicalize().map_err(|e| BenchError::Io { path: dir.clone(), message: e.to_string() })
}

fn pixels(m: &Measured) -> u64 {
    u64::from(m.point.desc.width) * u64::from(m.point.desc.height) * m.point.desc.cameras.len() as u64
}

fn csv(rows: &[Measured]) -> String {
    let mut s = CSV_COLUMNS.join(",");
    s.push('\n');
    for m in rows {
        let d = &m.point.desc;
        let peak = m.costs.iter().map(|(_, c)| c.peak_rss_mb).fold(0.0, f64::max);
        let cpu: f64 = m.costs.iter().map(|(_, c)| c.cpu_s).sum();
        let total = StageCost { wall_s: m.wall_s, cpu_s: cpu, peak_rss_mb: peak };
        for (stage, c) in m.costs.iter().map(|(s, c)| (s.as_str(), c)).chain([("total", &total)]) {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.1},{:.1},{:.2},{},{},{:.5},{:.5}",
                m.point.axis,
                m.point.value,
                m.triangles,
                d.objects.len(),
                d.cameras.len(),
                d.width,
                d.height,
                pixels(m),
                stage,
                c.wall_s,
                c.cpu_s,
                c.peak_rss_mb,
                m.time_v_peak_rss_mb,
                m.load_avg_1m,
                m.train_pixels,
                m.holdout_pixels,
                m.albedo_l1,
                m.emission_rel_err
            );
        }
    }
    s
}

/// The size an axis varies, as a number (in the CSV: the `triangles`, `objects`, `photos` or `pixels` column).
fn size(m: &Measured) -> f64 {
    match m.point.axis {
        "triangles" => m.triangles as f64,
        "objects" => m.point.desc.objects.len() as f64,
        "photos" => m.point.desc.cameras.len() as f64,
        _ => pixels(m) as f64,
    }
}

/// Least-squares slope of log(y) against log(x): the exponent of a power law.
fn exponent(pts: &[(f64, f64)]) -> f64 {
    let l: Vec<(f64, f64)> = pts.iter().filter(|(x, y)| *x > 0.0 && *y > 0.0).map(|(x, y)| (x.ln(), y.ln())).collect();
    let n = l.len() as f64;
    if l.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (l.iter().map(|p| p.0).sum::<f64>() / n, l.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = l.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = l.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    sxy / sxx
}

/// The distinct axes of `axes`, in order of first appearance.
fn axes_of<'a>(axes: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut a: Vec<&str> = Vec::new();
    for axis in axes {
        if !a.contains(&axis) {
            a.push(axis);
        }
    }
    a
}

fn axis_label(axis: &str) -> &'static str {
    match axis {
        "triangles" => "triangles",
        "objects" => "objects",
        "photos" => "photos",
        _ => "photo pixels (all photos)",
    }
}

/// One point of the plot: the axis it varies, its size on that axis ([`size`]), the whole pipeline's wall time
/// and its peak RSS by `/usr/bin/time -v`.
struct PlotPoint {
    axis: String,
    size: f64,
    wall_s: f64,
    rss_mb: f64,
}

/// The plot's points from the `total` rows of a [`CSV_COLUMNS`] table, in the table's order.
fn plot_points(text: &str) -> Result<Vec<PlotPoint>, String> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| header.iter().position(|c| *c == name).ok_or_else(|| format!("no column {name}"));
    let (axis, stage, wall, rss) = (col("axis")?, col("stage")?, col("wall_s")?, col("time_v_peak_rss_mb")?);
    let mut out = Vec::new();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != header.len() {
            return Err(format!("line {}: {} fields, the header has {}", i + 2, f.len(), header.len()));
        }
        if f[stage] != "total" {
            continue;
        }
        let num = |c: usize| f[c].parse::<f64>().map_err(|e| format!("line {}: {}: {e}", i + 2, header[c]));
        let size_col = match f[axis] {
            "triangles" | "objects" | "photos" => col(f[axis])?,
            _ => col("pixels")?,
        };
        out.push(PlotPoint { axis: f[axis].to_owned(), size: num(size_col)?, wall_s: num(wall)?, rss_mb: num(rss)? });
    }
    Ok(out)
}

fn plot(points: &[PlotPoint]) -> String {
    let mut panels = Vec::new();
    for axis in axes_of(points.iter().map(|p| p.axis.as_str())) {
        let r: Vec<&PlotPoint> = points.iter().filter(|p| p.axis == axis).collect();
        let wall: Vec<(f64, f64)> = r.iter().map(|p| (p.size, p.wall_s)).collect();
        let rss: Vec<(f64, f64)> = r.iter().map(|p| (p.size, p.rss_mb)).collect();
        panels.push(Panel {
            title: format!("wall time [s] against {}", axis_label(axis)),
            x_label: axis_label(axis).to_owned(),
            y_label: "s".to_owned(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                name: "whole pipeline".into(),
                color: "#1f77b4".into(),
                points: wall,
                line: true,
                markers: true,
            }],
        });
        panels.push(Panel {
            title: format!("peak RSS [MB] against {}", axis_label(axis)),
            x_label: axis_label(axis).to_owned(),
            y_label: "MB".to_owned(),
            log_x: true,
            log_y: true,
            series: vec![Series {
                name: "peak RSS".into(),
                color: "#d62728".into(),
                points: rss,
                line: true,
                markers: true,
            }],
        });
    }
    svg::render("Pipeline cost against scan size (one size varied at a time)", &panels, 2)
}

fn summary(rows: &[Measured]) -> String {
    let mut s = String::from("# Pipeline cost against scan size\n\n");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let load: Vec<f64> = rows.iter().map(|m| m.load_avg_1m).filter(|v| v.is_finite()).collect();
    let (lo, hi) = load.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    let _ = writeln!(
        s,
        "Measured by `lab bench scale` on {} ({cores} logical cores, 1-minute load average {lo:.1}–{hi:.1} at the \
         points' starts). Scans generated from `data-fixtures/scenes/demo.toml`, one size varied at a time; data in \
         `scale.csv`, plots in `scale.svg`.\n",
        std::env::consts::ARCH
    );
    let _ = writeln!(s, "| axis | sizes | wall time exponent | peak RSS exponent | held-out pixels |");
    let _ = writeln!(s, "|---|---|---|---|---|");
    for axis in axes_of(rows.iter().map(|m| m.point.axis)) {
        let r: Vec<&Measured> = rows.iter().filter(|m| m.point.axis == axis).collect();
        let sizes: Vec<String> = r.iter().map(|m| format!("{}", size(m))).collect();
        let e_wall = exponent(&r.iter().map(|m| (size(m), m.wall_s)).collect::<Vec<_>>());
        let e_rss = exponent(&r.iter().map(|m| (size(m), m.time_v_peak_rss_mb)).collect::<Vec<_>>());
        let held: Vec<String> = r.iter().map(|m| m.holdout_pixels.to_string()).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {e_wall:.2} | {e_rss:.2} | {} |",
            axis_label(axis),
            sizes.join(", "),
            held.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "\nThe exponent is the least-squares slope of log(cost) against log(size) over the axis's points: 1 is \
         linear growth. Fixed costs (start-up, the report) flatten it at small sizes."
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exponent_of_a_power_law_is_its_power() {
        let pts: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 8.0].iter().map(|&x: &f64| (x, 3.0 * x.powf(1.5))).collect();
        assert!((exponent(&pts) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn time_v_reports_kilobytes() {
        let text = "\tMaximum resident set size (kbytes): 31832\n";
        assert_eq!(time_v_peak_rss_mb(text), Some(31832.0 * 1024.0 / 1e6));
    }
}
