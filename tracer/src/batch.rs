//! Entry points: pixel-batch rendering and gradients, parallel over pixels with rayon and deterministic
//! (each pixel's result depends only on its own counter-based random numbers, and per-pixel results are
//! reduced in pixel order on one thread).
//!
//! [`Renderer`] holds what one optimiser iteration shares between its value and gradient estimates (the
//! validated parameters and the light-selection distribution built from them); the free functions are
//! one-call conveniences that build it each time.
//!
//! # Discarded samples
//!
//! A path sample whose estimate is not finite is *discarded*: in value mode, its radiance; in gradient mode,
//! its radiance or any of its gradient contributions. It contributes nothing, the pixel still divides by the
//! number of samples taken, and it is counted in [`TraceStats::discarded`] (and in [`total_trace_stats`]).
//! Such samples come from f32 overflow at extreme inputs (an emission near `f32::MAX` times a throughput
//! above one, two such terms summed, or 0·∞ in a product), not from ordinary scenes (tests/discarded.rs).
//! Dropping them biases the pixel slightly darker (the estimator becomes E[L·1{L finite}] ≤ E[L]; a
//! gradient is biased towards zero alike); that is accepted because the alternative is one ∞ or NaN that
//! destroys the pixel's whole estimate and every quantity summed from it (a loss, a gradient, an optimiser
//! step), and because the count is returned, so a caller can bound the fraction of discarded samples instead
//! of trusting a silently biased estimate (the pipeline's fit fails above 1e-4 of its paths). The checks are
//! one `is_finite` of the path's radiance and, in gradient mode, one of the sum of the path's gradient entries
//! (a handful per path); never one per vertex. Non-finite *inputs* are the caller's bug, not overflow: a
//! non-finite gradient weight is an error, not a discarded sample.

use crate::camera::Camera;
use crate::error::TracerError;
use crate::integrator::{self, Context, DIM_JITTER, GradEntry, Mode};
use crate::lights::LightSampler;
use crate::params::{Grads, Params, TracerSettings};
use crate::rng::{PathSampler, PixelKey, Stream};
use crate::scene::Scene;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// One pixel of one view (`view` indexes the `cameras` slice).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PixelRef {
    pub view: u32,
    pub x: u32,
    pub y: u32,
}

/// Work counters of one call (for benchmarks and for the caller's bound on discarded samples).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TraceStats {
    /// Path samples taken, discarded ones included.
    pub paths: u64,
    /// Embree queries: closest-hit plus shadow rays.
    pub rays: u64,
    /// The shadow (occlusion) rays among them.
    pub shadow_rays: u64,
    /// Path samples among `paths` whose estimate was not finite and that therefore contributed nothing (see
    /// the module doc, "Discarded samples"). Zero for any scene without overflowing values.
    pub discarded: u64,
}

impl TraceStats {
    /// Adds `o`'s counters to these.
    pub fn add(&mut self, o: &TraceStats) {
        self.paths += o.paths;
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
        self.discarded += o.discarded;
    }
}

/// Process-wide totals of every [`Renderer`] call (paths, rays, shadow rays, discarded paths), for benchmarks
/// that time code which calls the tracer internally (pipeline's `bench`). One relaxed update per call, not per
/// path.
static TOTALS: [AtomicU64; 4] = [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)];

fn add_to_totals(s: &TraceStats) {
    TOTALS[0].fetch_add(s.paths, Ordering::Relaxed);
    TOTALS[1].fetch_add(s.rays, Ordering::Relaxed);
    TOTALS[2].fetch_add(s.shadow_rays, Ordering::Relaxed);
    TOTALS[3].fetch_add(s.discarded, Ordering::Relaxed);
}

/// The work of every render and gradient call of this process so far; the difference of two readings is the
/// work done in between (exact when nothing else traces concurrently).
#[must_use]
pub fn total_trace_stats() -> TraceStats {
    TraceStats {
        paths: TOTALS[0].load(Ordering::Relaxed),
        rays: TOTALS[1].load(Ordering::Relaxed),
        shadow_rays: TOTALS[2].load(Ordering::Relaxed),
        discarded: TOTALS[3].load(Ordering::Relaxed),
    }
}

/// Largest accepted `max_depth`: bounds the random-number dimension (8 per vertex) well inside u32 and the
/// recorded path length; far beyond any depth with measurable energy.
pub const MAX_DEPTH_LIMIT: u32 = 1024;

/// A scene with one parameter set, ready to render and differentiate.
#[derive(Debug)]
pub struct Renderer<'a> {
    scene: &'a Scene,
    params: &'a Params,
    settings: TracerSettings,
    lights: LightSampler,
}

impl<'a> Renderer<'a> {
    /// Validates `params` against the scene and `settings`, and builds the light distribution.
    pub fn new(scene: &'a Scene, params: &'a Params, settings: &TracerSettings) -> Result<Self, TracerError> {
        params.check(scene)?;
        if settings.max_depth > MAX_DEPTH_LIMIT {
            return Err(TracerError::BadSetting {
                what: "max_depth",
                requirement: "≤ 1024",
                value: settings.max_depth.to_string(),
            });
        }
        Ok(Renderer { scene, params, settings: *settings, lights: LightSampler::new(scene, params) })
    }

    fn context(&self) -> Context<'_> {
        Context { scene: self.scene, params: self.params, lights: &self.lights, settings: &self.settings }
    }

    /// Mean radiance of each pixel over `spp` paths (box pixel filter), from the value stream of
    /// (`seed`, `iteration`), and the work done. Paths with a non-finite estimate are discarded and counted
    /// (module doc), so every returned value is finite.
    pub fn render_pixels(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        spp: u32,
        seed: u64,
        iteration: u64,
    ) -> Result<(Vec<Vec3>, TraceStats), TracerError> {
        check_pixels(cameras, pixels, spp)?;
        let ctx = self.context();
        let per_pixel: Vec<(Vec3, [u64; 2], u64)> = pixels
            .par_iter()
            .map_init(Vec::new, |record, &p| {
                let mut sum = DVec3::ZERO;
                let mut rays = [0; 2];
                let mut discarded = 0;
                for s in 0..spp {
                    let rng = PathSampler::new(seed, Stream::Value, iteration, key(p), s);
                    let (o, d) = primary(cameras, p, &rng);
                    let l = integrator::trace(&ctx, o, d, &rng, Mode::Value, record, &mut rays);
                    // The one check per path (module doc): a non-finite estimate is dropped and counted.
                    if l.is_finite() {
                        sum += l.as_dvec3();
                    } else {
                        discarded += 1;
                    }
                }
                // The mean of finite f32 values is finite (the f64 sum cannot overflow).
                ((sum / f64::from(spp)).as_vec3(), rays, discarded)
            })
            .collect();
        let stats = TraceStats {
            paths: pixels.len() as u64 * u64::from(spp),
            rays: per_pixel.iter().map(|p| p.1[0] + p.1[1]).sum(),
            shadow_rays: per_pixel.iter().map(|p| p.1[1]).sum(),
            discarded: per_pixel.iter().map(|p| p.2).sum(),
        };
        add_to_totals(&stats);
        Ok((per_pixel.into_iter().map(|p| p.0).collect(), stats))
    }

    /// `∂(Σ_j weights[j] · I_j)/∂θ` estimated with `spp_grad` paths per pixel from the gradient stream of
    /// (`seed`, `iteration`), independent of the value stream, and the work done. For the L1 loss of
    /// Eq. 3–4, `weights[j] = sign(I_j − I_target,j) / B` per channel, formed by the caller from
    /// `render_pixels`. Pixels with zero weight trace nothing. A path whose radiance or any of whose gradient
    /// contributions is not finite is discarded and counted (module doc), so every returned entry is finite.
    pub fn gradient_pixels(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        weights: &[Vec3],
        spp_grad: u32,
        seed: u64,
        iteration: u64,
    ) -> Result<(Grads, TraceStats), TracerError> {
        check_pixels(cameras, pixels, spp_grad)?;
        if weights.len() != pixels.len() {
            return Err(TracerError::LengthMismatch { what: "weights", expected: pixels.len(), got: weights.len() });
        }
        // A non-finite weight would make every path of its pixel non-finite: the caller's bug, reported as such
        // rather than discarded (module doc).
        if let Some((index, w)) = weights.iter().enumerate().find(|(_, w)| !w.is_finite()) {
            return Err(TracerError::BadSetting {
                what: "gradient weight",
                requirement: "finite",
                value: format!("{w} at pixel {index}"),
            });
        }
        let ctx = self.context();
        let per_pixel: Vec<(Vec<GradEntry>, [u64; 2], u64, u64)> = pixels
            .par_iter()
            .zip(weights.par_iter())
            .map_init(
                || (Vec::new(), Vec::new()),
                |(record, path_entries), (&p, &w)| {
                    let mut entries = Vec::new();
                    let mut rays = [0; 2];
                    let mut discarded = 0;
                    // A zero weight means the pixel does not enter the objective: its gradient is exactly zero.
                    if w == Vec3::ZERO {
                        return (entries, rays, 0, 0);
                    }
                    let w = w / spp_grad as f32;
                    for s in 0..spp_grad {
                        let rng = PathSampler::new(seed, Stream::Gradient, iteration, key(p), s);
                        let (o, d) = primary(cameras, p, &rng);
                        let l = integrator::trace(&ctx, o, d, &rng, Mode::Gradient, record, &mut rays);
                        // The path's contributions go to a scratch list first, so that a non-finite one can be
                        // dropped whole (module doc) without touching the pixel's sums.
                        path_entries.clear();
                        integrator::backward(record, w, path_entries);
                        if l.is_finite() && entries_are_finite(path_entries) {
                            integrator::merge(&mut entries, path_entries);
                        } else {
                            discarded += 1;
                        }
                    }
                    (entries, rays, u64::from(spp_grad), discarded)
                },
            )
            .collect();
        let mut grads = Grads::zeros_like(self.params);
        let mut stats = TraceStats::default();
        for (e, rays, paths, discarded) in &per_pixel {
            integrator::accumulate(&mut grads, e);
            stats.rays += rays[0] + rays[1];
            stats.shadow_rays += rays[1];
            stats.paths += paths;
            stats.discarded += discarded;
        }
        add_to_totals(&stats);
        Ok((grads, stats))
    }
}

/// Whether every component of one path's gradient entries is finite, by one check of their sum: a sum of
/// finite values is finite (each is an f32 product widened to f64, so a path's few dozen cannot overflow f64),
/// and any ∞ or NaN makes the sum ∞ or NaN (∞ − ∞ = NaN).
fn entries_are_finite(entries: &[GradEntry]) -> bool {
    let mut sum = 0.0f64;
    for e in entries {
        sum += match e {
            GradEntry::Material(_, m) => m.base_color.element_sum() + m.roughness + m.metallic + m.specular,
            GradEntry::Emission(_, d) => d.element_sum(),
        };
    }
    sum.is_finite()
}

fn check_pixels(cameras: &[Camera], pixels: &[PixelRef], spp: u32) -> Result<(), TracerError> {
    if spp == 0 {
        return Err(TracerError::BadSetting { what: "samples per pixel", requirement: "≥ 1", value: "0".into() });
    }
    for (index, p) in pixels.iter().enumerate() {
        let ok = cameras.get(p.view as usize).is_some_and(|c| p.x < c.width && p.y < c.height);
        if !ok {
            return Err(TracerError::BadPixel { index, view: p.view, x: p.x, y: p.y });
        }
    }
    Ok(())
}

fn primary(cameras: &[Camera], p: PixelRef, rng: &PathSampler) -> (Vec3, Vec3) {
    let cam = &cameras[p.view as usize];
    let uv = Camera::jitter(p.x, p.y, Vec2::new(rng.get(DIM_JITTER), rng.get(DIM_JITTER + 1)));
    cam.ray(uv)
}

fn key(p: PixelRef) -> PixelKey {
    PixelKey { view: p.view, x: p.x, y: p.y }
}

/// [`Renderer::render_pixels`] without the statistics, building the renderer for this one call.
pub fn render_pixels(
    scene: &Scene,
    params: &Params,
    cameras: &[Camera],
    pixels: &[PixelRef],
    spp: u32,
    settings: &TracerSettings,
    seed: u64,
    iteration: u64,
) -> Result<Vec<Vec3>, TracerError> {
    Ok(Renderer::new(scene, params, settings)?.render_pixels(cameras, pixels, spp, seed, iteration)?.0)
}

/// [`Renderer::gradient_pixels`] without the statistics, building the renderer for this one call.
pub fn gradient_pixels(
    scene: &Scene,
    params: &Params,
    cameras: &[Camera],
    pixels: &[PixelRef],
    weights: &[Vec3],
    spp_grad: u32,
    settings: &TracerSettings,
    seed: u64,
    iteration: u64,
) -> Result<Grads, TracerError> {
    Ok(Renderer::new(scene, params, settings)?.gradient_pixels(cameras, pixels, weights, spp_grad, seed, iteration)?.0)
}

/// Renders every pixel of one camera (row-major, `width × height`), as view 0. Discarded paths (module doc)
/// are counted in [`total_trace_stats`].
pub fn render_image(
    scene: &Scene,
    params: &Params,
    camera: &Camera,
    spp: u32,
    settings: &TracerSettings,
    seed: u64,
    iteration: u64,
) -> Result<Vec<Vec3>, TracerError> {
    let pixels: Vec<PixelRef> =
        (0..camera.height).flat_map(|y| (0..camera.width).map(move |x| PixelRef { view: 0, x, y })).collect();
    render_pixels(scene, params, std::slice::from_ref(camera), &pixels, spp, settings, seed, iteration)
}
