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
use crate::params::{Grads, MaterialGradSum, Params, TracerSettings};
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
        let stats = value_stats(pixels.len(), spp, per_pixel.iter().map(|p| (p.1, p.2)));
        Ok((per_pixel.into_iter().map(|p| p.0).collect(), stats))
    }

    /// The basis images of the emission entries `slots` over `pixels` (an emitter slot, or the ground half of a
    /// slot that this renderer's [`crate::params::Horizon`] splits): entry i is, bit for bit, what
    /// [`Renderer::render_pixels`] returns with this renderer's materials and horizon and an emission of 1 at
    /// `slots[i]` and 0 elsewhere (the column ∂I/∂e of that entry; this renderer's own emission is not used),
    /// and the work done. Each path is traced once for all the columns ([`integrator::trace_columns`]): its
    /// continuation rays are shared, its next-event connections are one per column. A path whose estimate in
    /// a column is not finite is discarded from that column (module doc) and counted once.
    pub fn render_emission_columns(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        slots: &[u32],
        spp: u32,
        seed: u64,
        iteration: u64,
    ) -> Result<(Vec<Vec<Vec3>>, TraceStats), TracerError> {
        check_pixels(cameras, pixels, spp)?;
        let n_slots = self.scene.emitter_slots();
        let mut of_slot = Vec::with_capacity(slots.len());
        for &entry in slots {
            let slot = self.params.slot_of_entry(entry, n_slots).ok_or_else(|| TracerError::BadSetting {
                what: "emission column",
                requirement: "an emitter slot of the scene or the ground or zenith entry of a split slot",
                value: format!("entry {entry} ({n_slots} slots)"),
            })?;
            of_slot.push(slot);
        }
        let samplers = of_slot
            .iter()
            .map(|&k| {
                let mut emission = vec![Vec3::ZERO; n_slots];
                emission[k as usize] = Vec3::ONE;
                LightSampler::new(self.scene, &Params { materials: Vec::new(), emission, ..Params::default() })
            })
            .collect();
        let cols = integrator::Columns { samplers, entries: slots.to_vec() };
        let ctx = self.context();
        let n = slots.len();
        let per_pixel: Vec<(Vec<Vec3>, [u64; 2], u64)> = pixels
            .par_iter()
            .map_init(integrator::ColumnScratch::default, |scratch, &p| {
                let mut sums = vec![DVec3::ZERO; n];
                let mut rays = [0; 2];
                let mut discarded = 0;
                for s in 0..spp {
                    let rng = PathSampler::new(seed, Stream::Value, iteration, key(p), s);
                    let (o, d) = primary(cameras, p, &rng);
                    integrator::trace_columns(&ctx, &cols, o, d, &rng, scratch, &mut rays);
                    let mut dropped = false;
                    for (sum, l) in sums.iter_mut().zip(&scratch.out) {
                        if l.is_finite() {
                            *sum += l.as_dvec3();
                        } else {
                            dropped = true;
                        }
                    }
                    discarded += u64::from(dropped);
                }
                (sums.iter().map(|s| (*s / f64::from(spp)).as_vec3()).collect(), rays, discarded)
            })
            .collect();
        let stats = value_stats(pixels.len(), spp, per_pixel.iter().map(|p| (p.1, p.2)));
        let columns = (0..n).map(|i| per_pixel.iter().map(|p| p.0[i]).collect()).collect();
        Ok((columns, stats))
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
        let (mut grads, stats) =
            self.gradient_pixels_weighted(cameras, pixels, &[weights], spp_grad, seed, iteration)?;
        Ok((grads.swap_remove(0), stats))
    }

    /// [`Renderer::gradient_pixels`] for several weightings of the same pixels at once: entry i of the result
    /// is `∂(Σ_j weight_sets[i][j] · I_j)/∂θ`, bit for bit what `gradient_pixels` returns for
    /// `weight_sets[i]`. A path does not depend on the weights (they enter only its backward pass), so each
    /// pixel's paths are traced once and every weighting's backward pass runs on the same recorded path: a
    /// Jacobian per colour channel (three unit weightings) costs one trace instead of three. A pixel is traced
    /// when any weighting gives it a non-zero weight; a path is discarded for the weightings under which its
    /// entries are not finite, and counted once in the returned statistics if any weighting discarded it.
    pub fn gradient_pixels_weighted(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        weight_sets: &[&[Vec3]],
        spp_grad: u32,
        seed: u64,
        iteration: u64,
    ) -> Result<(Vec<Grads>, TraceStats), TracerError> {
        let per_pixel = self.pixel_entries(cameras, pixels, weight_sets, spp_grad, seed, iteration, |e| e)?;
        let mut grads = vec![Grads::zeros_like(self.params); weight_sets.len()];
        for (e, ..) in &per_pixel {
            for (g, e) in grads.iter_mut().zip(e) {
                integrator::accumulate(g, e);
            }
        }
        Ok((grads, gradient_stats(&per_pixel)))
    }

    /// Per pixel j, [`Renderer::gradient_pixels`] of pixel j alone with weight `weights[j]`, as the sparse
    /// list of the parameters its paths touched ([`SparseGrads`]: every value bit for bit the dense table's),
    /// passed to `reduce` as soon as it is estimated, so that only the reductions are held; and the work
    /// done. A Jacobian row per pixel: a dense table per pixel holds every material slot, which with a slot per
    /// triangle (a house's 521 k) is 25 MB to clear and read for each pixel, where its paths touch a few
    /// hundred.
    #[allow(clippy::too_many_arguments)]
    pub fn gradient_rows<T: Send>(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        weights: &[Vec3],
        spp_grad: u32,
        seed: u64,
        iteration: u64,
        reduce: impl Fn(SparseGrads) -> T + Sync,
    ) -> Result<(Vec<T>, TraceStats), TracerError> {
        let per_pixel = self.pixel_entries(cameras, pixels, &[weights], spp_grad, seed, iteration, |e| {
            reduce(e.first().map_or_else(SparseGrads::default, |e| sparse(e)))
        })?;
        let stats = gradient_stats(&per_pixel);
        Ok((per_pixel.into_iter().map(|p| p.0).collect(), stats))
    }

    /// Every pixel's gradient entries per weighting (validated as [`Renderer::gradient_pixels_weighted`]
    /// documents), reduced by `reduce`, with its ray counts, paths and discarded paths.
    #[allow(clippy::too_many_arguments)]
    fn pixel_entries<T: Send>(
        &self,
        cameras: &[Camera],
        pixels: &[PixelRef],
        weight_sets: &[&[Vec3]],
        spp_grad: u32,
        seed: u64,
        iteration: u64,
        reduce: impl Fn(Vec<Vec<GradEntry>>) -> T + Sync,
    ) -> Result<Vec<PixelGrads<T>>, TracerError> {
        check_pixels(cameras, pixels, spp_grad)?;
        for weights in weight_sets {
            if weights.len() != pixels.len() {
                return Err(TracerError::LengthMismatch {
                    what: "weights",
                    expected: pixels.len(),
                    got: weights.len(),
                });
            }
            // A non-finite weight would make every path of its pixel non-finite: the caller's bug, reported as
            // such rather than discarded (module doc).
            if let Some((index, w)) = weights.iter().enumerate().find(|(_, w)| !w.is_finite()) {
                return Err(TracerError::BadSetting {
                    what: "gradient weight",
                    requirement: "finite",
                    value: format!("{w} at pixel {index}"),
                });
            }
        }
        let ctx = self.context();
        let n_sets = weight_sets.len();
        let per_pixel: Vec<PixelGrads<T>> = pixels
            .par_iter()
            .enumerate()
            .map_init(
                || (Vec::new(), Vec::new(), Vec::<integrator::EntryIndex>::new()),
                |(record, path_entries, indices), (j, &p)| {
                    let mut entries = vec![Vec::new(); n_sets];
                    indices.resize_with(n_sets, Default::default);
                    for index in indices.iter_mut() {
                        index.clear();
                    }
                    let mut rays = [0; 2];
                    let mut discarded = 0;
                    // A zero weight means the pixel does not enter that objective: its gradient is exactly zero.
                    let ws: Vec<Option<Vec3>> = weight_sets
                        .iter()
                        .map(|w| Some(w[j]).filter(|&w| w != Vec3::ZERO).map(|w| w / spp_grad as f32))
                        .collect();
                    if ws.iter().all(Option::is_none) {
                        return (reduce(entries), rays, 0, 0);
                    }
                    for s in 0..spp_grad {
                        let rng = PathSampler::new(seed, Stream::Gradient, iteration, key(p), s);
                        let (o, d) = primary(cameras, p, &rng);
                        let l = integrator::trace(&ctx, o, d, &rng, Mode::Gradient, record, &mut rays);
                        let mut dropped = false;
                        for ((w, out), index) in ws.iter().zip(&mut entries).zip(indices.iter_mut()) {
                            let Some(w) = *w else { continue };
                            // The path's contributions go to a scratch list first, so that a non-finite one can
                            // be dropped whole (module doc) without touching the pixel's sums.
                            path_entries.clear();
                            integrator::backward(record, w, path_entries);
                            if l.is_finite() && entries_are_finite(path_entries) {
                                integrator::merge(out, path_entries, index);
                            } else {
                                dropped = true;
                            }
                        }
                        discarded += u64::from(dropped);
                    }
                    (reduce(entries), rays, u64::from(spp_grad), discarded)
                },
            )
            .collect();
        Ok(per_pixel)
    }
}

/// The work of a gradient call from its pixels' counts, added to the process totals.
fn gradient_stats<T>(per_pixel: &[PixelGrads<T>]) -> TraceStats {
    let mut stats = TraceStats::default();
    for (_, rays, paths, discarded) in per_pixel {
        stats.rays += rays[0] + rays[1];
        stats.shadow_rays += rays[1];
        stats.paths += paths;
        stats.discarded += discarded;
    }
    add_to_totals(&stats);
    stats
}

/// One pixel's gradient as sparse lists ([`Renderer::gradient_rows`]): every parameter the pixel's paths
/// touched, in ascending slot order, with the sum of its entries.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SparseGrads {
    /// (material slot, ∂/∂ of its parameters).
    pub materials: Vec<(u32, MaterialGradSum)>,
    /// (emitter slot, ∂/∂ of its emission).
    pub emission: Vec<(u32, DVec3)>,
}

/// A pixel's entries as [`SparseGrads`]: each parameter's entries summed from zero in their order, as
/// [`integrator::accumulate`] sums them into a zeroed dense table, so every value is the dense one bit for bit.
fn sparse(entries: &[GradEntry]) -> SparseGrads {
    let mut order: Vec<usize> = (0..entries.len()).collect();
    // Stable: a parameter's entries keep their order.
    order.sort_by_key(|&i| entries[i].param());
    let mut out = SparseGrads::default();
    for i in order {
        match entries[i] {
            GradEntry::Material(t, ref m) => match out.materials.last_mut() {
                Some((last, acc)) if *last == t => acc.add(m),
                _ => {
                    let mut acc = MaterialGradSum::default();
                    acc.add(m);
                    out.materials.push((t, acc));
                }
            },
            GradEntry::Emission(k, d) => match out.emission.last_mut() {
                Some((last, acc)) if *last == k => *acc += d,
                _ => out.emission.push((k, DVec3::ZERO + d)),
            },
        }
    }
    out
}

/// One pixel's gradient entries per weighting (or what a caller reduced them to), its [closest-hit, shadow]
/// ray counts, paths and discarded paths.
type PixelGrads<T = Vec<Vec<GradEntry>>> = (T, [u64; 2], u64, u64);

/// The work of a value-mode call over `n_pixels` pixels at `spp` paths each, from every pixel's [closest-hit,
/// shadow] ray counts and discarded paths, added to the process totals.
fn value_stats(n_pixels: usize, spp: u32, per_pixel: impl Iterator<Item = ([u64; 2], u64)> + Clone) -> TraceStats {
    let stats = TraceStats {
        paths: n_pixels as u64 * u64::from(spp),
        rays: per_pixel.clone().map(|p| p.0[0] + p.0[1]).sum(),
        shadow_rays: per_pixel.clone().map(|p| p.0[1]).sum(),
        discarded: per_pixel.map(|p| p.1).sum(),
    };
    add_to_totals(&stats);
    stats
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
