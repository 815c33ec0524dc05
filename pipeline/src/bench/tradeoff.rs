//! `pipeline bench tradeoff`: sweeps the fit's cost settings on each scene, one at a time around the default
//! and at a few joint corners, and writes `tradeoff.csv`, `tradeoff.svg` (error against time, Pareto front
//! marked) and `tradeoff.md` into the output directory.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::metrics::{self, Accuracy};
use super::scenes::{self, BenchScene};
use super::svg::{self, Panel, Series};
use super::{BenchError, FitSetup};
use crate::fit::ObjectFitSettings;

/// Paths per pixel of the re-renders of the held-back views: their own noise (relative L1 ≈ 1–2 % on the
/// demo's 96×72 views, measured by rendering the truth the same way) is the floor of that column.
const HOLDOUT_RENDER_SPP: u32 = 256;
/// Same in `--quick` mode (a smoke test: only well-formedness matters).
const QUICK_HOLDOUT_RENDER_SPP: u32 = 8;
/// Photo paths per pixel of scenes rendered in memory in `--quick` mode (the committed scans use 1024).
const QUICK_PHOTO_SPP: u32 = 16;
/// Seed of the held-back renders (fixed: every point is compared on the same random numbers).
const HOLDOUT_SEED: u64 = 0x5eed;

/// What to run.
#[derive(Debug, Clone)]
pub struct TradeoffOptions {
    pub workspace: PathBuf,
    pub scenes: Vec<String>,
    pub out: PathBuf,
    pub quick: bool,
    /// Run only the points with these labels (empty = the whole sweep).
    pub only: Vec<String>,
}

/// One point of the sweep.
#[derive(Debug, Clone)]
pub struct SweepPoint {
    /// Which setting the point varies (`default`, `n_value`, ..., `corner`).
    pub group: String,
    /// Unique name within the sweep.
    pub label: String,
    pub setup: FitSetup,
}

/// One measured row of `tradeoff.csv`.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub point: SweepPoint,
    pub seconds: f64,
    pub paths: u64,
    pub rays: u64,
    pub accuracy: Accuracy,
    /// Relative L1 of the held-back views re-rendered with the fitted materials.
    pub rerender_l1: f64,
    /// The same for the true materials (the noise floor of `rerender_l1`).
    pub rerender_l1_truth: f64,
    /// On the (seconds, albedo_l1) Pareto front of its scene.
    pub pareto: bool,
}

/// The CSV columns, in order.
pub const CSV_COLUMNS: [&str; 24] = [
    "scene",
    "group",
    "label",
    "iterations",
    "batch_pixels",
    "n_value",
    "n_grad",
    "solve_pixels",
    "solve_spp",
    "refine_steps",
    "try_specular",
    "max_depth",
    "downscale",
    "wall_time_s",
    "paths",
    "rays",
    "albedo_l1",
    "emission_rel_err",
    "spurious_emission",
    "roughness_err",
    "rerender_l1",
    "rerender_l1_truth",
    "pareto",
    "models",
];

/// The sweep around `base` (the default settings with the scene's own max depth).
#[must_use]
pub fn sweep_points(base: &FitSetup, quick: bool) -> Vec<SweepPoint> {
    let mut pts = Vec::new();
    let mut add = |group: &'static str, label: String, f: &dyn Fn(&mut FitSetup)| {
        let mut s = base.clone();
        f(&mut s);
        pts.push(SweepPoint { group: group.to_owned(), label, setup: s });
    };
    if quick {
        let tiny = |s: &mut FitSetup| {
            let o = &mut s.object;
            (o.iterations, o.batch_pixels, o.n_value, o.solve_pixels, o.solve_spp) = (2, 16, 4, 64, 4);
            (o.refine_steps, o.holdout_spp, o.try_specular, o.emission_solve_every) = (2, 8, false, 0);
            s.max_depth = 3;
        };
        add("corner", "quick".into(), &tiny);
        add("downscale", "quick/downscale=2".into(), &|s| {
            tiny(s);
            s.downscale = 2;
        });
        return pts;
    }
    // Measured on 2 shared cores, a default demo fit takes 2–3 minutes, most of it in the closed-form solves,
    // the refinement, the specular trial and the held-out model tests; the Adam settings barely move the
    // time. The sweep keeps the run near half an hour: the joint corners first (the preset candidates), then
    // one value per setting, cheapest first.
    for c in corners(base) {
        add("corner", c.label, &move |s| *s = c.setup.clone());
    }
    for v in [4, 2] {
        add("downscale", format!("downscale={v}"), &move |s| s.downscale = v);
    }
    for v in [2, 4] {
        add("max_depth", format!("max_depth={v}"), &move |s| s.max_depth = v);
    }
    add("holdout_spp", "holdout_spp=64".into(), &|s| s.object.holdout_spp = 64);
    add("try_specular", "try_specular=false".into(), &|s| s.object.try_specular = false);
    add("solve_spp", "solve_spp=32".into(), &|s| s.object.solve_spp = 32);
    add("solve_pixels", "solve_pixels=256".into(), &|s| s.object.solve_pixels = 256);
    add("refine_steps", "refine_steps=4".into(), &|s| s.object.refine_steps = 4);
    add("iterations", "iterations=0".into(), &|s| s.object.iterations = 0);
    add("default", "default".into(), &|_| {});
    add("n_value", "n_value=8".into(), &|s| s.object.n_value = 8);
    add("n_value", "n_value=512".into(), &|s| s.object.n_value = 512);
    add("n_grad", "n_grad=4".into(), &|s| s.object.n_grad = 4);
    add("batch_pixels", "batch_pixels=256".into(), &|s| s.object.batch_pixels = 256);
    pts
}

/// Joint corners: candidates for the presets (cheap everywhere, middle, expensive everywhere).
#[must_use]
pub fn corners(base: &FitSetup) -> Vec<SweepPoint> {
    let mk = |label: &str, it, nv, sp, ss, rs, spec, depth: Option<u32>, ds, hs| {
        let mut s = base.clone();
        let o = &mut s.object;
        (o.iterations, o.n_value, o.solve_pixels, o.solve_spp, o.refine_steps, o.try_specular) =
            (it, nv, sp, ss, rs, spec);
        o.holdout_spp = hs;
        if let Some(d) = depth {
            s.max_depth = d;
        }
        s.downscale = ds;
        SweepPoint { group: "corner".into(), label: label.into(), setup: s }
    };
    vec![
        mk("corner:tiny", 10, 16, 128, 32, 4, false, Some(3), 4, 32),
        mk("corner:fast", 25, 32, 256, 64, 4, false, Some(4), 2, 64),
        mk("corner:fast-full-res", 25, 32, 256, 64, 4, true, None, 1, 128),
        mk("corner:mid", 50, 128, 512, 128, 8, true, None, 1, 256),
        mk("corner:fast-depth8", 25, 32, 256, 64, 4, false, None, 2, 64),
        mk("corner:mid-ds2", 50, 128, 512, 128, 8, true, None, 2, 128),
    ]
}

/// The points run on every scene but the default scene `demo` (which gets the whole sweep).
pub const SECONDARY_SCENE_POINTS: [&str; 7] = [
    "corner:tiny",
    "corner:fast",
    "corner:fast-full-res",
    "corner:mid",
    "downscale=2",
    "try_specular=false",
    "default",
];

/// The base setup of a scene: default fit settings, the scene's own max depth, full resolution.
#[must_use]
pub fn base_setup(scene: &BenchScene) -> FitSetup {
    FitSetup { object: ObjectFitSettings::default(), max_depth: scene.built.settings.max_depth, downscale: 1 }
}

/// The held-back views of a scene: its last view (the fit never sees it).
#[must_use]
pub fn holdout_views(scene: &BenchScene) -> (Vec<usize>, Vec<usize>) {
    let n = scene.built.cameras.len();
    if n < 2 {
        return ((0..n).collect(), Vec::new());
    }
    ((0..n - 1).collect(), vec![n - 1])
}

/// Relative L1 of the held-back views rendered with `params` (at full resolution, the scene's own depth).
pub fn rerender_l1(scene: &BenchScene, views: &[usize], params: &tracer::Params, spp: u32) -> Result<f64, BenchError> {
    let mut v = Vec::new();
    for &k in views {
        let img = tracer::render_image(
            &scene.built.scene,
            params,
            &scene.built.cameras[k],
            spp,
            &scene.built.settings,
            HOLDOUT_SEED,
            k as u64,
        )?;
        v.push(metrics::relative_l1(&img, &scene.photos[k].rgb));
    }
    Ok(metrics::mean(&v))
}

/// Runs the sweep on every scene and writes the outputs. Returns the rows.
pub fn run(opts: &TradeoffOptions) -> Result<Vec<Row>, BenchError> {
    let mut rows = Vec::new();
    let holdout_spp = if opts.quick { QUICK_HOLDOUT_RENDER_SPP } else { HOLDOUT_RENDER_SPP };
    for name in &opts.scenes {
        let mut scene = load_scene(&opts.workspace, name, opts.quick)?;
        if opts.quick {
            scene.built.settings.max_depth = scene.built.settings.max_depth.min(3);
        }
        let (train, held) = holdout_views(&scene);
        let floor = rerender_l1(&scene, &held, &scene.built.params, holdout_spp)?;
        let base = base_setup(&scene);
        let first = rows.len();
        for point in sweep_points(&base, opts.quick) {
            if !opts.only.is_empty() && !opts.only.contains(&point.label) {
                continue;
            }
            if !opts.quick
                && opts.only.is_empty()
                && scene.name != "demo"
                && !SECONDARY_SCENE_POINTS.contains(&point.label.as_str())
            {
                continue;
            }
            if !scenes::divisible(&scene, point.setup.downscale) {
                eprintln!("bench: {}: skipping {} (image size not divisible)", scene.name, point.label);
                continue;
            }
            let fit = super::timed_fit(&scene, &train, &point.setup)?;
            let accuracy = metrics::accuracy(&scene.built, &fit.outcome.params);
            let rerender = rerender_l1(&scene, &held, &fit.outcome.params, holdout_spp)?;
            eprintln!(
                "bench: {:>7} {:<24} {:7.2} s  albedo L1 {:.4}  emission {:.4}  roughness {:.3}  re-render {:.4} (truth {:.4})",
                scene.name,
                point.label,
                fit.seconds,
                accuracy.albedo_l1,
                accuracy.emission_rel_err,
                accuracy.roughness_err,
                rerender,
                floor
            );
            let models = fit.outcome.per_object.iter().map(|m| m.model.as_str()).collect::<Vec<_>>().join(";");
            rows.push((
                Row {
                    scene: scene.name.clone(),
                    point,
                    seconds: fit.seconds,
                    paths: fit.paths,
                    rays: fit.rays,
                    accuracy,
                    rerender_l1: rerender,
                    rerender_l1_truth: floor,
                    pareto: false,
                },
                models,
            ));
            // Written after every point so that an interrupted sweep keeps what it measured.
            let (r, m): (Vec<Row>, Vec<String>) = rows.iter().cloned().unzip();
            super::write_file(&opts.out.join("tradeoff.csv"), csv(&r, &m).as_bytes())?;
        }
        let pts: Vec<(f64, f64)> = rows[first..].iter().map(|(r, _)| (r.seconds, r.accuracy.albedo_l1)).collect();
        for i in svg::pareto_front(&pts) {
            rows[first + i].0.pareto = true;
        }
    }
    let (rows, models): (Vec<Row>, Vec<String>) = rows.into_iter().unzip();
    write_outputs(&rows, &models, opts)?;
    Ok(rows)
}

fn write_outputs(rows: &[Row], models: &[String], opts: &TradeoffOptions) -> Result<(), BenchError> {
    super::write_file(&opts.out.join("tradeoff.csv"), csv(rows, models).as_bytes())?;
    super::write_file(&opts.out.join("tradeoff.svg"), plot(rows).as_bytes())?;
    super::write_file(&opts.out.join("tradeoff.md"), summary(rows, opts).as_bytes())?;
    Ok(())
}

/// Rebuilds `tradeoff.svg` and `tradeoff.md` (and the Pareto column) from an existing `tradeoff.csv` in
/// `opts.out`, e.g. one left by an interrupted sweep.
pub fn replot(opts: &TradeoffOptions) -> Result<Vec<Row>, BenchError> {
    let path = opts.out.join("tradeoff.csv");
    let bad = |m: String| BenchError::Io { path: path.clone(), message: m };
    let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    if header != CSV_COLUMNS {
        return Err(bad("header differs from this version's columns".into()));
    }
    let mut rows = Vec::new();
    let mut models = Vec::new();
    for (n, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let c: Vec<&str> = line.split(',').collect();
        if c.len() != CSV_COLUMNS.len() {
            return Err(bad(format!("line {}: {} cells", n + 2, c.len())));
        }
        let int = |i: usize| c[i].parse::<u64>().map_err(|e| bad(format!("line {}: {}: {e}", n + 2, CSV_COLUMNS[i])));
        let num = |i: usize| c[i].parse::<f64>().map_err(|e| bad(format!("line {}: {}: {e}", n + 2, CSV_COLUMNS[i])));
        let u32_at = |i: usize| int(i).map(|v| v as u32);
        let object = ObjectFitSettings {
            iterations: u32_at(3)?,
            batch_pixels: u32_at(4)?,
            n_value: u32_at(5)?,
            n_grad: u32_at(6)?,
            solve_pixels: u32_at(7)?,
            solve_spp: u32_at(8)?,
            refine_steps: u32_at(9)?,
            try_specular: c[10] == "true",
            ..ObjectFitSettings::default()
        };
        rows.push(Row {
            scene: c[0].to_owned(),
            point: SweepPoint {
                group: c[1].to_owned(),
                label: c[2].to_owned(),
                setup: FitSetup { object, max_depth: u32_at(11)?, downscale: u32_at(12)? },
            },
            seconds: num(13)?,
            paths: int(14)?,
            rays: int(15)?,
            accuracy: Accuracy {
                albedo_l1: num(16)?,
                emission_rel_err: num(17)?,
                spurious_emission: num(18)?,
                roughness_err: num(19)?,
            },
            rerender_l1: num(20)?,
            rerender_l1_truth: num(21)?,
            pareto: false,
        });
        models.push(c[23].to_owned());
    }
    for scene in scene_names(&rows) {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].scene == scene).collect();
        let pts: Vec<(f64, f64)> = idx.iter().map(|&i| (rows[i].seconds, rows[i].accuracy.albedo_l1)).collect();
        for k in svg::pareto_front(&pts) {
            rows[idx[k]].pareto = true;
        }
    }
    write_outputs(&rows, &models, opts)?;
    Ok(rows)
}

/// Loads a bench scene; in `--quick` mode scenes without a committed scan get cheap photos.
pub fn load_scene(workspace: &Path, name: &str, quick: bool) -> Result<BenchScene, BenchError> {
    if quick {
        let committed = scenes::fixtures_dir(workspace).join(name).join("undistorted_color_images");
        if !committed.is_dir() {
            let desc_path = scenes::fixtures_dir(workspace).join("scenes").join(format!("{name}.toml"));
            let mut desc = crate::synth::load_desc(&desc_path)?;
            desc.spp = QUICK_PHOTO_SPP;
            let built = crate::synth::build(desc, &desc_path)?;
            let photos = crate::synth::photos(&built)?;
            return Ok(BenchScene { name: name.to_owned(), built, photos });
        }
    }
    scenes::load(workspace, name)
}

fn csv(rows: &[Row], models: &[String]) -> String {
    let mut s = CSV_COLUMNS.join(",");
    s.push('\n');
    for (r, m) in rows.iter().zip(models) {
        let o = &r.point.setup.object;
        let a = &r.accuracy;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{},{}",
            r.scene,
            r.point.group,
            r.point.label,
            o.iterations,
            o.batch_pixels,
            o.n_value,
            o.n_grad,
            o.solve_pixels,
            o.solve_spp,
            o.refine_steps,
            o.try_specular,
            r.point.setup.max_depth,
            r.point.setup.downscale,
            r.seconds,
            r.paths,
            r.rays,
            a.albedo_l1,
            a.emission_rel_err,
            a.spurious_emission,
            a.roughness_err,
            r.rerender_l1,
            r.rerender_l1_truth,
            r.pareto,
            m
        );
    }
    s
}

fn scene_names(rows: &[Row]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for r in rows {
        if !names.contains(&r.scene) {
            names.push(r.scene.clone());
        }
    }
    names
}

fn plot(rows: &[Row]) -> String {
    let mut panels = Vec::new();
    type Metric = (&'static str, fn(&Row) -> f64);
    let metrics: [Metric; 3] = [
        ("albedo mean L1", |r| r.accuracy.albedo_l1),
        ("emission max relative error", |r| r.accuracy.emission_rel_err),
        ("held-back view re-render relative L1", |r| r.rerender_l1),
    ];
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        for (name, f) in metrics {
            let pts: Vec<(f64, f64)> = sr.iter().map(|r| (r.seconds, f(r))).collect();
            let front: Vec<(f64, f64)> = svg::pareto_front(&pts).into_iter().map(|i| pts[i]).collect();
            let mut series = vec![Series {
                name: "sweep points".into(),
                color: "#999999".into(),
                points: pts,
                line: false,
                markers: true,
            }];
            series.push(Series {
                name: "Pareto front".into(),
                color: svg::PALETTE[1].into(),
                points: front,
                line: true,
                markers: true,
            });
            if let Some(d) = sr.iter().find(|r| r.point.group == "default") {
                series.push(Series {
                    name: "default settings".into(),
                    color: svg::PALETTE[0].into(),
                    points: vec![(d.seconds, f(d))],
                    line: false,
                    markers: true,
                });
            }
            if name.starts_with("held-back") {
                let floor = sr.first().map_or(0.0, |r| r.rerender_l1_truth);
                let (lo, hi) =
                    sr.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| (a.min(r.seconds), b.max(r.seconds)));
                series.push(Series {
                    name: "true materials (noise floor)".into(),
                    color: svg::PALETTE[2].into(),
                    points: vec![(lo, floor), (hi, floor)],
                    line: true,
                    markers: false,
                });
            }
            panels.push(Panel {
                title: format!("{scene}: {name}"),
                x_label: "fit wall time [s]".into(),
                y_label: name.into(),
                log_x: true,
                log_y: true,
                series,
            });
        }
    }
    svg::render("Per-object fit: error against time (pipeline bench tradeoff)", &panels, 3)
}

fn summary(rows: &[Row], opts: &TradeoffOptions) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Speed/accuracy trade-off of the per-object fit\n");
    let _ = writeln!(
        s,
        "Measured by `pipeline bench tradeoff{}` on {} ({} logical cores). Each scene's last view is held back from \
         the fit and re-rendered with the fitted materials ({} paths/pixel; `rerender_l1_truth` is the same for the \
         true materials, i.e. the noise floor). Errors against the scene's ground truth. Full data: `tradeoff.csv`; \
         plot: `tradeoff.svg`.\n",
        if opts.quick { " --quick" } else { "" },
        std::env::consts::ARCH,
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        if opts.quick { QUICK_HOLDOUT_RENDER_SPP } else { HOLDOUT_RENDER_SPP },
    );
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        let _ = writeln!(s, "## {scene}: Pareto front (wall time vs albedo L1)\n");
        let _ = writeln!(
            s,
            "| point | time [s] | rays | albedo L1 | emission rel. err | roughness err | re-render L1 |\n|---|---|---|---|---|---|---|"
        );
        let mut front: Vec<&&Row> = sr.iter().filter(|r| r.pareto).collect();
        front.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        for r in front {
            let _ = writeln!(
                s,
                "| `{}` | {:.2} | {:.3e} | {:.4} | {:.4} | {:.3} | {:.4} |",
                r.point.label,
                r.seconds,
                r.rays as f64,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.accuracy.roughness_err,
                r.rerender_l1
            );
        }
        if let Some(d) = sr.iter().find(|r| r.point.group == "default") {
            let _ = writeln!(
                s,
                "\nDefault settings: {:.2} s, albedo L1 {:.4}, emission error {:.4}, re-render L1 {:.4} (floor {:.4}).\n",
                d.seconds, d.accuracy.albedo_l1, d.accuracy.emission_rel_err, d.rerender_l1, d.rerender_l1_truth
            );
        }
        let _ = writeln!(
            s,
            "\nEvery point:\n\n| point | time [s] | albedo L1 | emission rel. err | re-render L1 |\n|---|---|---|---|---|"
        );
        for r in &sr {
            let _ = writeln!(
                s,
                "| `{}`{} | {:.2} | {:.4} | {:.4} | {:.4} |",
                r.point.label,
                if r.pareto { " (front)" } else { "" },
                r.seconds,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.rerender_l1
            );
        }
        s.push('\n');
    }
    s
}
