//! `lab bench`: the speed/accuracy trade-off of the per-object fit measured on the synthetic fixtures,
//! the paper's value/gradient path ablations (Fig. 9, 10), and the comparison with the Mitsuba 3
//! baseline (tests/validation/mitsuba_baseline).
//!
//! - [`tradeoff`]: one-at-a-time sweeps around the default settings plus joint corners; per point wall time,
//!   paths and rays traced ([`tracer::total_trace_stats`]), accuracy against the truth ([`metrics`]) and the
//!   re-render error on held-back views; CSV + SVG (error against time, Pareto front) + markdown. Scenes with
//!   a textured (checker) object also run the per-triangle stage at every point and record its time, face
//!   count and texture error ([`metrics::triangle_texture_error`]).
//! - `workflow::process_stats`: CPU time and load average next to every wall time (timings on a shared
//!   machine).
//! - [`ablation`]: Adam-phase convergence against the number of value paths, and the split of a fixed path
//!   budget between value and gradient paths.
//! - [`scale`]: the whole pipeline on scans of growing size (triangles, objects, photos, resolution), each
//!   point in its own process: wall and CPU time and peak RSS per stage, held-out pixels, accuracy.
//! - [`realistic`]: the quality presets on the realistic corpus (Mitsuba renders, docs/realistic/): the
//!   whole pipeline per scan and preset in its own process, costs per stage, the corpus scorer's accuracy.
//! - [`mitsuba`]: runs the Mitsuba baseline and our fit on the default scene in one process and reports the
//!   time each needs to reach the same albedo error.
//!
//! Everything is seeded; only the times (wall and CPU) and load averages vary between runs.

pub mod ablation;
pub mod metrics;
pub mod mitsuba;
pub mod realistic;
pub mod scale;
pub mod scenes;
pub mod tradeoff;

use std::path::{Path, PathBuf};
use std::time::Instant;

use optim::fit::{FitInputs, FitOutcome, ObjectFitSettings};
use scenes::BenchScene;

/// Why a benchmark failed.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("bench: {0}")]
    Synth(#[from] crate::synth::SynthError),
    #[error("bench: {0}")]
    Fit(#[from] optim::fit::FitError),
    #[error("bench: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error("bench: {0}")]
    Triangle(#[from] optim::triangle::TriangleError),
    #[error("bench: {0}")]
    Texture(#[from] metrics::TextureError),
    #[error("bench: {path}: {message}", path = .path.display())]
    Io { path: PathBuf, message: String },
    #[error("bench: scene {scene}: {message}")]
    Scene { scene: String, message: String },
    #[error("bench: {0}")]
    Other(String),
}

/// The settings of one fit of a sweep: the fit's own settings plus the two that change its inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSetup {
    pub object: ObjectFitSettings,
    /// `tracer.max_depth` of the fit (the photos keep the depth they were rendered with).
    pub max_depth: u32,
    /// `images.downscale`: integer box-filter factor of the photos (and cameras) the fit sees.
    pub downscale: u32,
}

/// The result of one timed fit.
#[derive(Debug, Clone)]
pub struct TimedFit {
    pub outcome: FitOutcome,
    /// Wall time of the fit alone (the inputs are prepared before the clock starts).
    pub seconds: f64,
    pub paths: u64,
    pub rays: u64,
}

/// Runs the per-object fit of `scene` on the views `train_views` with `setup`, timed, counting the work the
/// tracer did meanwhile.
pub fn timed_fit(scene: &BenchScene, train_views: &[usize], setup: &FitSetup) -> Result<TimedFit, BenchError> {
    Ok(timed_point(scene, train_views, setup, None)?.fit)
}

/// The per-triangle stage of one sweep point.
#[derive(Debug, Clone)]
pub struct TimedTriangle {
    /// The subdivided mesh with per-triangle materials.
    pub state: optim::triangle::TriangleState,
    /// Wall time of the stage alone.
    pub seconds: f64,
}

/// One timed sweep point: the per-object fit, optionally followed by the per-triangle stage.
#[derive(Debug, Clone)]
pub struct TimedPoint {
    pub fit: TimedFit,
    pub triangle: Option<TimedTriangle>,
    /// Wall time of the fit plus the per-triangle stage.
    pub seconds: f64,
    /// This process's user + system CPU time over the same span (NaN where `/proc` is unavailable).
    pub cpu_seconds: f64,
    /// The machine's 1-minute load average at the start of the point (NaN where unavailable).
    pub load_avg_1m: f64,
    /// Paths and rays traced by the fit and the per-triangle stage.
    pub paths: u64,
    pub rays: u64,
}

/// Runs the per-object fit of `scene` on the views `train_views` with `setup` and then, when `triangle` is
/// given, the per-triangle stage (adaptive subdivision + per-triangle fit, [`optim::triangle::run_rounds`],
/// what the `triangle` stage runs) from its result on the scan mesh, on the same (downscaled) views. Timed
/// (wall and CPU), counting the work the tracer did meanwhile.
pub fn timed_point(
    scene: &BenchScene,
    train_views: &[usize],
    setup: &FitSetup,
    triangle: Option<&workflow::config::TriangleConfig>,
) -> Result<TimedPoint, BenchError> {
    let d = setup.downscale.max(1);
    if !scenes::divisible(scene, d) {
        return Err(BenchError::Scene {
            scene: scene.name.clone(),
            message: format!("image size not divisible by downscale {d}"),
        });
    }
    let cameras: Vec<tracer::Camera> =
        train_views.iter().map(|&k| scenes::downscale_camera(&scene.built.cameras[k], d)).collect();
    let images: Vec<ingest::photo::LinearImage> =
        train_views.iter().map(|&k| scenes::downscale_image(&scene.photos[k], d)).collect::<Result<_, _>>()?;
    let objects = crate::synth::fit_objects(&scene.built);
    let tracer_settings = tracer::TracerSettings { max_depth: setup.max_depth, ..scene.built.settings };
    let inputs = FitInputs {
        scene: scene.fit_scene(),
        cameras: &cameras,
        images: &images,
        objects: &objects,
        settings: &setup.object,
        tracer: &tracer_settings,
        mode: optim::fit::FitMode::Full,
    };
    let load_avg_1m = workflow::process_stats::load_average_1m().unwrap_or(f64::NAN);
    let cpu_before = workflow::process_stats::cpu_time_s().unwrap_or(f64::NAN);
    let before = tracer::total_trace_stats();
    let t = Instant::now();
    let outcome = optim::fit::fit_objects(&inputs, None, &mut |_| Ok(()), &optim::NoProgress)?;
    let fit_seconds = t.elapsed().as_secs_f64();
    let after_fit = tracer::total_trace_stats();
    let fit = TimedFit {
        outcome,
        seconds: fit_seconds,
        paths: after_fit.paths - before.paths,
        rays: after_fit.rays - before.rays,
    };
    let triangle = match triangle {
        None => None,
        Some(config) => {
            let t_tri = Instant::now();
            let m = &scene.built.mesh;
            let start = optim::triangle::TriangleState::from_objects(
                m.positions.clone(),
                Some(m.normals.clone()),
                m.triangles.clone(),
                m.object_of_tri.clone(),
                &fit.outcome.params,
            )?;
            let specular: Vec<bool> = fit.outcome.per_object.iter().map(|o| o.model.contains("specular")).collect();
            let constrained: Vec<bool> = fit.outcome.per_object.iter().map(|o| o.constrained).collect();
            let round_inputs = optim::triangle::RoundInputs {
                cameras: &cameras,
                images: &images,
                settings: &optim::triangle::TriangleSettings::from(config),
                object: &setup.object,
                tracer: &tracer_settings,
                specular: &specular,
                constrained: &constrained,
            };
            let state = optim::triangle::run_rounds(&round_inputs, start, &mut |_| Ok(()), &optim::NoProgress)?;
            Some(TimedTriangle { state, seconds: t_tri.elapsed().as_secs_f64() })
        }
    };
    let seconds = t.elapsed().as_secs_f64();
    let cpu_seconds = workflow::process_stats::cpu_time_s().unwrap_or(f64::NAN) - cpu_before;
    let after = tracer::total_trace_stats();
    Ok(TimedPoint {
        fit,
        triangle,
        seconds,
        cpu_seconds,
        load_avg_1m,
        paths: after.paths - before.paths,
        rays: after.rays - before.rays,
    })
}

/// Writes `bytes` to `path` atomically, creating the parent directory.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
    let io = |e: &dyn std::fmt::Display| BenchError::Io { path: path.to_path_buf(), message: e.to_string() };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| io(&e))?;
    }
    ingest::atomic::write_atomic(path, bytes).map_err(|e| io(&e))
}

/// The workspace root this binary was built from (where `data-fixtures/` and `tests/validation/` are).
#[must_use]
pub fn default_workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}
