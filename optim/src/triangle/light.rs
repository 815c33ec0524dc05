//! The final round's light: the emission re-solved together with every non-emitting object's albedo scale
//! (texture shapes fixed), in cycles of averaged joint Gauss–Newton steps and ratio passes, and kept only when
//! a Wald test finds that it moved beyond its own Monte Carlo scatter. See the module docs of
//! [`crate::triangle`].

use glam::{DVec3, Vec3};
use tracer::PixelRef;

use super::pixels::TriSample;
use super::ratio::{Fitted, bound_discards, fit_pass};
use super::{RoundInputs, TriangleError, TriangleState};
use crate::fit::emission_solve::{Columns, SolveOptions, Unknowns, solve_on_columns};
use crate::fit::jacobian::Ctx;
use crate::fit::linear::{DataLoss, mean_se};
use crate::fit::pixels::{Stratum, draw_strata_rows};
use crate::fit::samples::SampleCounter;
use crate::fit::solve::{SOLVE_FLOOR, solve_options};
use crate::streams::{draw, key, uniform};

/// Fewest joint light/albedo-scale steps of a cycle of [`refine_light`] (`triangle.light_steps` is the most):
/// [`LIGHT_BURN_IN`] left out, 4 averaged, the count the light-change gate was calibrated with and the one the
/// default scene's light settles in (docs/optim/design-measurements.md, "Joint steps per light cycle").
pub const LIGHT_MIN_STEPS: u32 = 6;

/// Joint steps of each cycle of [`refine_light`] left out of its average: the first step crosses the valley
/// (measured: from 6.5 % off to within 1–2 %), the second settles; later ones scatter by their noise.
pub const LIGHT_BURN_IN: u32 = 2;

/// Cycles of [`refine_light`]: [`LIGHT_MIN_STEPS`] to `triangle.light_steps` joint steps, then
/// `triangle.light_fit_steps` ratio steps.
pub const LIGHT_CYCLES: u32 = 2;

/// Family-wise level of [`light_change_p`]'s test in [`refine_light`]: the probability that the stage moves a
/// light that the object stage got right (no change beyond the steps' Monte Carlo scatter) is at most 1 %.
/// At 1 % rather than the shrinkage's 0.1 %: the test has only the scatter of a cycle's averaged steps to go
/// on (few degrees of freedom), and a wrong light costs the texture far more (checker: 33 dB instead of 43 dB)
/// than a spurious move costs a uniform scene (albedo mean error 0.0007 → 0.0025).
pub const LIGHT_SIGNIFICANCE: f64 = 0.01;

/// Marquardt damping of the albedo scales in [`solve_light`] (prox = damping · mean J², in the L2 data term's
/// units). Measured in `docs/optim/design-measurements.md`.
const LIGHT_DAMPING: f64 = 1e-3;

/// Per joint step of [`solve_light`], an albedo scale stays within [1/`LIGHT_SCALE_TRUST`,
/// `LIGHT_SCALE_TRUST`] (a trust region about the linearisation point s = 1). The step needs scales of the
/// light's own relative error (the object stage's unseen lamps were up to 69 % off, a factor 1.7), but each
/// object's scale rests on a few dozen rows and two Monte Carlo estimates of its column, whose ratio (the
/// instrumental-variables estimate) has heavy tails: on the natively rendered house one step put 30 of 189
/// scales outside [1/2, 2], from 0 to 81 (docs/optim/design-measurements.md, "Albedo scales of the light
/// re-solve"). A scale of 0 is final — an object at base colour 0 has a zero column in every later step, and
/// the ratio steps multiply its value — so whole walls and floors ended black.
pub const LIGHT_SCALE_TRUST: f64 = 2.0;

/// One pixel's Jacobian entries in [`solve_light`]: per emitter ∂I/∂e_k, per scaled object ∂I/∂s_o (RGB).
type LightRow = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// One unknown's Jacobian column over the solve's pixels (RGB).
type Column = Vec<[f64; 3]>;

/// One Gauss–Newton step on the light with the per-triangle textures fixed in shape: the unknowns are the emission
/// of `emitters` (objects) and, per colour channel, one scale s_o of the base colours of every `scaled` object
/// ([`scaled_objects`]: non-emitting and constrained; ρ_t → s_o·ρ_t for its triangles). Radiance is linear in
/// emission, and the ratio steps only set each triangle's
/// value *given* the light: a light that is off by a factor is compensated by albedos off by its inverse (the
/// albedo/emission scale valley, which only interreflection pins down), so re-solving the emission alone with those
/// albedos returns the same light. Moving the light and every object's albedo scale together crosses that valley,
/// as the object stage's joint step does. Same estimator ([`crate::fit::emission_solve::solve_on_columns`]): the
/// emission columns ∂I/∂e_k and the scale columns ∂I/∂s_o = Σ_(t ∈ o) ρ_t ∂I/∂ρ_t from the same gradient paths, two
/// independent estimates (instrumental variables), IRLS-L1, relative emission lasso relaxed on its support,
/// Marquardt damping of the scales, s_o ≤ 1/max ρ_t (no albedo above 1) and within the trust region of
/// [`LIGHT_SCALE_TRUST`]; on pixels drawn from the round's pixels as the object stage's solves draw them (`strata`:
/// per object its [`SOLVE_FLOOR`] pixels, the rest of `object.solve_pixels` in proportion to the objects' pixels,
/// weighted so that the data term estimates the mean over all of them without bias), `object.solve_spp` paths per
/// entry — the object stage's solve size. Drawn uniformly instead, the 1024 pixels of a 213-object house gave each
/// seen lamp 0.03–0.7 rows on average (it covers 0.003–0.06 % of the photos), and the averaged steps took a seen
/// lamp to 4× its emission and an unseen one to 245× in one channel. Every other object's emission stays 0. Keyed
/// by (seed, round, pass).
#[allow(clippy::too_many_arguments)]
fn solve_light(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    strata: &[Stratum],
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
    let key = key::triangle(round, key::TRIANGLE_EMISSION | pass);
    let (rows, weights) = draw_strata_rows(
        strata,
        s.solve_pixels.max(1) as usize,
        SOLVE_FLOOR,
        cfg.seed,
        draw::TRIANGLE_EMISSION_PIXELS,
        key,
    );
    let drawn: Vec<&TriSample> = rows.iter().map(|&j| &samples[j]).collect();
    let pix: Vec<PixelRef> = drawn.iter().map(|p| p.pixel).collect();
    let targets: Vec<Vec3> = drawn.iter().map(|p| p.target).collect();
    let scaled = scaled_objects(&state.face_object, free, objects);
    let scaled: Vec<usize> = (0..objects).filter(|&o| scaled[o]).collect();
    let mut slot = vec![usize::MAX; objects];
    for (i, &o) in scaled.iter().enumerate() {
        slot[o] = i;
    }
    let counter = SampleCounter::default();
    let ctx = Ctx {
        scene,
        cameras: inputs.cameras,
        settings: inputs.tracer,
        seed: cfg.seed,
        samples: &counter,
        split: &crate::fit::layout::NO_SPLIT,
    };
    let params = state.params();
    let spp = s.solve_spp.max(1);
    // Per pixel: the emitters' and the scales' Jacobian entries, reduced from the pixel's sparse per-triangle
    // gradient (the triangles its paths touched, in ascending order): a dense table over every triangle per
    // pixel, cleared and read whole, was most of a house's light step (docs/scale/README.md, "Per-pixel
    // gradients at house scale").
    let rows = |key: u64| -> Result<Vec<LightRow>, TriangleError> {
        Ok(ctx.gradient_rows(&params, &pix, spp, key, |g| {
            let emission_of = |o: usize| {
                g.emission.binary_search_by_key(&(o as u32), |&(k, _)| k).map_or(DVec3::ZERO, |i| g.emission[i].1)
            };
            let e: Vec<[f64; 3]> = emitters.iter().map(|&o| emission_of(o).to_array()).collect();
            let mut x = vec![DVec3::ZERO; scaled.len()];
            for &(t, ref m) in &g.materials {
                let t = t as usize;
                let i = slot[state.face_object[t] as usize];
                if free[t] && i != usize::MAX {
                    x[i] += state.materials[t].base_color.as_dvec3() * m.base_color;
                }
            }
            (e, x.iter().map(|v| v.to_array()).collect())
        })?)
    };
    let columns = |r: &[LightRow]| -> (Vec<Column>, Vec<Column>) {
        let e = (0..emitters.len()).map(|k| r.iter().map(|row| row.0[k]).collect()).collect();
        let x = (0..scaled.len()).map(|i| r.iter().map(|row| row.1[i]).collect()).collect();
        (e, x)
    };
    let (je, jx) = columns(&rows(key)?);
    let (je2, jx2) = columns(&rows(key | key::TRIANGLE_EMISSION_SECOND)?);
    let mut e: Vec<[f64; 3]> = emitters.iter().map(|&o| state.emission[o].as_dvec3().to_array()).collect();
    let mut scale = vec![[1.0f64; 3]; scaled.len()];
    let mut top = vec![DVec3::ZERO; scaled.len()];
    for (t, m) in state.materials.iter().enumerate() {
        let i = slot[state.face_object[t] as usize];
        if free[t] && i != usize::MAX {
            top[i] = top[i].max(m.base_color.as_dvec3());
        }
    }
    // No albedo above 1; a channel that is 0 on every triangle has a zero column and keeps its scale 1. Within
    // the trust region (`LIGHT_SCALE_TRUST`); 1/max ρ ≥ 1 keeps the box non-empty.
    let hi: Vec<[f64; 3]> = top
        .iter()
        .map(|m| m.to_array().map(|v| if v > 0.0 { (1.0 / v).min(LIGHT_SCALE_TRUST) } else { 1.0 }))
        .collect();
    let lo: Vec<[f64; 3]> = hi.iter().map(|h| h.map(|h| (1.0 / LIGHT_SCALE_TRUST).min(h))).collect();
    let before = e.clone();
    // L2, not the object stage's IRLS-L1: the ratio steps match sums (means) of photo and render, and an L1
    // fit matches medians, which differ for the skewed Monte Carlo pixel estimates; alternating two estimators
    // with different fixed points walks along the albedo/emission valley (measured: the red light −1 % per pass
    // with L1, see `docs/optim/design-measurements.md`).
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
        &weights,
        &[],
        &mut e,
        &[],
        &mut scale,
        &lo,
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

/// Per object, whether its albedo scale is an unknown of the light re-solve: it has a fitted (`free`) triangle
/// ([`super::fitted_triangles`]: not an emitter, nor an object the object stage left unconstrained). Such an
/// object's value is the object stage's estimate weighed against a prior by its standard error
/// (`crate::fit::prior`); a scale of its own here rests on its few pixels, or on what it reflects, without that
/// prior, and undid it: on the corpus house a sphere seen in 4 pixels, at its category's mean (0.52, 0.54, 0.49)
/// after the object stage, came out of the light re-solve at (0.47, 0.18, 0.48), while `materials.json` still
/// called it unconstrained.
fn scaled_objects(face_object: &[u32], free: &[bool], objects: usize) -> Vec<bool> {
    let mut scaled = vec![false; objects];
    for (&o, &f) in face_object.iter().zip(free) {
        scaled[o as usize] |= f;
    }
    scaled
}

/// The round's pixels grouped by the object their centre sees (the strata of [`solve_light`]'s draw), in
/// object order.
fn object_strata(samples: &[TriSample], face_object: &[u32], objects: usize) -> Vec<Stratum> {
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); objects];
    for (i, s) in samples.iter().enumerate() {
        members[face_object[s.tri as usize] as usize].push(i);
    }
    members
        .into_iter()
        .enumerate()
        .filter(|(_, m)| !m.is_empty())
        .map(|(o, m)| Stratum { object: Some(o as u32), population: m.len(), members: m })
        .collect()
}

/// Emitter k's relative scatter over a cycle's averaged steps (`steps[i][k]`: its emission after step i): the
/// variance of one step about the steps' mean, relative to that mean and pooled over the channels whose mean
/// is positive (the channels share their paths and pixels, so their relative noise is alike), with its degrees
/// of freedom (n − 1 per such channel), and the mean. `None` with fewer than 2 steps or no positive channel.
fn relative_scatter(steps: &[Vec<DVec3>], k: usize) -> Option<(f64, f64, DVec3)> {
    let n = steps.len();
    if n < 2 {
        return None;
    }
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
    (dof > 0.0).then_some((ss / dof, dof, mean))
}

/// The largest relative standard error of an emitter's mean over a cycle's averaged steps (`steps[i][k]`, see
/// [`relative_scatter`]): what the cycle's averaged light is known to. Infinite with fewer than 2 steps.
#[must_use]
pub fn light_relative_se(steps: &[Vec<DVec3>]) -> f64 {
    if steps.len() < 2 {
        return f64::INFINITY;
    }
    let n = steps.len() as f64;
    (0..steps[0].len())
        .filter_map(|k| relative_scatter(steps, k))
        .map(|(var, _, _)| (var / n).sqrt())
        .fold(0.0, f64::max)
}

/// Each emitter's light after a later cycle of [`refine_light`]: `(prev, prev_var)` is its light before the
/// cycle and that light's relative variance (per channel, the square of its relative standard error), `steps`
/// the cycle's averaged steps. Where the cycle's mean agrees with the previous light within their joint Monte
/// Carlo scatter (per channel, |Δ|/√(v_prev + v_cycle) ≤ [`POOL_Z`]), the two are two estimates of one light
/// and their inverse-variance weighted mean is known better than either (relative variance
/// 1/(1/v_prev + 1/v_cycle)); where it does not, the light moved with the textures the cycle started from, and
/// the cycle's mean replaces it. A lamp that no photo sees scatters by a quarter of its value per step on the
/// house, so one cycle knows it only to 6–12 %, and a second cycle that replaced the first's estimate with a
/// fresh one as noisy lost what the first had found (docs/optim/design-measurements.md, "Light cycles pooled
/// where they agree"). An emitter whose steps give no scatter to go on (fewer than 2 steps, or every channel
/// at 0) takes the cycle's mean, its variance unknown (infinite); without steps everything stays as `prev`.
#[must_use]
pub fn pool_cycles(prev: &[DVec3], prev_var: &[DVec3], steps: &[Vec<DVec3>]) -> Vec<(DVec3, DVec3)> {
    if steps.is_empty() {
        return prev.iter().copied().zip(prev_var.iter().copied()).collect();
    }
    let n = steps.len() as f64;
    (0..prev.len())
        .map(|k| {
            let Some((var, _, mean)) = relative_scatter(steps, k) else {
                return (steps.iter().map(|s| s[k]).sum::<DVec3>() / n, DVec3::INFINITY);
            };
            let v_cycle = var / n;
            let mut light = mean;
            let mut rel_var = DVec3::splat(v_cycle);
            for c in 0..3 {
                let (a, va) = (prev[k][c], prev_var[k][c]);
                // A channel at 0 or a previous light of unknown variance (NaN included) is not pooled.
                if mean[c] <= 0.0 || a <= 0.0 || !(va.is_finite() && va > 0.0) {
                    continue;
                }
                // Variances relative to each estimate's own value, put on one absolute scale.
                let (sa, sb) = (va * a * a, v_cycle * mean[c] * mean[c]);
                if (mean[c] - a).abs() > POOL_Z * (sa + sb).sqrt() {
                    continue;
                }
                let w = sb / (sa + sb);
                light[c] = w * a + (1.0 - w) * mean[c];
                rel_var[c] = sa * sb / (sa + sb) / (light[c] * light[c]);
            }
            (light, rel_var)
        })
        .collect()
}

/// Largest disagreement, in joint standard errors, at which [`pool_cycles`] takes two cycles' lights for
/// estimates of one light: two-sided 1 %, the light-change gate's level ([`LIGHT_SIGNIFICANCE`]), so that a
/// light is held to the previous cycle's only where nothing shows that it moved.
pub const POOL_Z: f64 = 2.576;

/// Each emitter's relative variance of its mean over a cycle's averaged steps (see [`relative_scatter`]), per
/// channel; infinite (unknown) where it has no scatter to go on.
fn cycle_rel_var(steps: &[Vec<DVec3>], emitters: usize) -> Vec<DVec3> {
    let n = steps.len() as f64;
    (0..emitters)
        .map(|k| relative_scatter(steps, k).map_or(DVec3::INFINITY, |(var, _, _)| DVec3::splat(var / n)))
        .collect()
}

/// The p-value of "the light did not change": `steps[i][k]` is emitter k's emission after the i-th averaged
/// joint step of a cycle, `start[k]` its emission before the cycle. Per emitter and channel the Wald statistic
/// t = (x̄ − x₀)/(s/√n) of the mean x̄ of the n steps against the start, with the steps' scatter s as the Monte
/// Carlo standard error (each step is a fresh Gauss–Newton solve on newly drawn pixels and paths; once
/// converged the steps scatter about the light the per-triangle model calls for with no measurable
/// correlation: lag-1 autocorrelation −0.04 over 64 steps on the default scene, −0.22 and −0.08 over 16 on
/// the house, docs/optim/design-measurements.md, "Joint steps per light cycle"). The scatter is pooled over an
/// emitter's 3 channels as a relative variance ([`relative_scatter`]: 3(n − 1) degrees of freedom instead of
/// n − 1, which with n = 4 steps is the difference between a t(3) and a t(9) tail). Then
/// t² ~ F(1, 3(n − 1)) ([`super::significance::f_survival`], two-sided), and the smallest p over the 3K tests
/// × 3K (Bonferroni, valid whatever their dependence; the same as asking whether Holm's procedure,
/// [`super::significance::holm`], rejects any). 1 with fewer than 2 steps or no emitters.
#[must_use]
pub fn light_change_p(start: &[DVec3], steps: &[Vec<DVec3>]) -> f64 {
    let n = steps.len();
    if n < 2 || start.is_empty() {
        return 1.0;
    }
    let mut p_min = 1.0f64;
    let tests = 3 * start.len();
    for (k, &x0) in start.iter().enumerate() {
        let Some((var, dof, mean)) = relative_scatter(steps, k) else { continue };
        for c in 0..3 {
            if mean[c] <= 0.0 {
                continue;
            }
            let rel = (mean[c] - x0[c]) / mean[c];
            let t2 = rel * rel / (var / n as f64);
            p_min = p_min.min(super::significance::f_survival(t2, 1.0, dof));
        }
    }
    (p_min * tests as f64).min(1.0)
}

/// The final round's light, in [`LIGHT_CYCLES`] cycles: joint Gauss–Newton steps on the emission of the
/// emitting objects and the albedo scale of every other object (`solve_light`, per-triangle textures fixed in
/// shape), whose iterates after the first [`LIGHT_BURN_IN`] are averaged (Polyak–Ruppert: once converged, each
/// step scatters by the Monte Carlo noise of its Jacobian along the albedo/emission valley; each object's
/// averaged scale shrunk toward the common one by [`shrink_scales`]), then a pass of
/// `light_fit_steps` ratio steps against the averaged light ([`fit_pass`] `cycle + 1`), which lets the texture follow
/// the new light before the next cycle. A cycle takes [`LIGHT_MIN_STEPS`] steps, and more, up to
/// `triangle.light_steps`, while some emitter's averaged emission is known to worse than
/// `triangle.light_precision` ([`light_relative_se`]): a lamp that no photo sees scatters by a quarter of its
/// value per step on the house, a seen one by under 1 %. A later cycle's averaged light is pooled with the
/// light it started from where the two agree ([`pool_cycles`]). Gated: after the first cycle's steps the averaged
/// light is tested against the light it started from ([`light_change_p`] at [`LIGHT_SIGNIFICANCE`]); without a
/// significant change the cycle is undone (emission and materials as the round's fit left them) and the rest
/// skipped: `Ok(None)`. After each cycle's ratio pass the re-solved state must fit the photos no worse than the
/// round's fit ([`fits_worse`]), else it is undone likewise. Returns the last pass's [`Fitted`] (losses of all
/// passes); without emitters, or with `fit_steps` or `light_steps` = 0, nothing to do: `Ok(None)`.
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
    let max_steps = inputs.settings.light_steps;
    if emitters.is_empty() || inputs.settings.fit_steps == 0 || max_steps == 0 {
        return Ok(None);
    }
    let min_steps = LIGHT_MIN_STEPS.min(max_steps);
    let free = super::fitted_triangles(&state.face_object, &state.emission, inputs.constrained);
    let objects = state.emission.len();
    let strata = object_strata(samples, &state.face_object, objects);
    let scaled = scaled_objects(&state.face_object, &free, objects);
    let mut work = tracer::TraceStats::default();
    let start = state.emission.clone();
    let kept_materials = state.materials.clone();
    let from: Vec<[f32; 3]> = emitters.iter().map(|&o| start[o].to_array()).collect();
    let mut fitted: Option<Fitted> = None;
    // Joint steps taken per cycle.
    let mut taken: Vec<u32> = Vec::new();
    // Per emitter, the light the cycles have settled on so far (as the state holds it) and its relative
    // variance per channel.
    let mut settled: Vec<(DVec3, DVec3)> = Vec::new();
    for cycle in 0..LIGHT_CYCLES {
        let base: Vec<Vec3> = state.materials.iter().map(|m| m.base_color).collect();
        let mut cumulative = vec![DVec3::ONE; objects];
        // Per averaged step, every object's cumulative albedo scale.
        let mut scale_steps: Vec<Vec<DVec3>> = Vec::new();
        let mut n = 0.0;
        // Per averaged step, the emitters' emission (in `emitters` order).
        let mut averaged: Vec<Vec<DVec3>> = Vec::new();
        progress.phase(&format!("round {round}: light cycle {}, step", cycle + 1), u64::from(max_steps), 0);
        let mut steps = 0;
        for i in 0..max_steps {
            crate::progress::check_stop(progress)?;
            // Keyed by the step's place in the budget, so a cycle's draws do not depend on where the previous
            // one stopped.
            let pass = cycle * max_steps + i + 1;
            let scale = solve_light(inputs, scene, samples, &strata, state, &emitters, &free, round, pass, &mut work)?;
            progress.set_position(i as u64 + 1);
            steps = i + 1;
            for (c, s) in cumulative.iter_mut().zip(&scale) {
                *c *= *s;
            }
            if i >= LIGHT_BURN_IN.min(max_steps - 1) {
                scale_steps.push(cumulative.clone());
                averaged.push(emitters.iter().map(|&o| state.emission[o].as_dvec3()).collect());
                n += 1.0;
            }
            if steps >= min_steps && light_relative_se(&averaged) <= inputs.settings.light_precision {
                break;
            }
        }
        taken.push(steps);
        tracing::debug!(round, cycle, steps, se = light_relative_se(&averaged), "triangle light cycle steps");
        // The averaged light, per emitter.
        let mut mean_e: Vec<DVec3> =
            (0..emitters.len()).map(|j| averaged.iter().map(|a| a[j]).sum::<DVec3>() / n).collect();
        if cycle == 0 {
            // The gate: the object stage's light stays unless the first cycle moved it significantly beyond
            // its own Monte Carlo scatter. A uniform scene's per-triangle model is its per-object model, whose
            // light the object stage already fitted jointly with the albedos; re-solving it only adds noise
            // that every albedo then follows. Not significant: the cycle is undone (emission and materials as
            // the round's fit left them) and the rest of the re-solve (a second cycle, two ratio passes) is
            // skipped.
            let start_e: Vec<DVec3> = emitters.iter().map(|&o| start[o].as_dvec3()).collect();
            let p = light_change_p(&start_e, &averaged);
            let proposed: Vec<[f32; 3]> = mean_e.iter().map(|e| e.as_vec3().to_array()).collect();
            tracing::debug!(round, p, ?proposed, "triangle light change test");
            if p > LIGHT_SIGNIFICANCE {
                state.emission.clone_from(&start);
                state.materials.clone_from(&kept_materials);
                tracing::info!(round, p, kept = ?from, ?proposed, "triangle light kept");
                progress.note(&format!(
                    "[triangle] round {round}: light kept at {from:?} (proposed {proposed:?} after {steps} joint steps: \
                     p = {p:.3} > {LIGHT_SIGNIFICANCE}, no significant change)"
                ));
                bound_discards(round, work.discarded, work.paths)?;
                return Ok(None);
            }
            tracing::info!(round, p, ?proposed, "triangle light change significant");
            progress.note(&format!(
                "[triangle] round {round}: light change significant (p = {p:.2e}), proposed {proposed:?} after {steps} \
                 joint steps"
            ));
        }
        let rel_var = if cycle == 0 {
            cycle_rel_var(&averaged, emitters.len())
        } else {
            let (prev, prev_var): (Vec<DVec3>, Vec<DVec3>) = settled.iter().copied().unzip();
            let pooled = pool_cycles(&prev, &prev_var, &averaged);
            tracing::debug!(round, cycle, cycle_mean = ?mean_e, ?pooled, "triangle light cycles pooled");
            let (light, rel_var): (Vec<DVec3>, Vec<DVec3>) = pooled.into_iter().unzip();
            mean_e = light;
            rel_var
        };
        for (&o, e) in emitters.iter().zip(&mean_e) {
            state.emission[o] = e.as_vec3();
        }
        settled = emitters.iter().zip(rel_var).map(|(&o, v)| (state.emission[o].as_dvec3(), v)).collect();
        let shrunk = shrink_scales(&scale_steps, &scaled);
        tracing::debug!(round, cycle, scales = ?scale_diagnostics(&scale_steps, &shrunk), "triangle light scales");
        for (t, m) in state.materials.iter_mut().enumerate() {
            if free[t] {
                let s = shrunk[state.face_object[t] as usize];
                m.base_color = (base[t].as_dvec3() * s).as_vec3().clamp(Vec3::ZERO, Vec3::ONE);
            }
        }
        let mut f = fit_pass(inputs, scene, samples, state, round, cycle + 1, progress)?;
        if let Some(prev) = fitted.take() {
            f.loss.splice(0..0, prev.loss);
            f.traced_paths += prev.traced_paths;
            f.discarded_samples += prev.discarded_samples;
        }
        fitted = Some(f);
        // The re-solved light and the albedos that followed it must fit the photos no worse than the round's
        // fit did: both are rendered on a sample of the round's pixels with the same random numbers and
        // compared pixel by pixel (paired t of the L1 differences, the object stage's step-check level). On
        // Modern Hall a re-solve passed the change gate and took an emitter seen in a few pixels from 0.06 to
        // 7377 (the round's loss 0.167 → 0.482). Checked after every cycle's ratio pass, not only the last: a
        // re-solve that fits worse after its first pass is refused there, which on a house saves the second
        // cycle (docs/optim/design-measurements.md, "The light re-solve's pixels at house scale").
        let to: Vec<[f32; 3]> = emitters.iter().map(|&o| state.emission[o].to_array()).collect();
        let (t, before, after) = fit_change(inputs, scene, samples, &kept_materials, &start, state, round, &mut work)?;
        if fits_worse(t, before, after) {
            state.emission.clone_from(&start);
            state.materials.clone_from(&kept_materials);
            tracing::info!(round, cycle, t, before, after, ?from, ?to, "triangle light re-solve refused");
            progress.note(&format!(
                "[triangle] round {round}: re-solved light {to:?} refused after cycle {} of {LIGHT_CYCLES}: it fits \
                 the photos worse (mean L1 {before:.4} → {after:.4}, paired t = {t:.1}); the light stays {from:?}",
                cycle + 1
            ));
            bound_discards(round, work.discarded, work.paths)?;
            return Ok(None);
        }
    }
    let Some(mut fitted) = fitted else { return Ok(None) };
    let to: Vec<[f32; 3]> = emitters.iter().map(|&o| state.emission[o].to_array()).collect();
    tracing::info!(round, ?from, ?to, "triangle light re-solved");
    progress.note(&format!("[triangle] round {round}: light {from:?} → {to:?} ({taken:?} joint steps per cycle)"));
    fitted.traced_paths += work.paths;
    fitted.discarded_samples += work.discarded;
    bound_discards(round, fitted.discarded_samples, fitted.traced_paths)?;
    Ok(Some(fitted))
}

/// Floor of a scale's per-step standard deviation in [`shrink_scales`] (0.1 %): a scale held at its bound in all
/// but one step would otherwise weigh millions of times a wall's in the common scale. Far below any solve's
/// Monte Carlo scatter (a seen lamp's averaged steps scatter by ~1 % each, an object's scale by more).
const MIN_SCALE_STEP_SD: f64 = 1e-3;

/// Per object, the albedo scale a cycle applies: the mean of its averaged steps' cumulative scales
/// (`steps[i][o]`), shrunk toward the scale common to all objects by empirical Bayes, channel by channel
/// ([`shrink_channel`]). Each object's mean s̄_o has the sampling variance v_o = Var(steps)/n (the averaged
/// steps scatter by their Monte Carlo noise once converged, as the light's do); the common scale m is the
/// inverse-variance weighted mean of the `scaled` objects' means (the light's move, which every albedo answers
/// with its inverse), and the objects' spread of true scales about it is τ² by the DerSimonian–Laird method of
/// moments. Each object gets m + τ²/(τ² + v_o)·(s̄_o − m): a wall seen in thousands of the solves' rows keeps
/// its own mean, an object seen in a few pixels, whose column rests on repeated draws of those few rows and
/// whose steps scatter by tens of percent, follows the common scale instead of its noise. Objects that are
/// not `scaled`, and channels whose averaged steps never moved, take no part in the common scale; of those, a
/// channel still at 1 (no rows, or a base colour of 0 in that channel) keeps it, and one that moved during the
/// burn-in and then froze (its column out of reach of the averaged steps' rows, or its albedo held at 1) takes
/// the common scale: its burn-in move is not averaged evidence. Without the latter rule an object no photo
/// sees froze at (0.5, 1.87, 0.5) on the house and kept it. The steps of a noisy object are
/// positively correlated (lag-1 0.3–0.7 on the house, against a median of −0.01 over all objects), so its v_o
/// is underestimated and the shrinkage errs toward keeping its own mean (measured:
/// docs/optim/design-measurements.md, "Albedo scales shrunk toward the common scale").
#[must_use]
pub fn shrink_scales(steps: &[Vec<DVec3>], scaled: &[bool]) -> Vec<DVec3> {
    if steps.is_empty() {
        return vec![DVec3::ONE; scaled.len()];
    }
    let channels: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            let columns: Vec<Vec<f64>> = (0..scaled.len()).map(|o| steps.iter().map(|s| s[o][c]).collect()).collect();
            shrink_channel(&columns, scaled)
        })
        .collect();
    (0..scaled.len()).map(|o| DVec3::new(channels[0][o], channels[1][o], channels[2][o])).collect()
}

/// One channel of [`shrink_scales`]: `columns[o][i]` is object o's cumulative scale at averaged step i.
fn shrink_channel(columns: &[Vec<f64>], scaled: &[bool]) -> Vec<f64> {
    let objects = scaled.len();
    let moved: Vec<bool> = columns.iter().map(|col| col.iter().any(|&v| v != col[0])).collect();
    // Mean and variance of the mean; a scale that never moved is its value, exactly (a sum of n equal values
    // divided by n need not be), and takes no part (`None`), nor does an object that is not scaled.
    let (mean, var): (Vec<f64>, Vec<Option<f64>>) = columns
        .iter()
        .enumerate()
        .map(|(o, col)| {
            if !moved[o] {
                return (col[0], None);
            }
            let (m, se) = mean_se(col);
            let floor = MIN_SCALE_STEP_SD * MIN_SCALE_STEP_SD / col.len() as f64;
            (m, scaled[o].then(|| (se * se).max(floor)))
        })
        .unzip();
    let members: Vec<(usize, f64)> = var.iter().enumerate().filter_map(|(o, v)| v.map(|v| (o, 1.0 / v))).collect();
    let k = members.len();
    if k < 2 {
        return mean;
    }
    let sw: f64 = members.iter().map(|&(_, w)| w).sum();
    let sw2: f64 = members.iter().map(|&(_, w)| w * w).sum();
    let common = members.iter().map(|&(o, w)| w * mean[o]).sum::<f64>() / sw;
    let q: f64 = members.iter().map(|&(o, w)| w * (mean[o] - common).powi(2)).sum();
    // DerSimonian–Laird: E[Q] = (k − 1) + τ²·(Σw − Σw²/Σw).
    let tau2 = ((q - (k - 1) as f64) / (sw - sw2 / sw)).max(0.0);
    (0..objects)
        .map(|o| match var[o] {
            Some(v) => common + tau2 / (tau2 + v).max(f64::MIN_POSITIVE) * (mean[o] - common),
            // Moved during the burn-in, then frozen (a column that no averaged step's rows reach, or an albedo
            // held at 1): the averaged steps say nothing of its noise, so the common scale.
            None if scaled[o] && mean[o] != 1.0 => common,
            None => mean[o],
        })
        .collect()
}

/// One object's line in the debug log of a cycle's scales: the object, its steps' plain mean, the standard
/// error of that mean, the applied scale and the lag-1 autocorrelation of its steps (RGB each).
type ScaleDiagnostic = (usize, [f32; 3], [f32; 3], [f32; 3], [f32; 3]);

/// Per object with moving scales, its [`ScaleDiagnostic`].
fn scale_diagnostics(steps: &[Vec<DVec3>], shrunk: &[DVec3]) -> Vec<ScaleDiagnostic> {
    let n = steps.len();
    if n < 3 {
        return Vec::new();
    }
    let nf = n as f64;
    (0..shrunk.len())
        .filter_map(|o| {
            let mean = steps.iter().map(|s| s[o]).sum::<DVec3>() / nf;
            let dev: Vec<DVec3> = steps.iter().map(|s| s[o] - mean).collect();
            let ss = dev.iter().map(|d| *d * *d).sum::<DVec3>();
            if ss.max_element() <= 0.0 {
                return None;
            }
            let lag1 = dev.windows(2).map(|w| w[0] * w[1]).sum::<DVec3>() / ss.max(DVec3::splat(f64::MIN_POSITIVE));
            let se = (ss / (nf - 1.0) / nf).map(f64::sqrt);
            Some((
                o,
                mean.as_vec3().to_array(),
                se.as_vec3().to_array(),
                shrunk[o].as_vec3().to_array(),
                lag1.as_vec3().to_array(),
            ))
        })
        .collect()
}

/// Whether a light re-solve fits the photos worse than the round's fit, from `fit_change`'s paired t and mean
/// L1 before and after: significantly worse (t above the object stage's step-check level), or with a mean L1
/// more than [`MAX_LOSS_GROWTH`] times the start's, significant or not.
#[must_use]
fn fits_worse(t: f64, before: f64, after: f64) -> bool {
    t > crate::fit::step_check::WORSE_T || after > MAX_LOSS_GROWTH * before
}

/// A re-solve whose mean L1 over the check's pixels grows beyond this factor is refused whatever its t. The
/// paired t of a change confined to k pixels grows only as √k, however large the change: on Modern Hall a
/// re-solve took a lamp seen in a few pixels to 255 414 and raised the mean L1 from 0.105 to 13.3 at t = 2.2,
/// refused by a hair. A change that is noise moves the mean by the check's Monte Carlo scatter, which common
/// random numbers keep to a few percent over tens of thousands of pixels (every re-solve measured on the
/// corpus moved it by 1–4 %, `docs/optim/design-measurements.md`, "The light-change gate on the corpus").
pub const MAX_LOSS_GROWTH: f64 = 1.5;

/// Pixels of the check after a light re-solve: a uniform sample of the round's pixels, enough for a paired t
/// of a 1 % change (the per-pixel L1 differences scatter by ~10–30 % of their mean on the corpus scenes).
const CHECK_PIXELS: usize = 65_536;

/// Paired t of (L1 after − L1 before) per pixel, the mean L1 before and after, for the state before the light
/// re-solve (`materials`, `emission`) and `state`, rendered on up to [`CHECK_PIXELS`] of `samples` with the
/// same random numbers.
#[allow(clippy::too_many_arguments)]
fn fit_change(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    materials: &[tracer::Material],
    emission: &[Vec3],
    state: &TriangleState,
    round: u32,
    work: &mut tracer::TraceStats,
) -> Result<(f64, f64, f64), TriangleError> {
    let cfg = inputs.settings;
    let chosen: Vec<&TriSample> = if samples.len() <= CHECK_PIXELS {
        samples.iter().collect()
    } else {
        let bar = CHECK_PIXELS as f64 / samples.len() as f64;
        samples
            .iter()
            .filter(|s| {
                uniform(cfg.seed, draw::TRIANGLE_LIGHT_CHECK, crate::streams::pixel_key(s.pixel), u64::from(round))
                    < bar
            })
            .collect()
    };
    let pix: Vec<PixelRef> = chosen.iter().map(|s| s.pixel).collect();
    let k = key::triangle(round, key::TRIANGLE_LIGHT_CHECK);
    let mut render = |params: &tracer::Params| -> Result<Vec<Vec3>, TriangleError> {
        let (v, stats) = tracer::Renderer::new(scene, params, inputs.tracer)?.render_pixels(
            inputs.cameras,
            &pix,
            cfg.spp,
            cfg.seed,
            k,
        )?;
        work.add(&stats);
        Ok(v)
    };
    let before = render(&tracer::Params {
        materials: materials.to_vec(),
        emission: emission.to_vec(),
        horizon: state.horizon.clone(),
    })?;
    let after = render(&state.params())?;
    let l1 = |s: &TriSample, v: &Vec3| f64::from((s.target - *v).abs().element_sum()) / 3.0;
    let d: Vec<f64> = chosen.iter().zip(before.iter().zip(&after)).map(|(s, (b, a))| l1(s, a) - l1(s, b)).collect();
    let n = chosen.len().max(1) as f64;
    let mean_before = chosen.iter().zip(&before).map(|(s, b)| l1(s, b)).sum::<f64>() / n;
    let mean_after = chosen.iter().zip(&after).map(|(s, a)| l1(s, a)).sum::<f64>() / n;
    Ok((crate::fit::linear::paired_t(&d).1, mean_before, mean_after))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_constrained_objects_with_a_fitted_triangle_have_a_scale() {
        // Objects 0–3: fitted and constrained; fitted but unconstrained; an emitter (no fitted triangle);
        // fitted, and beyond the `constrained` slice (counts as constrained).
        let face_object = [0, 0, 1, 2, 3];
        let emission = [Vec3::ZERO, Vec3::ZERO, Vec3::ONE, Vec3::ZERO];
        let constrained = [true, false, true];
        let free = crate::triangle::fitted_triangles(&face_object, &emission, &constrained);
        assert_eq!(free, vec![true, true, false, false, true]);
        assert_eq!(scaled_objects(&face_object, &free, 4), vec![true, false, false, true]);
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
            rng = crate::streams::mix64(rng);
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
            support: crate::fit::emission_solve::Support::Current,
            loss: DataLoss::L2,
            emission_l1: 0.0,
            damping: LIGHT_DAMPING,
            irls_iters: 1,
            basis_rows: usize::MAX,
        };
        let cols = |x: &'_ [Vec<[f64; 3]>], y: &'_ [Vec<[f64; 3]>]| (x.to_vec(), y.to_vec());
        let (ea, eb) = cols(&[ja], &[ja2]);
        let (sa, sb) = cols(&[jb], &[jb2]);
        solve_on_columns(
            Columns { a: &ea, b: &eb },
            Columns { a: &sa, b: &sb },
            &targets,
            &[],
            &[],
            &mut e,
            &[],
            &mut scale,
            &[],
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

    /// Standard normal draws (Box–Muller on the seeded [`crate::streams::mix64`] stream).
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let mut rng = seed;
        let mut u = || {
            rng = crate::streams::mix64(rng);
            ((rng >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * u().ln()).sqrt() * (2.0 * std::f64::consts::PI * u()).cos()).collect()
    }

    #[test]
    fn noisy_albedo_scales_follow_the_common_scale_and_well_measured_ones_keep_their_own() {
        // 40 walls whose true scales spread about 0.9 (the light rose by ~11 %) by ±0.05, measured by 16 steps
        // of 1 % scatter; one object seen in a few pixels, true scale 0.9, whose steps scatter by 40 %; one
        // emitter (not scaled) and one object whose steps never move from 1.
        let n = 16;
        let mut draws = normals(0x0bad_5eed, 64 * n).into_iter();
        let mut gauss = || draws.next().unwrap_or(0.0);
        let walls = 40;
        let truth: Vec<f64> = (0..walls).map(|i| 0.9 + 0.05 * ((i % 5) as f64 - 2.0) / 2.0).collect();
        let (noisy, emitter, still) = (walls, walls + 1, walls + 2);
        let steps: Vec<Vec<DVec3>> = (0..n)
            .map(|_| {
                let mut s: Vec<DVec3> = truth.iter().map(|&t| DVec3::splat(t * (1.0 + 0.01 * gauss()))).collect();
                s.push(DVec3::splat(0.9 * (1.0 + 0.4 * gauss())));
                s.push(DVec3::ONE);
                s.push(DVec3::ONE);
                s
            })
            .collect();
        let mut scaled = vec![true; walls + 3];
        scaled[emitter] = false;
        let out = shrink_scales(&steps, &scaled);
        let plain = |o: usize| steps.iter().map(|s| s[o].x).sum::<f64>() / n as f64;
        for (o, &t) in truth.iter().enumerate() {
            // Each wall's mean is known to 1 %/√16 = 0.25 %, far inside the walls' spread: kept.
            assert!((out[o].x - plain(o)).abs() < 0.002, "wall {o}: {} against its mean {}", out[o].x, plain(o));
            assert!((out[o].x - t).abs() < 0.01, "wall {o}: {} against {t}", out[o].x);
        }
        // The noisy object's mean is known to 0.9·40 %/4 = 9 %, twice the walls' spread: pulled most of the way
        // to the common scale (≈ 0.9).
        let common = out[..walls].iter().map(|s| s.x).sum::<f64>() / walls as f64;
        let keep = (out[noisy].x - common) / (plain(noisy) - common);
        assert!(
            (0.0..0.35).contains(&keep),
            "noisy object {} from its mean {} (kept {keep})",
            out[noisy].x,
            plain(noisy)
        );
        // Not scaled, or never moved from 1: kept.
        assert_eq!(out[emitter], DVec3::ONE);
        assert_eq!(out[still], DVec3::ONE);
        // A channel that never moves (an object whose blue base colour is 0 has a zero column there) keeps its
        // value and does not pull that channel's common scale to it: the noisy object's blue still goes to the
        // walls' 0.9, not to the dead channel's 1.
        let dead = walls + 3;
        let with_dead: Vec<Vec<DVec3>> = steps
            .iter()
            .map(|s| {
                let mut s = s.clone();
                s.push(DVec3::new(0.9 * (1.0 + 0.01 * gauss()), 0.9 * (1.0 + 0.01 * gauss()), 1.0));
                s
            })
            .collect();
        let mut scaled_dead = scaled.clone();
        scaled_dead.push(true);
        let out_dead = shrink_scales(&with_dead, &scaled_dead);
        assert_eq!(out_dead[dead].z, 1.0);
        // A channel that moved during the burn-in and then froze at 1.87 takes the common scale.
        let frozen: Vec<Vec<DVec3>> = with_dead
            .iter()
            .map(|s| {
                let mut s = s.clone();
                s.push(DVec3::new(0.9 * (1.0 + 0.01 * gauss()), 1.87, 0.9 * (1.0 + 0.01 * gauss())));
                s
            })
            .collect();
        let mut scaled_frozen = scaled_dead.clone();
        scaled_frozen.push(true);
        let out_frozen = shrink_scales(&frozen, &scaled_frozen);
        assert!((out_frozen[dead + 1].y - 0.9).abs() < 0.01, "{}", out_frozen[dead + 1].y);
        assert!((out_dead[noisy].z - out[noisy].z).abs() < 1e-3, "{} against {}", out_dead[noisy].z, out[noisy].z);
        // Without any spread between the objects, every noisy mean goes to the common scale.
        let flat: Vec<Vec<DVec3>> = (0..n)
            .map(|_| (0..10).map(|o| DVec3::splat(1.1 * (1.0 + if o == 0 { 0.3 } else { 0.01 } * gauss()))).collect())
            .collect();
        let out = shrink_scales(&flat, &[true; 10]);
        assert!((out[0].x - out[1].x).abs() < 0.01, "{out:?}");
        assert!((out[0].x - 1.1).abs() < 0.01, "{out:?}");
    }

    #[test]
    fn the_light_change_test_holds_its_level_and_sees_a_light_off_by_its_scatter_times_a_few() {
        // Null: n steps scatter independently by 1.5 % (the measured per-step scatter of a seen lamp) about the
        // start light, n = 4 (the fewest a cycle averages) and 16 (a cycle at the default budget). Over 4000
        // seeded trials the rejection rate at 1 % must stay at most the level (Bonferroni over the channels is
        // conservative) up to its binomial noise (4 standard deviations of 0.01·4000: ±25).
        let start = vec![DVec3::new(20.0, 18.0, 15.0)];
        let trials = 4000;
        for n in [4, 16] {
            let z = normals(0x5eed + n as u64, trials * n * 3);
            let mut rejected = 0;
            let mut shifted_rejected = 0;
            for i in 0..trials {
                let steps = |shift: f64| -> Vec<Vec<DVec3>> {
                    (0..n)
                        .map(|j| {
                            let k = 3 * (n * i + j);
                            vec![start[0] * (1.0 + shift) * (DVec3::ONE + 0.015 * DVec3::new(z[k], z[k + 1], z[k + 2]))]
                        })
                        .collect()
                };
                rejected += usize::from(light_change_p(&start, &steps(0.0)) <= LIGHT_SIGNIFICANCE);
                // A light 6 % off (the checker's object stage): 8 standard errors of the 4-step mean (0.75 %).
                shifted_rejected += usize::from(light_change_p(&start, &steps(-0.06)) <= LIGHT_SIGNIFICANCE);
            }
            eprintln!(
                "{n} steps, rejected at {LIGHT_SIGNIFICANCE}: null {rejected}, 6 % shift {shifted_rejected} of {trials}"
            );
            assert!(rejected <= 40 + 25, "{n} steps: null rejected {rejected} of {trials}");
            // Power: t(9) beyond the Bonferroni threshold (|t| ≈ 3.7) at a mean of 8 is all but certain.
            assert!(
                shifted_rejected as f64 >= 0.99 * trials as f64,
                "{n} steps: 6 % shift seen {shifted_rejected} of {trials}"
            );
        }
        // Degenerate inputs: no steps, one step, no emitters → no evidence.
        assert_eq!(light_change_p(&start, &[]), 1.0);
        assert_eq!(light_change_p(&start, std::slice::from_ref(&start)), 1.0);
        assert_eq!(light_change_p(&[], &[vec![], vec![]]), 1.0);
    }

    #[test]
    fn a_cycles_precision_is_its_least_known_emitters_standard_error() {
        // Emitter 0 scatters by 1 % per step, emitter 1 (unseen, dark in blue) by 20 %; 16 steps: standard
        // errors 0.25 % and 5 %, the cycle knows its light to the larger. Relative scatter, so the scale of
        // the emission does not matter; a channel at 0 is left out of the pooling.
        let n = 16;
        let z = normals(0xface, n * 6);
        let steps: Vec<Vec<DVec3>> = (0..n)
            .map(|j| {
                let k = 6 * j;
                vec![
                    DVec3::new(20.0, 18.0, 15.0) * (DVec3::ONE + 0.01 * DVec3::new(z[k], z[k + 1], z[k + 2])),
                    DVec3::new(3.0, 2.0, 0.0) * (DVec3::ONE + 0.2 * DVec3::new(z[k + 3], z[k + 4], z[k + 5])),
                ]
            })
            .collect();
        let se = light_relative_se(&steps);
        // The pooled estimate of 0.2/4 from 30 degrees of freedom: within ±35 % (about 3 of its standard errors).
        assert!((se / 0.05 - 1.0).abs() < 0.35, "{se}");
        let seen: Vec<Vec<DVec3>> = steps.iter().map(|s| vec![s[0]]).collect();
        let se_seen = light_relative_se(&seen);
        assert!((se_seen / 0.0025 - 1.0).abs() < 0.35, "{se_seen}");
        // Fewer than 2 steps: nothing is known yet.
        assert_eq!(light_relative_se(&steps[..1]), f64::INFINITY);
        assert_eq!(light_relative_se(&[]), f64::INFINITY);
    }

    #[test]
    fn cycles_that_agree_are_pooled_and_a_light_that_moved_takes_the_new_cycle() {
        // An unseen lamp: 16 averaged steps per cycle, each scattering by 25 % of the truth (the house's unseen
        // lamps, 24–49 %), so each cycle's mean is known to about 6 %. Over 2000 seeded trials of two cycles
        // about the same light, the pooled light's mean squared relative error must be near half the second
        // cycle's alone (inverse-variance weights of two equal variances; the pretest costs a little), and a
        // light that moved by 40 % (about 5 joint standard errors) must take the second cycle's mean.
        let truth = DVec3::new(20.0, 15.0, 9.0);
        let (n, trials) = (16, 2000);
        let z = normals(0xc0ff, trials * 2 * n * 3);
        let cycle = |i: usize, c: usize, light: DVec3| -> Vec<Vec<DVec3>> {
            (0..n)
                .map(|j| {
                    let k = 3 * ((2 * i + c) * n + j);
                    vec![light * (DVec3::ONE + 0.25 * DVec3::new(z[k], z[k + 1], z[k + 2]))]
                })
                .collect()
        };
        let mean = |steps: &[Vec<DVec3>]| steps.iter().map(|s| s[0]).sum::<DVec3>() / n as f64;
        let rel_err2 = |e: DVec3, t: DVec3| ((e - t) / t).length_squared();
        let (mut pooled_err, mut second_err, mut moved_taken) = (0.0, 0.0, 0);
        for i in 0..trials {
            let first = cycle(i, 0, truth);
            let prev = vec![mean(&first)];
            let prev_var = cycle_rel_var(&first, 1);
            let second = cycle(i, 1, truth);
            let second_mean = mean(&second);
            let (light, var) = pool_cycles(&prev, &prev_var, &second)[0];
            pooled_err += rel_err2(light, truth);
            second_err += rel_err2(second_mean, truth);
            // Where pooled, the light is known better than by either cycle alone (absolute variances).
            let second_var = cycle_rel_var(&second, 1)[0];
            for c in (0..3).filter(|&c| light[c] != second_mean[c]) {
                let v = var[c] * light[c] * light[c];
                assert!(v < prev_var[0][c] * prev[0][c] * prev[0][c], "{c}: {var}");
                assert!(v < second_var[c] * second_mean[c] * second_mean[c], "{c}: {var}");
            }
            let moved = cycle(i, 1, truth * 1.4);
            let moved_mean = mean(&moved);
            let (light, _) = pool_cycles(&prev, &prev_var, &moved)[0];
            moved_taken += usize::from((0..3).filter(|&c| light[c] == moved_mean[c]).count() >= 2);
        }
        let ratio = pooled_err / second_err;
        eprintln!("pooled / second cycle's mean squared error {ratio:.3}; moved light taken {moved_taken} of {trials}");
        assert!(ratio < 0.65, "pooling gained too little: {ratio}");
        assert!(moved_taken as f64 >= 0.9 * trials as f64, "a moved light taken in {moved_taken} of {trials}");
        // A previous light whose variance is unknown (infinite), or a channel at 0, takes the cycle's mean.
        let steps = cycle(0, 1, truth);
        assert_eq!(pool_cycles(&[truth], &[DVec3::INFINITY], &steps)[0].0, mean(&steps));
        let (light, _) = pool_cycles(&[DVec3::new(20.0, 15.0, 0.0)], &[DVec3::splat(0.004)], &steps)[0];
        assert_eq!(light.z, mean(&steps).z);
        // No steps: everything as it was.
        assert_eq!(pool_cycles(&[truth], &[DVec3::splat(0.01)], &[]), vec![(truth, DVec3::splat(0.01))]);
    }

    #[test]
    fn a_re_solve_is_refused_when_significantly_worse_or_far_worse_on_average() {
        // Better, or worse by noise: kept.
        assert!(!fits_worse(-3.0, 0.10, 0.09));
        assert!(!fits_worse(1.0, 0.10, 0.101));
        // Significantly worse.
        assert!(fits_worse(7.3, 0.0575, 0.0582));
        // A lamp blown up in a few pixels: t small, the mean L1 127 times the start's.
        assert!(fits_worse(2.2 - 0.5, 0.105, 13.3));
        // Half again as bad is the bound.
        assert!(!fits_worse(0.0, 0.1, 0.149));
        assert!(fits_worse(0.0, 0.1, 0.151));
    }

    #[test]
    fn the_light_solve_draws_every_object_its_floor_of_pixels() {
        // A large wall (object 0, 100 000 pixels on triangles 0–1) and a lamp seen in 40 pixels (object 1,
        // triangle 2), and 300 pixels of a box (object 2, triangle 3): a uniform draw of 1024 would give the lamp
        // 0.4 rows on average; each object gets its SOLVE_FLOOR, and the weights keep the mean unbiased.
        let face_object = [0u32, 0, 1, 2];
        let sample = |i: u32, tri: u32| TriSample {
            pixel: PixelRef { view: 0, x: i, y: 0 },
            target: Vec3::ONE,
            tri,
            child: 0,
            interior: true,
            on_object: true,
            bary: glam::Vec2::ZERO,
        };
        let samples: Vec<TriSample> = (0..100_000)
            .map(|i| sample(i, i % 2))
            .chain((0..40).map(|i| sample(200_000 + i, 2)))
            .chain((0..300).map(|i| sample(300_000 + i, 3)))
            .collect();
        let strata = object_strata(&samples, &face_object, 3);
        let (rows, weights) = draw_strata_rows(&strata, 1024, SOLVE_FLOOR, 7, draw::TRIANGLE_EMISSION_PIXELS, 1);
        let per_object = |o: u32| rows.iter().filter(|&&j| face_object[samples[j].tri as usize] == o).count();
        assert!(per_object(1) >= SOLVE_FLOOR && per_object(2) >= SOLVE_FLOOR, "{} {}", per_object(1), per_object(2));
        assert_eq!(rows.len(), 1024);
        // The weighted share of each object's rows is its share of the pixels.
        let share = |o: u32| {
            rows.iter()
                .zip(&weights)
                .filter(|(j, _)| face_object[samples[**j].tri as usize] == o)
                .map(|(_, w)| w)
                .sum::<f64>()
                / rows.len() as f64
        };
        let n = samples.len() as f64;
        for (o, count) in [(0, 100_000.0), (1, 40.0), (2, 300.0)] {
            assert!((share(o) - count / n).abs() < 1e-12, "object {o}: {} against {}", share(o), count / n);
        }
    }
}
