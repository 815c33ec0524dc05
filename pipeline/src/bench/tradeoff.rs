//! `pipeline bench tradeoff`: sweeps the fit's cost settings on each scene, one at a time around the default
//! and at a few joint corners, and writes `tradeoff.csv`, `tradeoff.svg` (error against time, Pareto front
//! marked) and `tradeoff.md` into the output directory.
//!
//! Scenes with textured (checker) objects also run the per-triangle stage after the per-object fit at every
//! point ([`super::timed_point`]); their rows get the stage's time, the final face count and the texture error
//! against the true checker ([`metrics::triangle_texture_error`]), and their Pareto front is on that texture
//! error. Every row records wall time, this process's CPU time over the same span and the 1-minute load
//! average at its start ([`super::process_clock`]); the Pareto front uses the wall time.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::metrics::{self, Accuracy};
use super::scenes::{self, BenchScene};
use super::{BenchError, FitSetup};
use crate::config::TriangleConfig;
use crate::svg::{self, Panel, Series};
use optim::fit::ObjectFitSettings;

/// Paths per pixel of the re-renders of the held-back views: their own noise (relative L1 ≈ 1–2 % on the
/// demo's 96×72 views, measured by rendering the truth the same way) is the floor of that column.
const HOLDOUT_RENDER_SPP: u32 = 256;
/// Same in `--quick` mode (a smoke test: only well-formedness matters).
const QUICK_HOLDOUT_RENDER_SPP: u32 = 8;
/// Photo paths per pixel of scenes rendered in memory in `--quick` mode (the committed scans use 1024).
const QUICK_PHOTO_SPP: u32 = 16;
/// Seed of the held-back renders (fixed: every point is compared on the same random numbers).
const HOLDOUT_SEED: u64 = 0x5eed;

/// The per-triangle stage's settings at every point of a textured scene: the stage's defaults (what
/// `pipeline run` does); in `--quick` mode one subdivision round at 8 paths per pixel (a smoke test of the
/// columns, not of the accuracy).
#[must_use]
pub fn triangle_config(quick: bool) -> TriangleConfig {
    if quick {
        TriangleConfig { rounds: 1, fit_steps: 2, spp: 8, ..TriangleConfig::default() }
    } else {
        TriangleConfig::default()
    }
}

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
    /// Wall time of the point: the per-object fit plus, on textured scenes, the per-triangle stage.
    pub seconds: f64,
    /// This process's user + system CPU time over the same span.
    pub cpu_seconds: f64,
    /// The machine's 1-minute load average when the point started.
    pub load_avg_1m: f64,
    pub paths: u64,
    pub rays: u64,
    pub accuracy: Accuracy,
    /// Relative L1 of the held-back views re-rendered with the fitted materials.
    pub rerender_l1: f64,
    /// The same for the true materials (the noise floor of `rerender_l1`).
    pub rerender_l1_truth: f64,
    /// The per-triangle stage, on scenes with textured objects.
    pub triangle: Option<TriangleColumns>,
    /// On the (seconds, [`pareto_error`]) Pareto front of its scene.
    pub pareto: bool,
}

/// What the per-triangle stage of a point did and how well its texture matches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleColumns {
    /// Wall time of the stage (included in [`Row::seconds`]).
    pub seconds: f64,
    /// Faces of the final mesh (all objects).
    pub faces: usize,
    /// Mean |albedo − true checker| over RGB at random points of the textured objects.
    pub texture_l1: f64,
    /// PSNR of the same (peak 1).
    pub texture_psnr_db: f64,
    /// Largest relative error of a true emitter's emission after the stage (the stage may re-solve the
    /// light; `Accuracy::emission_rel_err` is the per-object stage's).
    pub emission_rel_err: f64,
}

/// The error a scene's Pareto front is drawn on: the texture L1 on scenes whose rows ran the per-triangle
/// stage, else the per-object albedo L1.
#[must_use]
pub fn pareto_error(r: &Row) -> f64 {
    r.triangle.map_or(r.accuracy.albedo_l1, |t| t.texture_l1)
}

/// The CSV columns, in order.
pub const CSV_COLUMNS: [&str; 31] = [
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
    "cpu_time_s",
    "load_avg_1m",
    "paths",
    "rays",
    "albedo_l1",
    "emission_rel_err",
    "spurious_emission",
    "roughness_err",
    "rerender_l1",
    "rerender_l1_truth",
    "triangle_time_s",
    "faces",
    "texture_l1",
    "texture_psnr_db",
    "triangle_emission_rel_err",
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

/// The base setup of a scene: default fit settings, the scene's own max depth, full resolution.
#[must_use]
pub fn base_setup(scene: &BenchScene) -> FitSetup {
    FitSetup { object: ObjectFitSettings::default(), max_depth: scene.built.settings.max_depth, downscale: 1 }
}

/// The training and held-back views of a scene: one view is held back (the fit never sees it) — the last
/// view, or on a scene with textured objects the last view whose centre pixel sees a textured object (on the
/// checker fixture the last views look at the ceiling, which the fit needs to recover the hidden light: holding
/// one of them back left the light 45 % off at the default settings; holding back view 4, a floor view, 6.5 %;
/// `pipeline run` with every view 2.6 %; release build, 2026-11-21).
#[must_use]
pub fn holdout_views(scene: &BenchScene) -> (Vec<usize>, Vec<usize>) {
    let n = scene.built.cameras.len();
    if n < 2 {
        return ((0..n).collect(), Vec::new());
    }
    let textured = scene.textured_objects();
    let sees_texture =
        |k: usize| {
            let c = &scene.built.cameras[k];
            let (o, d) = c.ray(glam::Vec2::new(c.cx, c.cy));
            scene.built.scene.intersect(o, d, f32::INFINITY).is_some_and(|(hit, _)| {
                textured.contains(&(scene.built.render_object_of_tri[hit.tri as usize] as usize))
            })
        };
    let held = if textured.is_empty() { n - 1 } else { (0..n).rev().find(|&k| sees_texture(k)).unwrap_or(n - 1) };
    ((0..n).filter(|&k| k != held).collect(), vec![held])
}

/// Relative L1 of the held-back views of `scene` rendered from `mesh` (the truth's `built.scene`, the scan
/// mesh of the fits, or a per-triangle result) with `params` (at full resolution, the scene's own depth).
pub fn rerender_l1(
    scene: &BenchScene,
    mesh: &tracer::Scene,
    views: &[usize],
    params: &tracer::Params,
    spp: u32,
) -> Result<f64, BenchError> {
    let mut v = Vec::new();
    for &k in views {
        let img = tracer::render_image(
            mesh,
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
        let floor = rerender_l1(&scene, &scene.built.scene, &held, &scene.built.params, holdout_spp)?;
        eprintln!("bench: {}: held-back view(s) {held:?}, floor re-render L1 {floor:.4}", scene.name);
        let base = base_setup(&scene);
        let triangle_cfg = (!scene.textured_objects().is_empty()).then(|| triangle_config(opts.quick));
        let first = rows.len();
        for point in sweep_points(&base, opts.quick) {
            if !opts.only.is_empty() && !opts.only.contains(&point.label) {
                continue;
            }
            if !scenes::divisible(&scene, point.setup.downscale) {
                eprintln!("bench: {}: skipping {} (image size not divisible)", scene.name, point.label);
                continue;
            }
            let run = super::timed_point(&scene, &train, &point.setup, triangle_cfg.as_ref())?;
            let accuracy = metrics::accuracy(&scene.built, &run.fit.outcome.params);
            let (rerender, triangle) = match &run.triangle {
                None => (rerender_l1(&scene, scene.fit_scene(), &held, &run.fit.outcome.params, holdout_spp)?, None),
                Some(t) => {
                    let texture = metrics::triangle_texture_error(&scene.built, &t.state)?.ok_or_else(|| {
                        BenchError::Scene { scene: scene.name.clone(), message: "no checker object".into() }
                    })?;
                    let mesh = t.state.scene()?;
                    let rerender = rerender_l1(&scene, &mesh, &held, &t.state.params(), holdout_spp)?;
                    // The stage's light judged like the object stage's (same truth, same metric).
                    let light = tracer::Params {
                        materials: run.fit.outcome.params.materials.clone(),
                        emission: t.state.emission.clone(),
                    };
                    let cols = TriangleColumns {
                        seconds: t.seconds,
                        faces: t.state.triangles.len(),
                        texture_l1: texture.l1,
                        texture_psnr_db: texture.psnr_db,
                        emission_rel_err: metrics::accuracy(&scene.built, &light).emission_rel_err,
                    };
                    (rerender, Some(cols))
                }
            };
            eprintln!(
                "bench: {:>7} {:<24} {:7.2} s (cpu {:.2} s, load {:.2})  albedo L1 {:.4}  emission {:.4}  roughness {:.3}  re-render {:.4} (truth {:.4}){}",
                scene.name,
                point.label,
                run.seconds,
                run.cpu_seconds,
                run.load_avg_1m,
                accuracy.albedo_l1,
                accuracy.emission_rel_err,
                accuracy.roughness_err,
                rerender,
                floor,
                triangle.map_or(String::new(), |t| format!(
                    "  triangle {:.2} s, {} faces, texture L1 {:.4}, PSNR {:.2} dB, emission {:.4}",
                    t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
                ))
            );
            let models = run.fit.outcome.per_object.iter().map(|m| m.model.as_str()).collect::<Vec<_>>().join(";");
            rows.push((
                Row {
                    scene: scene.name.clone(),
                    point,
                    seconds: run.seconds,
                    cpu_seconds: run.cpu_seconds,
                    load_avg_1m: run.load_avg_1m,
                    paths: run.paths,
                    rays: run.rays,
                    accuracy,
                    rerender_l1: rerender,
                    rerender_l1_truth: floor,
                    triangle,
                    pareto: false,
                },
                models,
            ));
            // Written after every point so that an interrupted sweep keeps what it measured.
            let (r, m): (Vec<Row>, Vec<String>) = rows.iter().cloned().unzip();
            super::write_file(&opts.out.join("tradeoff.csv"), csv(&r, &m).as_bytes())?;
        }
        let pts: Vec<(f64, f64)> = rows[first..].iter().map(|(r, _)| (r.seconds, pareto_error(r))).collect();
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
        let at = |name: &str| CSV_COLUMNS.iter().position(|c| *c == name).unwrap_or(0);
        let cell = |name: &str| c[at(name)];
        let int = |name: &str| cell(name).parse::<u64>().map_err(|e| bad(format!("line {}: {name}: {e}", n + 2)));
        let num = |name: &str| cell(name).parse::<f64>().map_err(|e| bad(format!("line {}: {name}: {e}", n + 2)));
        let u32_at = |name: &str| int(name).map(|v| v as u32);
        let object = ObjectFitSettings {
            iterations: u32_at("iterations")?,
            batch_pixels: u32_at("batch_pixels")?,
            n_value: u32_at("n_value")?,
            n_grad: u32_at("n_grad")?,
            solve_pixels: u32_at("solve_pixels")?,
            solve_spp: u32_at("solve_spp")?,
            refine_steps: u32_at("refine_steps")?,
            try_specular: cell("try_specular") == "true",
            ..ObjectFitSettings::default()
        };
        // The per-triangle columns are empty on rows that did not run the stage.
        let triangle = if cell("faces").is_empty() {
            None
        } else {
            Some(TriangleColumns {
                seconds: num("triangle_time_s")?,
                faces: int("faces")? as usize,
                texture_l1: num("texture_l1")?,
                texture_psnr_db: num("texture_psnr_db")?,
                emission_rel_err: num("triangle_emission_rel_err")?,
            })
        };
        rows.push(Row {
            scene: cell("scene").to_owned(),
            point: SweepPoint {
                group: cell("group").to_owned(),
                label: cell("label").to_owned(),
                setup: FitSetup { object, max_depth: u32_at("max_depth")?, downscale: u32_at("downscale")? },
            },
            seconds: num("wall_time_s")?,
            cpu_seconds: num("cpu_time_s")?,
            load_avg_1m: num("load_avg_1m")?,
            paths: int("paths")?,
            rays: int("rays")?,
            accuracy: Accuracy {
                albedo_l1: num("albedo_l1")?,
                emission_rel_err: num("emission_rel_err")?,
                spurious_emission: num("spurious_emission")?,
                roughness_err: num("roughness_err")?,
            },
            rerender_l1: num("rerender_l1")?,
            rerender_l1_truth: num("rerender_l1_truth")?,
            triangle,
            pareto: false,
        });
        models.push(cell("models").to_owned());
    }
    for scene in scene_names(&rows) {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].scene == scene).collect();
        let pts: Vec<(f64, f64)> = idx.iter().map(|&i| (rows[i].seconds, pareto_error(&rows[i]))).collect();
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
            return BenchScene::new(name, built, photos);
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
        let tri = r.triangle.map_or_else(
            || ",,,,".to_owned(),
            |t| {
                format!(
                    "{:.3},{},{:.6},{:.3},{:.6}",
                    t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
                )
            },
        );
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.2},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{},{},{}",
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
            r.cpu_seconds,
            r.load_avg_1m,
            r.paths,
            r.rays,
            a.albedo_l1,
            a.emission_rel_err,
            a.spurious_emission,
            a.roughness_err,
            r.rerender_l1,
            r.rerender_l1_truth,
            tri,
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
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        let textured = sr.iter().any(|r| r.triangle.is_some());
        // Four panels per scene: the Pareto front's own error first (the texture error on textured scenes),
        // then emission, re-render and the CPU time (against the same wall time: contention shows as points
        // far below the line CPU = cores × wall).
        let metrics: [Metric; 4] = [
            if textured {
                ("texture L1 after the per-triangle stage", pareto_error)
            } else {
                ("albedo mean L1", pareto_error)
            },
            ("emission max relative error", |r| r.accuracy.emission_rel_err),
            ("held-back view re-render relative L1", |r| r.rerender_l1),
            ("process CPU time [s]", |r| r.cpu_seconds),
        ];
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
    svg::render("Per-object fit (+ per-triangle stage on textured scenes): error against time", &panels, 4)
}

fn summary(rows: &[Row], opts: &TradeoffOptions) -> String {
    let mut s = String::new();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let _ = writeln!(s, "# Speed/accuracy trade-off of the per-object fit\n");
    let _ = writeln!(
        s,
        "Measured by `pipeline bench tradeoff{}` on {} ({cores} logical cores). One view per scene is held back \
         from the fit (the last; on textured scenes the last whose centre sees the textured object, see \
         `holdout_views`) and re-rendered with the fitted materials ({} paths/pixel; `rerender_l1_truth` is the same for \
         the true materials, i.e. the noise floor). Errors against the scene's ground truth. Full data: \
         `tradeoff.csv`; plot: `tradeoff.svg`.\n",
        if opts.quick { " --quick" } else { "" },
        std::env::consts::ARCH,
        if opts.quick { QUICK_HOLDOUT_RENDER_SPP } else { HOLDOUT_RENDER_SPP },
    );
    let _ = writeln!(s, "{}\n", timing_note(rows, cores));
    if rows.iter().any(|r| r.triangle.is_some()) {
        let t = triangle_config(opts.quick);
        let _ = writeln!(
            s,
            "Scenes with a textured (checker) object also run the per-triangle stage (adaptive subdivision + \
             per-triangle fit, `rounds = {}`, `spp = {}`, `fit_steps = {}`) after the per-object fit at every point: \
             its time is part of the point's wall time and also listed alone; `texture L1`/`PSNR` compare the \
             final per-triangle albedo with the true checker at {} seeded random points of the textured object; \
             their Pareto front is on the texture L1, and `albedo L1` covers the untextured objects only. The \
             re-render uses the per-triangle result.\n",
            t.rounds,
            t.spp,
            t.fit_steps,
            metrics::TEXTURE_POINTS,
        );
    }
    for scene in scene_names(rows) {
        let sr: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
        let textured = sr.iter().any(|r| r.triangle.is_some());
        let error_name = if textured { "texture L1" } else { "albedo L1" };
        let _ = writeln!(s, "## {scene}: Pareto front (wall time vs {error_name})\n");
        let _ = writeln!(
            s,
            "| point | wall [s] | CPU [s] | load 1 min | rays | albedo L1 | emission rel. err | roughness err | \
             re-render L1 |{}\n|---|---|---|---|---|---|---|---|---|{}",
            if textured {
                " triangle stage [s] | faces | texture L1 | PSNR [dB] | emission rel. err after it |"
            } else {
                ""
            },
            if textured { "---|---|---|---|---|" } else { "" }
        );
        let mut front: Vec<&&Row> = sr.iter().filter(|r| r.pareto).collect();
        front.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        for r in front {
            let _ = writeln!(
                s,
                "| `{}` | {:.2} | {:.2} | {:.2} | {:.3e} | {:.4} | {:.4} | {:.3} | {:.4} |{}",
                r.point.label,
                r.seconds,
                r.cpu_seconds,
                r.load_avg_1m,
                r.rays as f64,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.accuracy.roughness_err,
                r.rerender_l1,
                triangle_cells(r)
            );
        }
        if let Some(d) = sr.iter().find(|r| r.point.group == "default") {
            let _ = writeln!(
                s,
                "\nDefault settings: {:.2} s wall ({:.2} s CPU, load {:.2}), albedo L1 {:.4}, emission error {:.4}, \
                 re-render L1 {:.4} (floor {:.4}){}.\n",
                d.seconds,
                d.cpu_seconds,
                d.load_avg_1m,
                d.accuracy.albedo_l1,
                d.accuracy.emission_rel_err,
                d.rerender_l1,
                d.rerender_l1_truth,
                d.triangle.map_or(String::new(), |t| format!(
                    ", per-triangle stage {:.2} s, {} faces, texture L1 {:.4} ({:.2} dB), emission error after it {:.4}",
                    t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
                ))
            );
        }
        let _ = writeln!(
            s,
            "\nEvery point:\n\n| point | wall [s] | CPU [s] | load 1 min | albedo L1 | emission rel. err | re-render L1 |{}\n\
             |---|---|---|---|---|---|---|{}",
            if textured {
                " triangle stage [s] | faces | texture L1 | PSNR [dB] | emission rel. err after it |"
            } else {
                ""
            },
            if textured { "---|---|---|---|---|" } else { "" }
        );
        for r in &sr {
            let _ = writeln!(
                s,
                "| `{}`{} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {:.4} |{}",
                r.point.label,
                if r.pareto { " (front)" } else { "" },
                r.seconds,
                r.cpu_seconds,
                r.load_avg_1m,
                r.accuracy.albedo_l1,
                r.accuracy.emission_rel_err,
                r.rerender_l1,
                triangle_cells(r)
            );
        }
        s.push('\n');
    }
    s
}

/// The per-triangle cells of a markdown row (empty for rows without the stage).
fn triangle_cells(r: &Row) -> String {
    r.triangle.map_or(String::new(), |t| {
        format!(
            " {:.2} | {} | {:.4} | {:.2} | {:.4} |",
            t.seconds, t.faces, t.texture_l1, t.texture_psnr_db, t.emission_rel_err
        )
    })
}

/// How to read the times: the range of load averages and of CPU/wall ratios over the rows.
fn timing_note(rows: &[Row], cores: usize) -> String {
    let finite = |v: Vec<f64>| -> Option<(f64, f64)> {
        let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        (!v.is_empty()).then(|| v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x))))
    };
    let load = finite(rows.iter().map(|r| r.load_avg_1m).collect());
    // Points shorter than 0.1 s are left out of the ratio: the CPU clock ticks in 10 ms steps.
    let ratio = finite(rows.iter().filter(|r| r.seconds >= 0.1).map(|r| r.cpu_seconds / r.seconds).collect());
    let mut s = format!(
        "Timing: `wall_time_s` is the elapsed time of the point (the Pareto fronts use it); `cpu_time_s` is this \
         process's user + system CPU time over the same span (all threads, `/proc/self/stat`), and `load_avg_1m` \
         the machine's 1-minute load average when the point started (`/proc/loadavg`). On an idle machine the \
         load stays below the {cores} cores and CPU ≈ {cores} × wall for the parallel parts; a load above the core \
         count with CPU/wall well below {cores} means other jobs took the cores and the wall time is inflated."
    );
    if let Some((lo, hi)) = load {
        let _ = write!(s, " This run: load average {lo:.2}–{hi:.2}");
        if let Some((a, b)) = ratio {
            let _ = write!(s, ", CPU/wall {a:.2}–{b:.2}");
        }
        s.push('.');
    }
    s
}
