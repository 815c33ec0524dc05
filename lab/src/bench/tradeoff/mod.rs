//! `lab bench tradeoff`: sweeps the fit's cost settings on each scene, one at a time around the default
//! and at a few joint corners, and writes `tradeoff.csv`, `tradeoff.svg` (error against time, Pareto front
//! marked) and `tradeoff.md` into the output directory.
//!
//! Scenes with textured (checker) objects also run the per-triangle stage after the per-object fit at every
//! point ([`super::timed_point`]); their rows get the stage's time, the final face count and the texture error
//! against the true checker ([`metrics::triangle_texture_error`]), and their Pareto front is on that texture
//! error. Every row records wall time, this process's CPU time over the same span and the 1-minute load
//! average at its start (`workflow::process_stats`); the Pareto front uses the wall time.

use std::path::{Path, PathBuf};

mod plot;
mod summary;
mod table;

pub use table::{CSV_COLUMNS, Row, TriangleColumns, pareto_error, pareto_point};

use super::metrics;
use super::scenes::{self, BenchScene};
use super::{BenchError, FitSetup};
use optim::fit::ObjectFitSettings;
use workflow::config::TriangleConfig;
use workflow::svg;

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
                        horizon: Default::default(),
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
            super::write_file(&opts.out.join("tradeoff.csv"), table::csv(&r, &m).as_bytes())?;
        }
        let pts: Vec<(f64, f64)> = rows[first..].iter().map(|(r, _)| pareto_point(r)).collect();
        for i in svg::pareto_front(&pts) {
            rows[first + i].0.pareto = true;
        }
    }
    let (rows, models): (Vec<Row>, Vec<String>) = rows.into_iter().unzip();
    write_outputs(&rows, &models, opts)?;
    Ok(rows)
}

fn write_outputs(rows: &[Row], models: &[String], opts: &TradeoffOptions) -> Result<(), BenchError> {
    super::write_file(&opts.out.join("tradeoff.csv"), table::csv(rows, models).as_bytes())?;
    super::write_file(&opts.out.join("tradeoff.svg"), plot::plot(rows).as_bytes())?;
    super::write_file(&opts.out.join("tradeoff.md"), summary::summary(rows, opts).as_bytes())?;
    Ok(())
}

/// Rebuilds `tradeoff.svg` and `tradeoff.md` (and the Pareto column) from an existing `tradeoff.csv` in
/// `opts.out`, e.g. one left by an interrupted sweep.
pub fn replot(opts: &TradeoffOptions) -> Result<Vec<Row>, BenchError> {
    let path = opts.out.join("tradeoff.csv");
    let bad = |m: String| BenchError::Io { path: path.clone(), message: m };
    let text = std::fs::read_to_string(&path).map_err(|e| bad(e.to_string()))?;
    let (mut rows, models) = table::parse(&text).map_err(bad)?;
    for scene in scene_names(&rows) {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].scene == scene).collect();
        let pts: Vec<(f64, f64)> = idx.iter().map(|&i| pareto_point(&rows[i])).collect();
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

pub(crate) fn scene_names(rows: &[Row]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for r in rows {
        if !names.contains(&r.scene) {
            names.push(r.scene.clone());
        }
    }
    names
}
