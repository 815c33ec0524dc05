//! One round's fit of the per-triangle parameters on a fixed mesh: closed-form ratio steps with the
//! smoothness regulariser, then (optionally) Adam. See the module docs of [`crate::triangle`].

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use tracer::PixelRef;

use super::pixels::TriSample;
use super::{RoundInputs, TriangleError, TriangleState};
use crate::fit::adam::{AdamConfig, AdamState};
use crate::fit::emission_solve::{Columns, SolveOptions, Unknowns, solve_on_columns};
use crate::fit::jacobian::Ctx;
use crate::fit::linear::DataLoss;
use crate::fit::pixels::uniform;
use crate::fit::samples::SampleCounter;
use crate::fit::solve::solve_options;

/// A triangle's closed-form update uses only its interior pixels (footprint wholly on it) when it has at least
/// this many: they depend on its own value alone. With fewer (small or grazing triangles) all its pixels are
/// used; the Jacobi iteration then settles the pixels shared with neighbours.
const MIN_INTERIOR: usize = 4;

/// Gauss–Seidel sweeps of the smoothness solve. Observed triangles settle in a few sweeps (their data weight
/// dominates); 64 sweeps carry a neighbour's value across ~8 unobserved triangles, beyond which a region keeps
/// its starting (object) value — the intended fallback.
const SMOOTH_SWEEPS: usize = 64;

/// Stream of the Adam batch draws ([`uniform`]), apart from the object stage's streams 1–3.
const STREAM_BATCH: u64 = 0x7269;

/// Stream of the emission solve's pixel draws ([`uniform`]), apart from the others.
const STREAM_EMISSION_PIXELS: u64 = 0x7265;

/// Joint light/albedo-scale steps of [`refine_light`] after the final round's fit; the last half are
/// averaged. Measured in the module docs of [`crate::triangle`].
pub const LIGHT_STEPS: u32 = 6;

/// Joint steps of each cycle of [`refine_light`] left out of its average: the first step crosses the valley
/// (measured: from 6.5 % off to within 1–2 %), the second settles; later ones scatter by their noise.
pub const LIGHT_BURN_IN: u32 = 2;

/// Cycles of [`refine_light`]: `LIGHT_STEPS` joint steps, then `fit_steps` ratio steps.
pub const LIGHT_CYCLES: u32 = 2;

/// Family-wise level of [`light_change_p`]'s test in [`refine_light`]: the probability that the stage moves a
/// light that the object stage got right (no change beyond the steps' Monte Carlo scatter) is at most 1 %.
/// At 1 % rather than the shrinkage's 0.1 %: the test has only the scatter of a cycle's averaged steps to go
/// on (few degrees of freedom), and a wrong light costs the texture far more (checker: 33 dB instead of 43 dB)
/// than a spurious move costs a uniform scene (albedo mean error 0.0007 → 0.0025).
pub const LIGHT_SIGNIFICANCE: f64 = 0.01;

/// Marquardt damping of the albedo scales in [`solve_light`] (prox = damping · mean J², in the L2 data term's
/// units). Measured in the module docs of [`crate::triangle`].
const LIGHT_DAMPING: f64 = 1e-3;

/// Step field of [`render_key`] for the emission solve of pass p (`EMISSION_KEY | p`), and the bit that keys
/// its second, independent Jacobian estimate: above every ratio step (< 2^16 steps) and Adam key (2^16 | it,
/// < 2^17 iterations), below the 2^20 of the round field.
const EMISSION_KEY: u32 = 1 << 17;
const EMISSION_SECOND_KEY: u64 = 1 << 18;

/// The key of the tracer's `iteration` argument for (round, step): distinct for every render of the stage
/// and disjoint from the object stage's keys (< 4·2^32).
#[must_use]
pub fn render_key(round: u32, step: u32) -> u64 {
    (16u64 << 32) | (u64::from(round) << 20) | u64::from(step)
}

/// What a round's fit leaves for the split test.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted {
    /// Mean per-channel |photo − render| over the fitted pixels, per step (before its update).
    pub loss: Vec<f64>,
    /// Per sample: photo − predicted render after the last update.
    pub residual: Vec<Vec3>,
    /// Per triangle: its parameters were fitted (its object does not emit).
    pub free: Vec<bool>,
    /// Path samples the round traced (value and gradient paths, discarded ones included).
    pub traced_paths: u64,
    /// Of these, the samples the tracer discarded as non-finite (at most
    /// [`crate::fit::samples::MAX_DISCARDED_FRACTION`] of them, else the round fails).
    pub discarded_samples: u64,
}

/// Pairs of triangles of one object that share an edge (edges identified by vertex position, as in
/// [`crate::subdivide`]); per triangle, its neighbours.
#[must_use]
pub fn neighbours(state: &TriangleState) -> Vec<Vec<u32>> {
    let key = |v: u32| state.positions[v as usize].to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
    let mut edges: HashMap<([u32; 3], [u32; 3]), Vec<u32>> = HashMap::new();
    for (t, tri) in state.triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (key(tri[e]), key(tri[(e + 1) % 3]));
            let k = if a <= b { (a, b) } else { (b, a) };
            edges.entry(k).or_default().push(t as u32);
        }
    }
    let mut out = vec![Vec::new(); state.triangles.len()];
    let mut keys: Vec<_> = edges.into_iter().collect();
    keys.sort_unstable_by_key(|k| k.0); // deterministic neighbour order
    for (_, tris) in keys {
        for (i, &t) in tris.iter().enumerate() {
            for &u in &tris[i + 1..] {
                if state.face_object[t as usize] == state.face_object[u as usize] && t != u {
                    out[t as usize].push(u);
                    out[u as usize].push(t);
                }
            }
        }
    }
    out
}

/// `min Σ_t n_t (ρ_t − r_t)² + λ Σ_(t,u) (ρ_t − ρ_u)²` over the free triangles by Gauss–Seidel, from `rho`
/// (updated in place). Triangles with neither data nor free neighbours keep their value.
pub fn smooth_solve(rho: &mut [Vec3], ratio: &[Vec3], weight: &[f64], nbrs: &[Vec<u32>], free: &[bool], lambda: f64) {
    for _ in 0..SMOOTH_SWEEPS {
        for t in 0..rho.len() {
            if !free[t] {
                continue;
            }
            let mut num = ratio[t].as_dvec3() * weight[t];
            let mut den = weight[t];
            for &u in &nbrs[t] {
                num += rho[u as usize].as_dvec3() * lambda;
                den += lambda;
            }
            if den > 0.0 {
                rho[t] = (num / den).as_vec3().clamp(Vec3::ZERO, Vec3::ONE);
            }
        }
    }
}

/// Shrink every triangle's estimate towards its object's pooled value ([`shrink_to_object`]) before the
/// smoothness solve. Measured in the module docs of [`crate::triangle`].
const SHRINK: bool = true;

/// 99.9 % quantile of χ² with 3 degrees of freedom (one per colour channel): the significance level of the
/// object-level update in [`shrink_to_object`] (a uniform object keeps its value 999 times in 1000 per step).
const CHI2_3_999: f64 = 16.266;

/// One fit step's evidence per triangle, over the pixels its update uses: the current base colour, the sums of
/// photo and render values, of squared differences (photo − render)², and the pixel count.
#[derive(Debug, Clone, Copy)]
pub struct Evidence<'a> {
    pub old: &'a [Vec3],
    pub t_sum: &'a [DVec3],
    pub r_sum: &'a [DVec3],
    pub d_sq: &'a [DVec3],
    pub count: &'a [f64],
    /// Interior pixels (footprint wholly on the triangle) per triangle.
    pub interior: &'a [usize],
}

impl Evidence<'_> {
    /// Sampling variance (per channel) of triangle `t`'s ratio estimate `ρ·T/R`, or `None` with fewer than 2
    /// pixels or no rendered radiance. The pixel differences photo − render scatter by the photo's and the
    /// render's Monte Carlo noise (plus any texture inside the triangle); their variance s² over the n pixels
    /// gives Var(T − R) = n·s², and ρ·T/R − ρ = ρ·(T − R)/R, so Var = ρ²·n·s²/R².
    #[must_use]
    pub fn ratio_variance(&self, t: usize) -> Option<DVec3> {
        let n = self.count[t];
        if n < 2.0 || self.r_sum[t].min_element() <= 0.0 {
            return None;
        }
        let mean_d = (self.t_sum[t] - self.r_sum[t]) / n;
        let s2 = (self.d_sq[t] - mean_d * mean_d * n) / (n - 1.0);
        let rho = self.old[t].as_dvec3();
        Some(rho * rho * n * s2.max(DVec3::ZERO) / (self.r_sum[t] * self.r_sum[t]))
    }
}

/// Empirical-Bayes (James–Stein) shrinkage of the per-triangle estimates `ratio` towards their object's pooled
/// value: per object and channel, the prior mean m = ΣT / Σ(R/ρ) is the object-level ratio update over all its
/// observed triangles' pixels (one ratio of two large sums: the per-triangle ratio T_t/R_t has the noise of a
/// few dozen pixels' renders in its denominator, which biases it upwards — E\[1/R\] > 1/E\[R\] — far more), the
/// estimates r_t have sampling variances v_t ([`Evidence::ratio_variance`]), and the spread of the true values
/// τ² = max(0, mean_t[(r_t − m)² − v_t]) is what the estimates scatter beyond their noise. Each estimate becomes
/// m + τ²/(τ² + v_t)·(r_t − m): on a uniform object (scatter explained by noise, τ² ≈ 0) every triangle keeps
/// the object's value; on a textured one (τ² ≫ v_t) each keeps its own. A triangle seen in a single pixel (no
/// measurable noise) or in fewer than `MIN_INTERIOR` interior pixels (its estimate rests on pixels shared with
/// neighbours and absorbs their misfit) has no clean evidence of a difference: it takes m. Unobserved triangles (left to the
/// smoothness solve) and those of emitting objects are unchanged. Only triangles with clean evidence enter m
/// and τ²; with fewer than 2 of them an object keeps its current value.
#[must_use]
pub fn shrink_to_object(
    ratio: &[Vec3],
    ev: &Evidence<'_>,
    face_object: &[u32],
    free: &[bool],
    objects: usize,
) -> Vec<Vec3> {
    let var: Vec<Option<DVec3>> = (0..ratio.len()).map(|t| if free[t] { ev.ratio_variance(t) } else { None }).collect();
    // Per object and channel: Σ T and Σ R/ρ (the render per unit albedo) over its observed triangles.
    let mut pooled = vec![(DVec3::ZERO, DVec3::ZERO, 0usize); objects];
    for (t, v) in var.iter().enumerate() {
        // Only triangles with clean evidence (interior pixels, see below) inform the object's value.
        if v.is_none() || ev.interior[t] < MIN_INTERIOR || ev.old[t].min_element() <= 0.0 {
            continue;
        }
        let o = &mut pooled[face_object[t] as usize];
        o.0 += ev.t_sum[t];
        o.1 += ev.r_sum[t] / ev.old[t].as_dvec3();
        o.2 += 1;
    }
    // The object's current value (pixel-weighted mean of its triangles' values) and the variance of the pooled
    // ratio, Σ n_t s_t² · (ρ_t/R_t)²-weighted like the per-triangle one: Var(ΣT − ΣR)/(Σ R/ρ)².
    let mut current = vec![(DVec3::ZERO, 0.0f64, DVec3::ZERO); objects];
    for (t, v) in var.iter().enumerate() {
        if !free[t] || ev.count[t] <= 0.0 {
            continue;
        }
        let o = &mut current[face_object[t] as usize];
        o.0 += ev.old[t].as_dvec3() * ev.count[t];
        o.1 += ev.count[t];
        let Some(v) = v.filter(|_| ev.interior[t] >= MIN_INTERIOR) else { continue };
        // v_t = ρ²·n·s²/R², so n·s² = v_t·(R/ρ)².
        let per_albedo = ev.r_sum[t] / ev.old[t].as_dvec3().max(DVec3::splat(f64::MIN_POSITIVE));
        o.2 += v * per_albedo * per_albedo;
    }
    let mean: Vec<Option<DVec3>> = pooled
        .iter()
        .zip(&current)
        .map(|((t, r, k), (cur, n, var_diff))| {
            if *n <= 0.0 {
                return None;
            }
            let cur = *cur / *n;
            // Fewer than 2 triangles with clean evidence: the object keeps its value.
            if *k < 2 || r.min_element() <= 0.0 {
                return Some(cur);
            }
            let m = (*t / *r).clamp(DVec3::ZERO, DVec3::ONE);
            // The object-level update is itself evidence: it moves the object's value only when significant,
            // z² = Σ_c (m − current)²/Var(m) above the 99.9 % quantile of χ²(3), 16.27 (a barely seen object,
            // e.g. a ceiling in 84 pixels mostly shared with walls, otherwise drifts on noise over the steps).
            let var_m = *var_diff / (*r * *r);
            let z2 = ((m - cur) * (m - cur) / var_m.max(DVec3::splat(1e-300))).element_sum();
            Some(if z2 > CHI2_3_999 { m } else { cur })
        })
        .collect();
    let mut excess = vec![(DVec3::ZERO, 0usize); objects];
    for (t, v) in var.iter().enumerate() {
        let (Some(v), Some(m)) = (v, mean[face_object[t] as usize]) else { continue };
        if ev.interior[t] < MIN_INTERIOR {
            continue;
        }
        let d = ratio[t].as_dvec3() - m;
        let e = &mut excess[face_object[t] as usize];
        e.0 += d * d - *v;
        e.1 += 1;
    }
    let tau2: Vec<DVec3> = excess.iter().map(|(s, k)| (*s / (*k).max(1) as f64).max(DVec3::ZERO)).collect();
    (0..ratio.len())
        .map(|t| {
            let o = face_object[t] as usize;
            let Some(m) = mean[o].filter(|_| free[t]) else { return ratio[t] };
            // Seen in fewer than MIN_INTERIOR interior pixels (its estimate then rests on pixels shared with
            // neighbours, whose misfit it absorbs) or in a single pixel (no measurable noise): no clean evidence
            // of a difference, so the object's value.
            if ev.count[t] > 0.0 && (var[t].is_none() || ev.interior[t] < MIN_INTERIOR) {
                return m.as_vec3();
            }
            let Some(v) = var[t] else { return ratio[t] };
            let keep = tau2[o] / (tau2[o] + v).max(DVec3::splat(f64::MIN_POSITIVE));
            (m + keep * (ratio[t].as_dvec3() - m)).as_vec3().clamp(Vec3::ZERO, Vec3::ONE)
        })
        .collect()
}

/// The object fit's bound on discarded path samples (`crate::fit::samples`), applied to a round's work.
fn bound_discards(round: u32, discarded: u64, paths: u64) -> Result<(), TriangleError> {
    if crate::fit::samples::within_bound(discarded, paths) {
        Ok(())
    } else {
        Err(TriangleError::TooManyDiscarded { round, discarded, paths })
    }
}

/// Runs the fit of one round on `state` (updated in place): `fit_steps` ratio steps under the current light.
pub fn fit_round(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    round: u32,
) -> Result<Fitted, TriangleError> {
    fit_pass(inputs, scene, samples, state, round, 0)
}

/// Pass `pass` of a round's fit: `fit_steps` ratio steps under the current light, random numbers keyed by
/// (seed, round, pass, step); pass 0 is [`fit_round`], later passes are [`refine_light`]'s.
pub fn fit_pass(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    round: u32,
    pass: u32,
) -> Result<Fitted, TriangleError> {
    let cfg = inputs.settings;
    let n = state.triangles.len();
    // Emitting objects keep their per-object materials (emission and materials are entangled there); their
    // emission is re-solved between passes of ratio steps. Only objects that emit now may emit: the object
    // stage's model decision (no emission) holds every other object at 0.
    let emits: Vec<bool> = state.emission.iter().map(|e| e.max_element() > 0.0).collect();
    let free: Vec<bool> = state.face_object.iter().map(|&o| !emits[o as usize]).collect();
    let nbrs = neighbours(state);
    let mut interior = vec![0usize; n];
    for s in samples {
        interior[s.tri as usize] += usize::from(s.interior);
    }
    let used = |s: &TriSample| s.interior || interior[s.tri as usize] < MIN_INTERIOR;
    let pix: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let mut loss = Vec::new();
    let mut residual = vec![Vec3::ZERO; samples.len()];
    let mut work = tracer::TraceStats::default();
    let steps = cfg.fit_steps.max(1);
    for k in pass * steps..(pass + 1) * steps {
        let params = state.params();
        let (values, stats) = tracer::Renderer::new(scene, &params, inputs.tracer)?.render_pixels(
            inputs.cameras,
            &pix,
            cfg.spp,
            cfg.seed,
            render_key(round, k),
        )?;
        work.add(&stats);
        let mut t_sum = vec![DVec3::ZERO; n];
        let mut r_sum = vec![DVec3::ZERO; n];
        let mut d_sq = vec![DVec3::ZERO; n];
        let mut count = vec![0f64; n];
        let mut l = 0.0;
        for (s, v) in samples.iter().zip(&values) {
            l += f64::from((*v - s.target).abs().element_sum()) / 3.0;
            if used(s) {
                let t = s.tri as usize;
                let d = (s.target - *v).as_dvec3();
                t_sum[t] += s.target.as_dvec3();
                r_sum[t] += v.as_dvec3();
                d_sq[t] += d * d;
                count[t] += 1.0;
            }
        }
        loss.push(l / samples.len().max(1) as f64);
        let old: Vec<Vec3> = state.materials.iter().map(|m| m.base_color).collect();
        let mut rho = old.clone();
        if cfg.fit_steps > 0 {
            let ratio: Vec<Vec3> = (0..n)
                .map(|t| {
                    let r = r_sum[t];
                    let q = |c: usize| if r[c] > 0.0 { t_sum[t][c] / r[c] } else { 1.0 };
                    (old[t].as_dvec3() * DVec3::new(q(0), q(1), q(2))).as_vec3().clamp(Vec3::ZERO, Vec3::ONE)
                })
                .collect();
            let ratio = if SHRINK {
                let evidence = Evidence {
                    old: &old,
                    t_sum: &t_sum,
                    r_sum: &r_sum,
                    d_sq: &d_sq,
                    count: &count,
                    interior: &interior,
                };
                shrink_to_object(&ratio, &evidence, &state.face_object, &free, state.emission.len())
            } else {
                ratio
            };
            smooth_solve(&mut rho, &ratio, &count, &nbrs, &free, cfg.smoothness);
            for (m, r) in state.materials.iter_mut().zip(&rho) {
                m.base_color = *r;
            }
        }
        // Residuals against the render predicted for the updated values: a pixel's radiance is linear in the
        // base colour of the triangle its centre sees (exactly so for an interior pixel of a diffuse one).
        for (j, (s, v)) in samples.iter().zip(&values).enumerate() {
            let t = s.tri as usize;
            let scale =
                Vec3::select(old[t].cmpgt(Vec3::ZERO), rho[t] / old[t].max(Vec3::splat(f32::MIN_POSITIVE)), Vec3::ONE);
            residual[j] = s.target - *v * scale;
        }
    }
    if cfg.adam_iterations > 0 {
        adam(inputs, scene, samples, state, &free, &nbrs, round, &mut work)?;
    }
    // The object fit's bound and reasons (`crate::fit::samples`), per round.
    if work.discarded > 0 {
        tracing::warn!(round, discarded = work.discarded, paths = work.paths, "non-finite path samples discarded");
    }
    bound_discards(round, work.discarded, work.paths)?;
    Ok(Fitted { loss, residual, free, traced_paths: work.paths, discarded_samples: work.discarded })
}

/// One pixel's Jacobian entries in [`solve_light`]: per emitter ∂I/∂e_k, per scaled object ∂I/∂s_o (RGB).
type LightRow = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// One unknown's Jacobian column over the solve's pixels (RGB).
type Column = Vec<[f64; 3]>;

/// One Gauss–Newton step on the light with the per-triangle textures fixed in shape: the unknowns are the
/// emission of `emitters` (objects) and, per colour channel, one scale s_o of the base colours of every
/// non-emitting object (ρ_t → s_o·ρ_t for its triangles). Radiance is linear in emission, and the ratio steps
/// only set each triangle's value *given* the light: a light that is off by a factor is compensated by albedos
/// off by its inverse (the albedo/emission scale valley, which only interreflection pins down), so re-solving
/// the emission alone with those albedos returns the same light. Moving the light and every object's albedo
/// scale together crosses that valley, as the object stage's joint step does. Same estimator
/// ([`crate::fit::emission_solve::solve_on_columns`]): the emission columns ∂I/∂e_k and the scale columns
/// ∂I/∂s_o = Σ_(t ∈ o) ρ_t ∂I/∂ρ_t from the same gradient paths, two independent estimates (instrumental
/// variables), IRLS-L1, relative emission lasso relaxed on its support, Marquardt damping of the scales,
/// s_o ≤ 1/max ρ_t (no albedo above 1); on `object.solve_pixels` pixels drawn uniformly (with replacement)
/// from the round's pixels, `object.solve_spp` paths per entry — the object stage's solve size. Every other
/// object's emission stays 0. Keyed by (seed, round, pass).
#[allow(clippy::too_many_arguments)]
fn solve_light(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    emitters: &[usize],
    free: &[bool],
    round: u32,
    pass: u32,
    work: &mut tracer::TraceStats,
) -> Result<Vec<DVec3>, TriangleError> {
    let cfg = inputs.settings;
    let s = inputs.object;
    let objects = state.emission.len();
    if samples.is_empty() || emitters.is_empty() {
        return Ok(vec![DVec3::ONE; objects]);
    }
    let key = render_key(round, EMISSION_KEY | pass);
    let drawn: Vec<&TriSample> = (0..u64::from(s.solve_pixels.max(1)))
        .map(|i| {
            let u = uniform(cfg.seed, STREAM_EMISSION_PIXELS, key, i);
            &samples[((u * samples.len() as f64) as usize).min(samples.len() - 1)]
        })
        .collect();
    let pix: Vec<PixelRef> = drawn.iter().map(|p| p.pixel).collect();
    let targets: Vec<Vec3> = drawn.iter().map(|p| p.target).collect();
    // Objects whose albedo scale is an unknown: those with a fitted (non-emitting) triangle.
    let mut scaled = vec![false; objects];
    for (t, &o) in state.face_object.iter().enumerate() {
        if free[t] {
            scaled[o as usize] = true;
        }
    }
    let scaled: Vec<usize> = (0..objects).filter(|&o| scaled[o]).collect();
    let mut slot = vec![usize::MAX; objects];
    for (i, &o) in scaled.iter().enumerate() {
        slot[o] = i;
    }
    let counter = SampleCounter::default();
    let ctx = Ctx { scene, cameras: inputs.cameras, settings: inputs.tracer, seed: cfg.seed, samples: &counter };
    let params = state.params();
    let spp = s.solve_spp.max(1);
    // Per pixel: the emitters' and the scales' Jacobian entries, reduced from the per-triangle gradient at once
    // (a row over every triangle would hold pixels × triangles values).
    let rows = |key: u64| -> Result<Vec<LightRow>, TriangleError> {
        pix.par_iter()
            .map(|p| {
                let g = ctx.gradient(&params, std::slice::from_ref(p), &[Vec3::ONE], spp, key)?;
                let e: Vec<[f64; 3]> = emitters.iter().map(|&o| g.emission[o].to_array()).collect();
                let mut x = vec![DVec3::ZERO; scaled.len()];
                for (t, m) in g.materials.iter().enumerate() {
                    let i = slot[state.face_object[t] as usize];
                    if free[t] && i != usize::MAX {
                        x[i] += state.materials[t].base_color.as_dvec3() * m.base_color;
                    }
                }
                Ok((e, x.iter().map(|v| v.to_array()).collect()))
            })
            .collect()
    };
    let columns = |r: &[LightRow]| -> (Vec<Column>, Vec<Column>) {
        let e = (0..emitters.len()).map(|k| r.iter().map(|row| row.0[k]).collect()).collect();
        let x = (0..scaled.len()).map(|i| r.iter().map(|row| row.1[i]).collect()).collect();
        (e, x)
    };
    let (je, jx) = columns(&rows(key)?);
    let (je2, jx2) = columns(&rows(key | EMISSION_SECOND_KEY)?);
    let mut e: Vec<[f64; 3]> = emitters.iter().map(|&o| state.emission[o].as_dvec3().to_array()).collect();
    let mut scale = vec![[1.0f64; 3]; scaled.len()];
    let mut top = vec![DVec3::ZERO; scaled.len()];
    for (t, m) in state.materials.iter().enumerate() {
        let i = slot[state.face_object[t] as usize];
        if free[t] && i != usize::MAX {
            top[i] = top[i].max(m.base_color.as_dvec3());
        }
    }
    // No albedo above 1; a channel that is 0 on every triangle has a zero column and keeps its scale 1.
    let hi: Vec<[f64; 3]> = top.iter().map(|m| m.to_array().map(|v| if v > 0.0 { 1.0 / v } else { 1.0 })).collect();
    let before = e.clone();
    // L2, not the object stage's IRLS-L1: the ratio steps match sums (means) of photo and render, and an L1
    // fit matches medians, which differ for the skewed Monte Carlo pixel estimates; alternating two estimators
    // with different fixed points walks along the albedo/emission valley (measured: the red light −1 % per pass
    // with L1, see the module docs).
    // No emission penalty: the lasso only selects which objects emit, and that is the object stage's decision,
    // kept here (its weight is also scaled for the L1 data term: with L2 it zeroed whole channels of the light).
    let opts = SolveOptions {
        loss: DataLoss::L2,
        emission_l1: 0.0,
        damping: LIGHT_DAMPING,
        ..solve_options(s, Unknowns::EmissionAndBaseColor)
    };
    let loss = solve_on_columns(
        Columns { a: &je, b: &je2 },
        Columns { a: &jx, b: &jx2 },
        &targets,
        &mut e,
        &[],
        &mut scale,
        &hi,
        &opts,
    );
    for (&o, v) in emitters.iter().zip(&e) {
        state.emission[o] = DVec3::from_array(*v).as_vec3();
    }
    for (t, m) in state.materials.iter_mut().enumerate() {
        let i = slot[state.face_object[t] as usize];
        if free[t] && i != usize::MAX {
            m.base_color =
                (m.base_color.as_dvec3() * DVec3::from_array(scale[i])).as_vec3().clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
    work.paths += counter.paths();
    work.discarded += counter.discarded();
    tracing::debug!(round, pass, loss, ?before, after = ?e, ?scale, "triangle light step");
    let mut per_object = vec![DVec3::ONE; objects];
    for (&o, v) in scaled.iter().zip(&scale) {
        per_object[o] = DVec3::from_array(*v);
    }
    Ok(per_object)
}

/// The p-value of "the light did not change": `steps[i][k]` is emitter k's emission after the i-th averaged
/// joint step of a cycle, `start[k]` its emission before the cycle. Per emitter and channel the Wald statistic
/// t = (x̄ − x₀)/(s/√n) of the mean x̄ of the n steps against the start, with the steps' scatter s as the Monte
/// Carlo standard error (each step is a fresh Gauss–Newton solve on newly drawn pixels and paths, so once
/// converged the steps scatter independently about the light the per-triangle model calls for). The scatter is
/// pooled over an emitter's 3 channels as a relative variance (the channels share their paths and pixels, so
/// their relative noise is alike; 3(n − 1) degrees of freedom instead of n − 1, which with n = 4 steps is the
/// difference between a t(3) and a t(9) tail). Then t² ~ F(1, 3(n − 1)) ([`super::significance::f_survival`],
/// two-sided), and the smallest p over the 3K tests × 3K (Bonferroni, valid whatever their dependence; the
/// same as asking whether Holm's procedure, [`super::significance::holm`], rejects any). 1 with fewer than 2
/// steps or no emitters.
#[must_use]
pub fn light_change_p(start: &[DVec3], steps: &[Vec<DVec3>]) -> f64 {
    let n = steps.len();
    if n < 2 || start.is_empty() {
        return 1.0;
    }
    let mut p_min = 1.0f64;
    let mut tests = 0usize;
    for (k, &x0) in start.iter().enumerate() {
        let mean = steps.iter().map(|s| s[k]).sum::<DVec3>() / n as f64;
        let mut ss = 0.0;
        let mut dof = 0.0;
        for c in 0..3 {
            if mean[c] <= 0.0 {
                continue;
            }
            ss += steps.iter().map(|s| ((s[k][c] - mean[c]) / mean[c]).powi(2)).sum::<f64>();
            dof += (n - 1) as f64;
        }
        for c in 0..3 {
            tests += 1;
            if mean[c] <= 0.0 || dof <= 0.0 {
                continue;
            }
            let se2 = ss / dof / n as f64;
            let rel = (mean[c] - x0[c]) / mean[c];
            let t2 = rel * rel / se2;
            p_min = p_min.min(super::significance::f_survival(t2, 1.0, dof));
        }
    }
    (p_min * tests as f64).min(1.0)
}

/// The final round's light, in [`LIGHT_CYCLES`] cycles: [`LIGHT_STEPS`] joint Gauss–Newton steps on the
/// emission of the emitting objects and the albedo scale of every other object (`solve_light`, per-triangle
/// textures fixed in shape), whose iterates after the first [`LIGHT_BURN_IN`] are averaged (Polyak–Ruppert:
/// once converged, each step scatters by the Monte Carlo noise of its Jacobian along the albedo/emission
/// valley), then a pass of `fit_steps` ratio steps against the averaged light ([`fit_pass`] `cycle + 1`), which
/// lets the texture follow the new light before the next cycle. Gated: after the first cycle's steps the
/// averaged light is tested against the light it started from ([`light_change_p`] at [`LIGHT_SIGNIFICANCE`]);
/// without a significant change the cycle is undone (emission and materials as the round's fit left them) and
/// the rest skipped: `Ok(None)`. Returns the last pass's [`Fitted`] (losses of all passes); without emitters,
/// or with `fit_steps` = 0, nothing to do: `Ok(None)`.
pub fn refine_light(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    round: u32,
    progress: &dyn crate::Progress,
) -> Result<Option<Fitted>, TriangleError> {
    let emits: Vec<bool> = state.emission.iter().map(|e| e.max_element() > 0.0).collect();
    let emitters: Vec<usize> = (0..emits.len()).filter(|&o| emits[o]).collect();
    if emitters.is_empty() || inputs.settings.fit_steps == 0 || LIGHT_STEPS == 0 {
        return Ok(None);
    }
    let free: Vec<bool> = state.face_object.iter().map(|&o| !emits[o as usize]).collect();
    let objects = state.emission.len();
    let mut work = tracer::TraceStats::default();
    let start = state.emission.clone();
    let kept_materials = state.materials.clone();
    let mut fitted: Option<Fitted> = None;
    for cycle in 0..LIGHT_CYCLES {
        let base: Vec<Vec3> = state.materials.iter().map(|m| m.base_color).collect();
        let mut cumulative = vec![DVec3::ONE; objects];
        let (mut sum_s, mut n) = (vec![DVec3::ZERO; objects], 0.0);
        // Per averaged step, the emitters' emission (in `emitters` order).
        let mut averaged: Vec<Vec<DVec3>> = Vec::new();
        for i in 0..LIGHT_STEPS {
            let pass = cycle * LIGHT_STEPS + i + 1;
            let scale = solve_light(inputs, scene, samples, state, &emitters, &free, round, pass, &mut work)?;
            for (c, s) in cumulative.iter_mut().zip(&scale) {
                *c *= *s;
            }
            if i >= LIGHT_BURN_IN.min(LIGHT_STEPS - 1) {
                for o in 0..objects {
                    sum_s[o] += cumulative[o];
                }
                averaged.push(emitters.iter().map(|&o| state.emission[o].as_dvec3()).collect());
                n += 1.0;
            }
        }
        // The averaged light, per emitter.
        let mean_e: Vec<DVec3> =
            (0..emitters.len()).map(|j| averaged.iter().map(|a| a[j]).sum::<DVec3>() / n).collect();
        if cycle == 0 {
            // The gate: the object stage's light stays unless the first cycle moved it significantly beyond
            // its own Monte Carlo scatter. A uniform scene's per-triangle model is its per-object model, whose
            // light the object stage already fitted jointly with the albedos; re-solving it only adds noise
            // that every albedo then follows. Not significant: the cycle is undone (emission and materials as
            // the round's fit left them) and the rest of the re-solve (a second cycle, two ratio passes) is
            // skipped.
            let from: Vec<DVec3> = emitters.iter().map(|&o| start[o].as_dvec3()).collect();
            let p = light_change_p(&from, &averaged);
            let proposed: Vec<[f32; 3]> = mean_e.iter().map(|e| e.as_vec3().to_array()).collect();
            tracing::debug!(round, p, ?proposed, "triangle light change test");
            if p > LIGHT_SIGNIFICANCE {
                state.emission.clone_from(&start);
                state.materials.clone_from(&kept_materials);
                let kept: Vec<[f32; 3]> = emitters.iter().map(|&o| start[o].to_array()).collect();
                tracing::info!(round, p, ?kept, ?proposed, "triangle light kept");
                progress.note(&format!(
                    "[triangle] round {round}: light kept at {kept:?} (proposed {proposed:?}: p = {p:.3} > \
                     {LIGHT_SIGNIFICANCE}, no significant change)"
                ));
                bound_discards(round, work.discarded, work.paths)?;
                return Ok(None);
            }
            tracing::info!(round, p, ?proposed, "triangle light change significant");
            progress.note(&format!(
                "[triangle] round {round}: light change significant (p = {p:.2e}), proposed {proposed:?}"
            ));
        }
        for (&o, e) in emitters.iter().zip(&mean_e) {
            state.emission[o] = e.as_vec3();
        }
        for (t, m) in state.materials.iter_mut().enumerate() {
            if free[t] {
                let s = sum_s[state.face_object[t] as usize] / n;
                m.base_color = (base[t].as_dvec3() * s).as_vec3().clamp(Vec3::ZERO, Vec3::ONE);
            }
        }
        let mut f = fit_pass(inputs, scene, samples, state, round, cycle + 1)?;
        if let Some(prev) = fitted.take() {
            f.loss.splice(0..0, prev.loss);
            f.traced_paths += prev.traced_paths;
            f.discarded_samples += prev.discarded_samples;
        }
        fitted = Some(f);
    }
    let Some(mut fitted) = fitted else { return Ok(None) };
    let from: Vec<[f32; 3]> = emitters.iter().map(|&o| start[o].to_array()).collect();
    let to: Vec<[f32; 3]> = emitters.iter().map(|&o| state.emission[o].to_array()).collect();
    tracing::info!(round, ?from, ?to, "triangle light re-solved");
    progress.note(&format!(
        "[triangle] round {round}: light {from:?} → {to:?} ({LIGHT_CYCLES} × {LIGHT_STEPS} joint steps)"
    ));
    fitted.traced_paths += work.paths;
    fitted.discarded_samples += work.discarded;
    bound_discards(round, fitted.discarded_samples, fitted.traced_paths)?;
    Ok(Some(fitted))
}

/// Adam on the per-triangle base colours (and roughness/metallic of specular objects): batches of
/// `object.batch_pixels` pixels drawn uniformly, `object.n_value` value and `object.n_grad` gradient paths,
/// the object stage's loss weight, plus the smoothness term `λ/N Σ_(t,u) |ρ_t − ρ_u|²` (N = fitted pixels,
/// the scale at which λ counts pixels of evidence), clamped to [0, 1]. The tracer's work is added to `work`.
fn adam(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    free: &[bool],
    nbrs: &[Vec<u32>],
    round: u32,
    work: &mut tracer::TraceStats,
) -> Result<(), TriangleError> {
    let cfg = inputs.settings;
    let s = inputs.object;
    let n = state.triangles.len();
    // 5 parameters per triangle: base colour RGB, roughness, metallic.
    let mut x: Vec<f64> = state
        .materials
        .iter()
        .flat_map(|m| [m.base_color.x, m.base_color.y, m.base_color.z, m.roughness, m.metallic].map(f64::from))
        .collect();
    let mut lr = vec![0.0; 5 * n];
    for t in (0..n).filter(|&t| free[t]) {
        let spec = inputs.specular.get(state.face_object[t] as usize).copied().unwrap_or(false);
        for p in 0..if spec { 5 } else { 3 } {
            lr[5 * t + p] = cfg.adam_lr;
        }
    }
    let (lo, hi) = (vec![0.0; 5 * n], vec![1.0; 5 * n]);
    let mut st = AdamState::new(5 * n, AdamConfig::default());
    let pool: Vec<&TriSample> = samples.iter().filter(|p| free[p.tri as usize]).collect();
    if pool.is_empty() {
        return Ok(());
    }
    let b = s.batch_pixels.max(1) as usize;
    let lambda = cfg.smoothness / pool.len() as f64;
    for it in 0..cfg.adam_iterations {
        let key = render_key(round, 1 << 16 | it);
        let batch: Vec<&TriSample> = (0..b as u64)
            .map(|i| {
                let u = uniform(cfg.seed, STREAM_BATCH, key, i);
                pool[((u * pool.len() as f64) as usize).min(pool.len() - 1)]
            })
            .collect();
        let pix: Vec<PixelRef> = batch.iter().map(|p| p.pixel).collect();
        let params = state.params();
        let renderer = tracer::Renderer::new(scene, &params, inputs.tracer)?;
        let (values, stats) = renderer.render_pixels(inputs.cameras, &pix, s.n_value, cfg.seed, key)?;
        work.add(&stats);
        let weights: Vec<Vec3> = values
            .iter()
            .zip(&batch)
            .map(|(v, p)| crate::fit::object::loss_weight(s, *v - p.target, p.target) / b as f32)
            .collect();
        let (g, stats) = renderer.gradient_pixels(inputs.cameras, &pix, &weights, s.n_grad, cfg.seed, key)?;
        work.add(&stats);
        let mut grad = vec![0.0; 5 * n];
        for t in 0..n {
            let m = &g.materials[t];
            grad[5 * t..5 * t + 5].copy_from_slice(&[
                m.base_color.x,
                m.base_color.y,
                m.base_color.z,
                m.roughness,
                m.metallic,
            ]);
            for &u in &nbrs[t] {
                for c in 0..3 {
                    grad[5 * t + c] += 2.0 * lambda * (x[5 * t + c] - x[5 * u as usize + c]);
                }
            }
        }
        // The tracer discards non-finite samples, so this is a bug check (e.g. a non-finite weight).
        if !grad.iter().all(|v| v.is_finite()) {
            return Err(TriangleError::Input(format!("non-finite gradient in round {round}, Adam iteration {it}")));
        }
        st.step(&mut x, &grad, &lr, &lo, &hi);
        for (t, m) in state.materials.iter_mut().enumerate() {
            m.base_color = Vec3::new(x[5 * t] as f32, x[5 * t + 1] as f32, x[5 * t + 2] as f32);
            m.roughness = x[5 * t + 3] as f32;
            m.metallic = x[5 * t + 4] as f32;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smoothing_fills_an_unobserved_triangle_with_its_neighbours_mean_and_keeps_isolated_ones() {
        // Chain 0 - 1 - 2 (1 unobserved) and 3 alone (unobserved).
        let nbrs = vec![vec![1], vec![0, 2], vec![1], vec![]];
        let ratio = vec![Vec3::splat(0.2), Vec3::ZERO, Vec3::splat(0.6), Vec3::ZERO];
        let weight = [100.0, 0.0, 100.0, 0.0];
        let mut rho = vec![Vec3::splat(0.5); 4];
        smooth_solve(&mut rho, &ratio, &weight, &nbrs, &[true; 4], 1.0);
        assert!((rho[1].x - 0.4).abs() < 1e-3, "{rho:?}");
        assert_eq!(rho[3], Vec3::splat(0.5));
        // Observed triangles move only slightly towards their neighbour (weight 100 vs 1).
        assert!((rho[0].x - 0.2).abs() < 0.01, "{rho:?}");
    }

    /// Evidence of triangles that each saw 100 interior pixels with render = photo·ρ_old/ρ_true (so the ratio
    /// is the true value) and a pixel scatter giving ratio variance `v`.
    type Sums = (Vec<DVec3>, Vec<DVec3>, Vec<DVec3>, Vec<f64>, Vec<usize>);

    fn evidence(old: &[Vec3], truth: &[Vec3], v: f64) -> Sums {
        let n = 100.0;
        let t_sum: Vec<DVec3> = truth.iter().map(|_| DVec3::splat(n * 0.5)).collect();
        let r_sum: Vec<DVec3> =
            old.iter().zip(truth).map(|(o, t)| DVec3::splat(n * 0.5) * o.as_dvec3() / t.as_dvec3()).collect();
        // v = ρ²·n·s²/R² ⇒ Σd² ≈ (n − 1)·s² + n·mean_d².
        let d_sq: Vec<DVec3> = (0..old.len())
            .map(|t| {
                let rho = old[t].as_dvec3();
                let s2 = DVec3::splat(v) * r_sum[t] * r_sum[t] / (rho * rho * n);
                let mean_d = (t_sum[t] - r_sum[t]) / n;
                s2 * (n - 1.0) + mean_d * mean_d * n
            })
            .collect();
        (t_sum, r_sum, d_sq, vec![n; old.len()], vec![100; old.len()])
    }

    #[test]
    fn a_uniform_object_keeps_its_value_and_a_textured_one_its_triangles_values() {
        // Object 0: uniform 0.5, triangle ratios scattered by exactly the noise (±0.01, v = 1e-4).
        // Object 1: a checker 0.2 / 0.8 (spread far beyond the same noise).
        let old = vec![Vec3::splat(0.5); 8];
        let ratio: Vec<Vec3> = [0.51, 0.49, 0.51, 0.49, 0.2, 0.8, 0.2, 0.8].iter().map(|&x| Vec3::splat(x)).collect();
        let (t_sum, r_sum, d_sq, count, interior) = evidence(&old, &ratio, 1e-4);
        let ev = Evidence { old: &old, t_sum: &t_sum, r_sum: &r_sum, d_sq: &d_sq, count: &count, interior: &interior };
        let v = ev.ratio_variance(0).unwrap();
        assert!((v.x - 1e-4).abs() < 1e-9, "{v}");
        let face_object = [0, 0, 0, 0, 1, 1, 1, 1];
        let out = shrink_to_object(&ratio, &ev, &face_object, &[true; 8], 2);
        for t in 0..4 {
            // Object-level update 0.5 is not significantly different from 0.5: every triangle keeps 0.5.
            assert!((out[t].x - 0.5).abs() < 1e-6, "{out:?}");
        }
        for t in 4..8 {
            // τ² ≈ 0.09 ≫ v: shrink factor ≈ 1e-4/0.09, the values move by < 0.001.
            assert!((out[t].x - ratio[t].x).abs() < 1e-3, "{out:?}");
        }
    }

    #[test]
    fn the_light_step_recovers_emission_and_albedo_scale_from_noisy_columns() {
        // Pixels I_j = a_j·e + b_j·(s − 1) (linearised about s = 1): the true light e = 20 and albedo scale
        // s = 0.95, started from e = 18.5; the columns are estimated twice with independent zero-mean noise of
        // 30 % (Monte Carlo columns), the photos carry 2 % noise. Instrumental variables make the L2 solve
        // consistent; plain least squares on one noisy estimate would shrink e by 1/(1 + 0.3²) ≈ 8 %.
        let m = 4000;
        let mut rng = 0x1234_5678_9abc_def0u64;
        let mut noise = || {
            rng = crate::fit::pixels::mix64(rng);
            (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (e_true, s_true) = (20.0, 0.95);
        // Independent random columns (the light's reach and the object's share of each pixel).
        let a: Vec<f64> = (0..m).map(|_| 0.01 + 0.02 * (0.5 + 0.5 * noise())).collect();
        let b: Vec<f64> = (0..m).map(|_| 0.4 * (0.5 + 0.5 * noise())).collect();
        let sq3 = 3f64.sqrt(); // uniform on [−√3, √3]·σ has standard deviation σ
        let mut est = |col: &[f64]| -> Vec<[f64; 3]> {
            col.iter().map(|v| [v * (1.0 + 0.3 * sq3 * noise()); 3]).collect::<Vec<_>>()
        };
        let (ja, ja2, jb, jb2) = (est(&a), est(&a), est(&b), est(&b));
        let targets: Vec<Vec3> = (0..m)
            .map(|j| Vec3::splat(((a[j] * e_true + b[j] * (s_true - 1.0)) * (1.0 + 0.02 * sq3 * noise())) as f32))
            .collect();
        let mut e = vec![[18.5; 3]];
        let mut scale = vec![[1.0; 3]];
        let opts = SolveOptions {
            unknowns: Unknowns::EmissionAndBaseColor,
            loss: DataLoss::L2,
            emission_l1: 0.0,
            damping: LIGHT_DAMPING,
            irls_iters: 1,
        };
        let cols = |x: &'_ [Vec<[f64; 3]>], y: &'_ [Vec<[f64; 3]>]| (x.to_vec(), y.to_vec());
        let (ea, eb) = cols(&[ja], &[ja2]);
        let (sa, sb) = cols(&[jb], &[jb2]);
        solve_on_columns(
            Columns { a: &ea, b: &eb },
            Columns { a: &sa, b: &sb },
            &targets,
            &mut e,
            &[],
            &mut scale,
            &[[2.0; 3]],
            &opts,
        );
        for c in 0..3 {
            // 2 %: a quarter of the errors-in-variables shrinkage that plain least squares would show.
            assert!((e[0][c] / e_true - 1.0).abs() < 0.02, "{e:?}");
            // The scale moves a pixel by b·Δs against the light's a·e (mean 0.2·Δs against 0.4): a 1 % error of e
            // is matched by Δs = 0.02, so the scale is known to a few hundredths only.
            assert!((scale[0][c] - s_true).abs() < 0.03, "{e:?} {scale:?}");
        }
    }

    /// Standard normal draws (Box–Muller on the seeded [`crate::fit::pixels::mix64`] stream).
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let mut rng = seed;
        let mut u = || {
            rng = crate::fit::pixels::mix64(rng);
            ((rng >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * u().ln()).sqrt() * (2.0 * std::f64::consts::PI * u()).cos()).collect()
    }

    #[test]
    fn the_light_change_test_holds_its_level_and_sees_a_light_off_by_its_scatter_times_a_few() {
        // Null: 4 steps scatter independently by 1.5 % (the measured per-step scatter) about the start light.
        // Over 4000 seeded trials the rejection rate at 1 % must stay at most the level (Bonferroni over the
        // channels is conservative) up to its binomial noise (4 standard deviations of 0.01·4000: ±25).
        let start = vec![DVec3::new(20.0, 18.0, 15.0)];
        let trials = 4000;
        let z = normals(0x5eed, trials * 4 * 3);
        let mut rejected = 0;
        let mut shifted_rejected = 0;
        for i in 0..trials {
            let steps = |shift: f64| -> Vec<Vec<DVec3>> {
                (0..4)
                    .map(|j| {
                        let k = 12 * i + 3 * j;
                        vec![start[0] * (1.0 + shift) * (DVec3::ONE + 0.015 * DVec3::new(z[k], z[k + 1], z[k + 2]))]
                    })
                    .collect()
            };
            rejected += usize::from(light_change_p(&start, &steps(0.0)) <= LIGHT_SIGNIFICANCE);
            // A light 6 % off (the checker's object stage): 8 standard errors of the 4-step mean (0.75 %).
            shifted_rejected += usize::from(light_change_p(&start, &steps(-0.06)) <= LIGHT_SIGNIFICANCE);
        }
        eprintln!("rejected at {LIGHT_SIGNIFICANCE}: null {rejected}, 6 % shift {shifted_rejected} of {trials}");
        assert!(rejected <= 40 + 25, "null rejected {rejected} of {trials}");
        // Power: t(9) beyond the Bonferroni threshold (|t| ≈ 3.7) at a mean of 8 is all but certain.
        assert!(shifted_rejected as f64 >= 0.99 * trials as f64, "6 % shift seen {shifted_rejected} of {trials}");
        // Degenerate inputs: no steps, one step, no emitters → no evidence.
        assert_eq!(light_change_p(&start, &[]), 1.0);
        assert_eq!(light_change_p(&start, std::slice::from_ref(&start)), 1.0);
        assert_eq!(light_change_p(&[], &[vec![], vec![]]), 1.0);
    }

    #[test]
    fn render_keys_are_distinct_per_round_and_step() {
        let mut keys: Vec<u64> = (0..4).flat_map(|r| (0..8).map(move |s| render_key(r, s))).collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), 32);
        assert!(render_key(0, 0) > 4 << 32);
    }
}
