//! One round's closed-form fit of the per-triangle base colours on a fixed mesh: ratio steps (each
//! triangle's value times photo sum over render sum, a Jacobi iteration towards T = R per triangle), shrunk
//! towards the object's value where the evidence does not call for a difference (empirical Bayes), combined
//! with the smoothness regulariser; optionally followed by Adam ([`super::adam`]). See the module docs of
//! [`crate::triangle`].

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use tracer::PixelRef;

use super::pixels::TriSample;
use super::{RoundInputs, TriangleError, TriangleSettings, TriangleState};
use crate::streams::key;

/// A triangle's closed-form update uses only its interior pixels (footprint wholly on it) when it has at least
/// this many: they depend on its own value alone. With fewer (small or grazing triangles) all its pixels are
/// used; the Jacobi iteration then settles the pixels shared with neighbours.
const MIN_INTERIOR: usize = 4;

/// Gauss–Seidel sweeps of the smoothness solve. Observed triangles settle in a few sweeps (their data weight
/// dominates); 64 sweeps carry a neighbour's value across ~8 unobserved triangles, beyond which a region keeps
/// the object's value it was given before the sweeps ([`fill_unobserved`]) — the intended fallback.
const SMOOTH_SWEEPS: usize = 64;

/// What a round's fit leaves for the split test.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted {
    /// Mean per-channel |photo − render| over the fitted pixels, per step (before its update).
    pub loss: Vec<f64>,
    /// Per sample: photo − predicted render after the last update.
    pub residual: Vec<Vec3>,
    /// Per triangle: its parameters were fitted (its object does not emit and is constrained).
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
    // The free triangles in index order, listed once: the lobe family look frees one object of a house's 10⁵
    // triangles per fit.
    let order: Vec<usize> = (0..rho.len()).filter(|&t| free[t]).collect();
    for _ in 0..SMOOTH_SWEEPS {
        for &t in &order {
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

/// The smallest fraction of a ratio step an object takes after its steps alternate in sign.
const MIN_RELAX: f64 = 1.0 / 16.0;

/// The smallest base colour channel a free triangle is rendered with in a ratio step. The step ρ·T/R is
/// multiplicative, so a channel at exactly 0 (an object stage that fitted a channel to its lower bound) stays 0
/// whatever its photos say, and the object's pooled value leaves such triangles out ([`Pooled`]): on the
/// corpus house a diffuse box of truth 0.16 / 0.28 / 0.20 came from the object stage at 0.00 / 0.009 / 0.25 and
/// ended the stage with its red at 0 (docs/optim/design-measurements.md, "A base colour channel at 0"). Lifted to
/// this floor, the channel's render carries its own diffuse share, and where that share dominates (R ≈ ρ·E) the
/// next step lands on the photos' value in one step (0.01 → 0.16 is a ratio of 16); a ρ-independent part of
/// the render (a specular lobe, a neighbour in a mixed pixel) slows it to a few steps. The step's result is not
/// floored, so a surface darker than the floor still ends below it: its last step starts from 0.01, which
/// bounds its error by 0.01, below the albedo noise of the stage's 32-path renders on a few-pixel triangle.
const MIN_STEP_BASE: f32 = 0.01;

/// Raises every free triangle's base colour channels to at least [`MIN_STEP_BASE`] before a ratio step renders
/// them.
fn lift_black_channels(materials: &mut [tracer::Material], free: &[bool]) {
    for (m, _) in materials.iter_mut().zip(free).filter(|(_, f)| **f) {
        m.base_color = m.base_color.max(Vec3::splat(MIN_STEP_BASE));
    }
}

/// Under-relaxes the ratio step per object where it oscillates. The ratio step ρ·T/R divides by the render
/// per unit of the triangle's *own* albedo, but when all triangles of an object move together the object's
/// light on itself moves with them: on a white hall (albedo 0.9, lit mostly by its own interreflections) the
/// step overshoots by more than its size, and the object's value alternated with growing amplitude (Modern
/// Hall's 741 m² wall: 0.94, 0.88, 0.97, 0.87, 1.02 over five steps; docs/optim/design-measurements.md, "The
/// ratio step on bright interreflecting objects"). Per object and channel, the pixel-weighted mean change of
/// its free triangles is compared with the previous step's: a reversal halves the fraction of the step taken
/// (down to [`MIN_RELAX`]), a step in the same direction raises it by half (up to the whole step), as Rprop
/// does. The fixed point (T = R on every triangle) is unchanged; an object whose steps do not reverse takes
/// them whole.
fn relax_objects(
    rho: &mut [Vec3],
    old: &[Vec3],
    count: &[f64],
    free: &[bool],
    face_object: &[u32],
    relax: &mut [DVec3],
    last_step: &mut [DVec3],
) {
    let mut change = vec![(DVec3::ZERO, 0.0f64); relax.len()];
    for t in 0..rho.len() {
        if free[t] && count[t] > 0.0 {
            let c = &mut change[face_object[t] as usize];
            c.0 += (rho[t] - old[t]).as_dvec3() * count[t];
            c.1 += count[t];
        }
    }
    for (o, (sum, n)) in change.iter().enumerate() {
        if *n <= 0.0 {
            continue;
        }
        let step = *sum / *n;
        for c in 0..3 {
            let product = step[c] * last_step[o][c];
            if product < 0.0 {
                relax[o][c] = (relax[o][c] * 0.5).max(MIN_RELAX);
            } else if product > 0.0 {
                relax[o][c] = (relax[o][c] * 1.5).min(1.0);
            }
        }
        last_step[o] = step * relax[o];
    }
    for t in 0..rho.len() {
        if free[t] {
            let w = relax[face_object[t] as usize].as_vec3();
            rho[t] = (old[t] + (rho[t] - old[t]) * w).clamp(Vec3::ZERO, Vec3::ONE);
        }
    }
}

/// Shrink every triangle's estimate towards its object's pooled value ([`shrink_to_object`]) before the
/// smoothness solve. Measured in `docs/optim/design-measurements.md`.
const SHRINK: bool = true;

/// 99.9 % quantile of χ² with 3 degrees of freedom (one per colour channel): the significance level of the
/// object-level update in [`shrink_to_object`] (a uniform object keeps its value 999 times in 1000 per step).
const CHI2_3_999: f64 = 16.266;

/// Floor of a triangle's ratio variance in the τ² estimate of [`shrink_to_object`], whose weights are 1/v_t:
/// far below any variance a Monte Carlo render and a photo's noise give (an albedo's standard error of 10⁻⁶),
/// it only keeps a triangle whose pixels happen to agree exactly from taking an infinite weight.
const MIN_VARIANCE: f64 = 1e-12;

/// One fit step's evidence per triangle, over the pixels its update uses: the current base colour, the sums of
/// photo and render values, of squared differences (photo − render)², and the pixel count; and per object,
/// the sums over the pixels that see it alone ([`Pooled`]).
#[derive(Debug, Clone, Copy)]
pub struct Evidence<'a> {
    pub old: &'a [Vec3],
    pub t_sum: &'a [DVec3],
    pub r_sum: &'a [DVec3],
    pub d_sq: &'a [DVec3],
    pub count: &'a [f64],
    /// Interior pixels (footprint wholly on the triangle) per triangle.
    pub interior: &'a [usize],
    /// Per object.
    pub pooled: &'a [Pooled],
}

/// One fit step's sums per object over its pixels that see it alone ([`super::pixels::TriSample::on_object`])
/// and lie on triangles whose base colour is positive in every channel: the object-level evidence of
/// [`shrink_to_object`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pooled {
    /// Σ photo.
    pub t: DVec3,
    /// Σ render/ρ_t: the render per unit of the base colour of the triangle the pixel's centre sees.
    pub r_per_albedo: DVec3,
    /// Σ (photo − render).
    pub d: DVec3,
    /// Σ (photo − render)².
    pub d_sq: DVec3,
    /// Pixels.
    pub n: f64,
}

impl Pooled {
    /// Adds one pixel of photo `target` and render `render` on a triangle of base colour `rho` (positive).
    pub fn add(&mut self, target: DVec3, render: DVec3, rho: DVec3) {
        let d = target - render;
        self.t += target;
        self.r_per_albedo += render / rho;
        self.d += d;
        self.d_sq += d * d;
        self.n += 1.0;
    }
}

/// Pixels an object's pooled update needs in [`shrink_to_object`] before it may move the object's value: the
/// χ² test divides by the variance of these pixels' differences, whose relative standard error is √(2/(n − 1)),
/// ±25 % at 32 pixels; with fewer the estimate of the noise is itself too noisy to judge a change by.
const MIN_POOLED: f64 = 32.0;

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

/// Per object: its current value, from which [`shrink_to_object`] shrinks and which its unobserved triangles
/// take ([`fill_unobserved`]): the object-level update m = ΣT / Σ(R/ρ) over its pooled pixels ([`Pooled`]) where
/// it differs significantly from the pixel-weighted mean of its observed triangles' values, else that mean;
/// `None` for an object none of whose free triangles has a pixel.
#[must_use]
pub fn object_values(ev: &Evidence<'_>, face_object: &[u32], free: &[bool], objects: usize) -> Vec<Option<DVec3>> {
    // The object's current value: the pixel-weighted mean of its triangles' values.
    let mut current = vec![(DVec3::ZERO, 0.0f64); objects];
    for t in 0..ev.old.len() {
        if !free[t] || ev.count[t] <= 0.0 {
            continue;
        }
        let o = &mut current[face_object[t] as usize];
        o.0 += ev.old[t].as_dvec3() * ev.count[t];
        o.1 += ev.count[t];
    }
    debug_assert_eq!(ev.pooled.len(), objects, "one pooled sum per object");
    current
        .iter()
        .zip(ev.pooled)
        .map(|(&(cur, n), p)| {
            if n <= 0.0 {
                return None;
            }
            let cur = cur / n;
            if p.n < MIN_POOLED || p.r_per_albedo.min_element() <= 0.0 {
                return Some(cur);
            }
            let m = (p.t / p.r_per_albedo).clamp(DVec3::ZERO, DVec3::ONE);
            // The object-level update is itself evidence: it moves the object's value only when significant,
            // z² = Σ_c (m − current)²/Var(m) above the 99.9 % quantile of χ²(3), 16.27 (a barely seen object,
            // e.g. a ceiling in 84 pixels mostly shared with walls, otherwise drifts on noise over the steps).
            // Var(m) = Var(ΣT − ΣR)/(Σ R/ρ)², with Var(ΣT − ΣR) = n·s² from the pixels' scatter about their mean
            // difference (on a textured object the texture adds to s², which only makes the test stricter).
            let s2 = ((p.d_sq - p.d * p.d / p.n) / (p.n - 1.0)).max(DVec3::ZERO);
            let var_m = s2 * p.n / (p.r_per_albedo * p.r_per_albedo);
            let z2 = ((m - cur) * (m - cur) / var_m.max(DVec3::splat(1e-300))).element_sum();
            Some(if z2 > CHI2_3_999 { m } else { cur })
        })
        .collect()
}

/// Sets every free triangle without a pixel of this step (`count` 0) to its object's value `mean` (where the
/// object has one), before the smoothness solve: an object seen from one side (a sphere in one photo, a
/// cabinet against a wall) has most of its surface in no photo, and the sweeps carry an observed neighbour's
/// value only a few triangles into it, so without this the unseen surface kept the object stage's value
/// whatever the observed part's fit found — the object's area-mean then mixed the two (on the corpus house a
/// sphere seen in one photo: its observed tenth 0.20 / 0.22 / 0.24 for the truth's 0.22 / 0.22 / 0.23, the
/// unseen nine tenths 0.13 / 0.10 / 0.10; docs/optim/design-measurements.md, "Unseen triangles take their
/// object's value"). The solve then blends the boundary of the unseen region into its observed neighbours.
pub fn fill_unobserved(rho: &mut [Vec3], count: &[f64], free: &[bool], face_object: &[u32], mean: &[Option<DVec3>]) {
    for (t, r) in rho.iter_mut().enumerate() {
        if free[t] && count[t] <= 0.0 {
            if let Some(m) = mean.get(face_object[t] as usize).copied().flatten() {
                *r = m.as_vec3();
            }
        }
    }
}

/// Empirical-Bayes (James–Stein) shrinkage of the per-triangle estimates `ratio` towards their object's pooled
/// value: per object and channel, the prior mean m = ΣT / Σ(R/ρ) is the object-level ratio update over all the
/// pixels that see the object alone ([`Pooled`]; one ratio of two large sums: the per-triangle ratio T_t/R_t has
/// the noise of a few dozen pixels' renders in its denominator, which biases it upwards — E\[1/R\] > 1/E\[R\] —
/// far more). Those pixels need not be interior to one triangle: a finely tessellated object (a sphere of
/// 5 120 triangles in a few hundred pixels of a 430×344 photo) has hardly a triangle with clean evidence, and
/// pooled over those alone it kept the object stage's value through every step and every light re-solve
/// (docs/optim/design-measurements.md, "Objects tessellated finer than the pixels"). The
/// estimates r_t have sampling variances v_t ([`Evidence::ratio_variance`]), and the spread of the true values
/// τ² is what the estimates scatter beyond their noise (the method of moments with weights 1/v_t, as
/// DerSimonian–Laird's, so that a triangle with a huge variance does not hide the others' spread). Each
/// estimate becomes m + τ²/(τ² + v_t)·(r_t − m): on a uniform object (scatter explained by noise, τ² ≈ 0)
/// every triangle keeps the object's value; on a textured one (τ² ≫ v_t) each keeps its own. A triangle seen
/// in a single pixel (no measurable noise) or in fewer than `MIN_INTERIOR` interior pixels (its estimate rests
/// on pixels shared with neighbours and absorbs their misfit) has no clean evidence of a difference: it takes
/// m. Unobserved triangles (given their object's value by [`fill_unobserved`], then the smoothness solve) and
/// those of emitting objects are unchanged here. Only triangles with clean evidence enter τ². `mean` is each
/// object's value from [`object_values`] (an object with fewer than [`MIN_POOLED`] pooled pixels keeps its
/// current value).
#[must_use]
pub fn shrink_to_object(
    ratio: &[Vec3],
    ev: &Evidence<'_>,
    face_object: &[u32],
    free: &[bool],
    mean: &[Option<DVec3>],
) -> Vec<Vec3> {
    let objects = mean.len();
    let var: Vec<Option<DVec3>> = (0..ratio.len()).map(|t| if free[t] { ev.ratio_variance(t) } else { None }).collect();
    // τ² per object and channel by the method of moments with inverse-variance weights a_t = 1/v_t: each
    // E[(r_t − m)²] = v_t + τ², so Σ a_t (r_t − m)² has expectation k + τ²·Σ a_t (k triangles). The unweighted
    // mean of (r_t − m)² − v_t solves the same moments with equal weights, and is dominated by the few triangles
    // whose variance is huge (a sliver with a near-zero render: mean v_t = 38 against a spread of 0.05 on the
    // textured room's cabinet after three rounds of splits), which set τ² to 0 and flattened a striped object
    // onto one colour; weighted by 1/v_t such a triangle counts for nothing (docs/optim/design-measurements.md,
    // "Shrinkage with triangles of very unequal noise").
    let mut moments = vec![(DVec3::ZERO, DVec3::ZERO, 0usize); objects];
    for (t, v) in var.iter().enumerate() {
        let (Some(v), Some(m)) = (v, mean[face_object[t] as usize]) else { continue };
        if ev.interior[t] < MIN_INTERIOR {
            continue;
        }
        let a = DVec3::ONE / v.max(DVec3::splat(MIN_VARIANCE));
        let d = ratio[t].as_dvec3() - m;
        let e = &mut moments[face_object[t] as usize];
        e.0 += a * d * d;
        e.1 += a;
        e.2 += 1;
    }
    let tau2: Vec<DVec3> = moments
        .iter()
        .map(|&(q, s, k)| {
            if k == 0 {
                return DVec3::ZERO;
            }
            ((q - DVec3::splat(k as f64)) / s).max(DVec3::ZERO)
        })
        .collect();
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
pub(super) fn bound_discards(round: u32, discarded: u64, paths: u64) -> Result<(), TriangleError> {
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
    progress: &dyn crate::Progress,
) -> Result<Fitted, TriangleError> {
    fit_pass(inputs, scene, samples, state, round, 0, progress)
}

/// The key numbers of pass `pass`'s ratio steps: pass 0 takes `fit_steps` (at least 1), each later pass
/// `light_fit_steps` (at least 1), numbered on from where the previous pass stopped, so that no two steps of a
/// round share their random numbers whatever the two counts.
#[must_use]
pub fn pass_steps(fit_steps: u32, light_fit_steps: u32, pass: u32) -> std::ops::Range<u32> {
    let (first_pass, later) = (fit_steps.max(1), light_fit_steps.max(1));
    if pass == 0 {
        0..first_pass
    } else {
        let start = first_pass + (pass - 1) * later;
        start..start + later
    }
}

/// Pass `pass` of a round's fit: ratio steps under the current light, `fit_steps` in pass 0 ([`fit_round`])
/// and `light_fit_steps` in each later pass ([`super::light::refine_light`]'s, after a light cycle); random
/// numbers keyed by (seed, round, step), the steps numbered on across the passes.
pub fn fit_pass(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    round: u32,
    pass: u32,
    progress: &dyn crate::Progress,
) -> Result<Fitted, TriangleError> {
    // The pass renders every pixel of the round: at most `paths_per_step` paths each time.
    let settings = TriangleSettings {
        spp: round_spp(inputs.settings.spp, inputs.settings.paths_per_step, samples.len()),
        ..inputs.settings.clone()
    };
    let inputs = &RoundInputs { settings: &settings, ..*inputs };
    let cfg = inputs.settings;
    // Only objects that emit now may emit: the object stage's model decision (no emission) holds every other
    // object at 0. Emitters and unconstrained objects keep their materials (`fitted_triangles`).
    let free = super::fitted_triangles(&state.face_object, &state.emission, inputs.constrained);
    let nbrs = neighbours(state);
    let keys: Vec<u64> =
        pass_steps(cfg.fit_steps, cfg.light_fit_steps, pass).map(|k| key::triangle(round, k)).collect();
    let (n, steps, pixels) = (state.triangles.len(), keys.len(), samples.len());
    let phase = |i: usize| {
        format!(
            "round {round}: ratio step {i}/{steps} of pass {pass} ({n} triangles, {pixels} pixels at ≤ {} paths), block",
            cfg.spp
        )
    };
    let update = if cfg.fit_steps > 0 { Update::PerTriangle { nbrs: &nbrs } } else { Update::RenderOnly };
    let plan = StepPlan { free: &free, keys: &keys, update, phase: &phase };
    let Stepped { loss, residual, mut work } = ratio_steps(inputs, scene, samples, state, &plan, progress)?;
    if cfg.adam_iterations > 0 {
        super::adam::adam(inputs, scene, samples, state, &free, &nbrs, round, &mut work)?;
    }
    // The object fit's bound and reasons (`crate::fit::samples`), per round.
    if work.discarded > 0 {
        tracing::warn!(round, discarded = work.discarded, paths = work.paths, "non-finite path samples discarded");
    }
    bound_discards(round, work.discarded, work.paths)?;
    Ok(Fitted { loss, residual, free, traced_paths: work.paths, discarded_samples: work.discarded })
}

/// How a run of ratio steps ([`ratio_steps`]) moves the free triangles' base colours.
pub(crate) enum Update<'a> {
    /// Each free triangle by its own ratio, shrunk towards its object's ([`shrink_to_object`]), then the
    /// smoothness solve over these [`neighbours`] of the state's mesh: a round's passes.
    PerTriangle { nbrs: &'a [Vec<u32>] },
    /// Each object's free triangles by one factor per channel ([`object_factor`]), their shape held: the lobe
    /// family look's fits of one colour per object (no smoothing, so no neighbours).
    OneFactor,
    /// None: the steps only render, for the loss and residuals.
    RenderOnly,
}

/// What a run of ratio steps ([`ratio_steps`]) updates and how it renders.
pub(crate) struct StepPlan<'a> {
    /// Per triangle: its base colour is updated (else it stays, and neither smoothing nor shrinkage moves it).
    pub free: &'a [bool],
    /// The render key of each step, one step per key.
    pub keys: &'a [u64],
    pub update: Update<'a>,
    /// The progress phase of step i (1-based) of a render's blocks.
    pub phase: &'a dyn Fn(usize) -> String,
}

/// Per free triangle: its value in `old` times its object's photo sum over render sum (over the pixels the steps
/// use on the object's free triangles), per channel, written to `out`: the ratio step of an object with one
/// colour, or of a texture whose shape is held. Other triangles' entries of `out` are left as they are.
fn object_factor(
    old: &[Vec3],
    (t_sum, r_sum): (&[DVec3], &[DVec3]),
    free: &[bool],
    face_object: &[u32],
    objects: usize,
    out: &mut [Vec3],
) {
    let mut sums = vec![(DVec3::ZERO, DVec3::ZERO); objects];
    for t in (0..old.len()).filter(|&t| free[t]) {
        let s = &mut sums[face_object[t] as usize];
        s.0 += t_sum[t];
        s.1 += r_sum[t];
    }
    for t in (0..old.len()).filter(|&t| free[t]) {
        let (ts, rs) = sums[face_object[t] as usize];
        out[t] = ratio_step(old[t], ts, rs);
    }
}

/// The ratio step of one value: `old` times photo sum `t` over render sum `r`, per channel, within [0, 1]. A
/// channel the renders put at 0 (no pixel, or no light of that colour there; a black base colour is not one,
/// being rendered at MIN_STEP_BASE) has no ratio: its value stays.
fn ratio_step(old: Vec3, t: DVec3, r: DVec3) -> Vec3 {
    let q = |c: usize| if r[c] > 0.0 { t[c] / r[c] } else { 1.0 };
    (old.as_dvec3() * DVec3::new(q(0), q(1), q(2))).as_vec3().clamp(Vec3::ZERO, Vec3::ONE)
}

/// What a run of ratio steps leaves: the loss before each update, the residuals against the render predicted
/// for the last update, and the tracer's work.
pub(crate) struct Stepped {
    /// Mean per-channel |photo − render| over `samples`, per step (before its update).
    pub loss: Vec<f64>,
    /// Per sample: photo − predicted render after the last update.
    pub residual: Vec<Vec3>,
    pub work: tracer::TraceStats,
}

/// Paths per pixel of each sample in a ratio step: `spp`, or fewer for the samples of a triangle with n samples
/// whose object has N: ⌊`per_triangle` / n⌋ or ⌈`per_object` / N⌉, whichever is more, at least 1; a
/// `per_triangle` of 0 renders every sample at `spp`. A step sets a triangle's value from its photo and render
/// sums over all its pixels, so the render's noise in that value is set by the paths the triangle gets in all,
/// not per pixel: a wall triangle's 4096 pixels at 32 paths each traced 64 times the paths of a 64-pixel
/// triangle for the same kind of estimate. The object's value, which the shrinkage pulls its uniform triangles
/// to, rests on all its pixels' paths, and an object of a few large triangles (a wall of 2) would have only the
/// few triangles' budgets, so each object keeps at least `per_object` paths. Every pixel keeps at least one
/// path, so the photo's side of the sums (its texture and noise) is still averaged over all of them, and within
/// a triangle the count is one, so the split test's pixels stay alike in their noise.
#[must_use]
pub fn paths_per_pixel(samples: &[TriSample], face_object: &[u32], objects: usize, budget: &PathBudget) -> Vec<u32> {
    let spp = budget.spp.max(1);
    if budget.per_triangle == 0 {
        return vec![spp; samples.len()];
    }
    let mut of_triangle = vec![0u32; face_object.len()];
    let mut of_object = vec![0u32; objects];
    for s in samples {
        of_triangle[s.tri as usize] += 1;
        of_object[face_object[s.tri as usize] as usize] += 1;
    }
    samples
        .iter()
        .map(|s| {
            let n = of_triangle[s.tri as usize].max(1);
            let big_n = of_object[face_object[s.tri as usize] as usize].max(1);
            (budget.per_triangle / n).max(budget.per_object.div_ceil(big_n)).clamp(1, spp)
        })
        .collect()
}

/// Paths per pixel of the renders of a round's passes ([`fit_pass`]) over its `pixels` pixels: `spp`, or
/// ⌊`per_step` / pixels⌋ (at least 1) where `spp` each would take more than `per_step` paths in one render; a
/// `per_step` of 0 bounds nothing. `pixels_per_triangle` bounds a round's pixels by its triangles, which on a
/// house of 10⁵–10⁶ triangles smaller than that budget is no bound: every pixel of the photos is fitted, and
/// each render's cost would grow with the photos' resolution. A triangle's value rests on the paths of all its
/// pixels together, so where a round has more pixels each needs fewer paths for the same noise in it. The
/// renders of fixed-size samples (the fit check's, the lobe family look's) do not grow with the photos and
/// keep `spp` (docs/scale/README.md, "A budget of paths per render").
#[must_use]
pub fn round_spp(spp: u32, per_step: u64, pixels: usize) -> u32 {
    let spp = spp.max(1);
    if per_step == 0 || pixels == 0 {
        return spp;
    }
    let each = per_step / pixels as u64;
    u32::try_from(each).unwrap_or(u32::MAX).clamp(1, spp)
}

/// What bounds a ratio step's paths ([`paths_per_pixel`]): `triangle.spp`, `triangle.paths_per_triangle` and
/// `triangle.paths_per_object`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PathBudget {
    pub spp: u32,
    pub per_triangle: u32,
    pub per_object: u32,
}

/// Ratio steps of the base colours of `plan.free` triangles on `samples` (the other triangles stay as they
/// are): per step one render of the samples at `triangle.spp` paths ([`paths_per_pixel`]: fewer on a triangle
/// whose samples would take more than its budget) with that step's key, then the update
/// `plan.update` names (each free triangle's ratio ρ·T/R shrunk towards its object's value
/// ([`shrink_to_object`]) and the smoothness solve, or one factor per object) and the per-object relaxation of
/// reversing steps. The one body of a round's passes ([`fit_pass`]) and of the lobe family look's fits and
/// steps on its objects' own pixels ([`super::family`]).
pub(crate) fn ratio_steps(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    samples: &[TriSample],
    state: &mut TriangleState,
    plan: &StepPlan<'_>,
    progress: &dyn crate::Progress,
) -> Result<Stepped, TriangleError> {
    let cfg = inputs.settings;
    let n = state.triangles.len();
    let free = plan.free;
    let mut interior = vec![0usize; n];
    for s in samples {
        interior[s.tri as usize] += usize::from(s.interior);
    }
    let used = |s: &TriSample| s.interior || interior[s.tri as usize] < MIN_INTERIOR;
    let pix: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let mut loss = Vec::new();
    let mut residual = vec![Vec3::ZERO; samples.len()];
    let mut work = tracer::TraceStats::default();
    let objects = state.emission.len();
    let budget = PathBudget { spp: cfg.spp, per_triangle: cfg.paths_per_triangle, per_object: cfg.paths_per_object };
    let spp = paths_per_pixel(samples, &state.face_object, objects, &budget);
    // Per object and channel: the fraction of the ratio step taken, and the object's mean change last step.
    let mut relax = vec![DVec3::ONE; objects];
    let mut last_step = vec![DVec3::ZERO; objects];
    // The per-triangle buffers of every step, allocated once: the lobe family look takes a dozen steps per
    // object on a few hundred pixels, and fresh buffers of a house's 521 362 triangles each step made page
    // faults, zeroing and copies about 40 % of its time (docs/optim/design-measurements.md, "Paths per
    // triangle in the ratio steps"). A step changes only the base colours: emission and horizon stay.
    let mut params = state.params();
    let mut t_sum = vec![DVec3::ZERO; n];
    let mut r_sum = vec![DVec3::ZERO; n];
    let mut d_sq = vec![DVec3::ZERO; n];
    let mut count = vec![0f64; n];
    let mut old = vec![Vec3::ZERO; n];
    let mut rho = vec![Vec3::ZERO; n];
    for (i, &key) in plan.keys.iter().enumerate() {
        if !matches!(plan.update, Update::RenderOnly) {
            lift_black_channels(&mut state.materials, free);
        }
        params.materials.copy_from_slice(&state.materials);
        let (values, stats) = crate::blocks::render_blocks_each(
            &tracer::Renderer::new(scene, &params, inputs.tracer)?,
            inputs.cameras,
            &pix,
            &spp,
            cfg.seed,
            key,
            progress,
            &(plan.phase)(i + 1),
        )?;
        work.add(&stats);
        t_sum.fill(DVec3::ZERO);
        r_sum.fill(DVec3::ZERO);
        d_sq.fill(DVec3::ZERO);
        count.fill(0.0);
        for (o, m) in old.iter_mut().zip(&state.materials) {
            *o = m.base_color;
        }
        let mut pooled = vec![Pooled::default(); objects];
        let mut l = 0.0;
        for (s, v) in samples.iter().zip(&values) {
            l += f64::from((*v - s.target).abs().element_sum()) / 3.0;
            let t = s.tri as usize;
            if s.on_object && free[t] && old[t].min_element() > 0.0 {
                pooled[state.face_object[t] as usize].add(s.target.as_dvec3(), v.as_dvec3(), old[t].as_dvec3());
            }
            if used(s) {
                let d = (s.target - *v).as_dvec3();
                t_sum[t] += s.target.as_dvec3();
                r_sum[t] += v.as_dvec3();
                d_sq[t] += d * d;
                count[t] += 1.0;
            }
        }
        loss.push(l / samples.len().max(1) as f64);
        rho.copy_from_slice(&old);
        match plan.update {
            Update::RenderOnly => {}
            Update::OneFactor => {
                // One factor per object keeps its shape: nothing for the smoothness to do.
                object_factor(&old, (&t_sum, &r_sum), free, &state.face_object, objects, &mut rho);
            }
            Update::PerTriangle { nbrs } => {
                let ratio: Vec<Vec3> = (0..n).map(|t| ratio_step(old[t], t_sum[t], r_sum[t])).collect();
                let evidence = Evidence {
                    old: &old,
                    t_sum: &t_sum,
                    r_sum: &r_sum,
                    d_sq: &d_sq,
                    count: &count,
                    interior: &interior,
                    pooled: &pooled,
                };
                let mean = object_values(&evidence, &state.face_object, free, objects);
                let ratio =
                    if SHRINK { shrink_to_object(&ratio, &evidence, &state.face_object, free, &mean) } else { ratio };
                fill_unobserved(&mut rho, &count, free, &state.face_object, &mean);
                smooth_solve(&mut rho, &ratio, &count, nbrs, free, cfg.smoothness);
            }
        }
        if !matches!(plan.update, Update::RenderOnly) {
            relax_objects(&mut rho, &old, &count, free, &state.face_object, &mut relax, &mut last_step);
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
    Ok(Stepped { loss, residual, work })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_round_renders_at_most_its_paths_per_step_whatever_its_pixels() {
        // Few pixels keep `spp`; a house's keep the budget (16 each at 10.5 M pixels and 1.7·10⁸ paths).
        assert_eq!(round_spp(32, 170_000_000, 55_296), 32);
        assert_eq!(round_spp(32, 170_000_000, 10_549_892), 16);
        assert_eq!(round_spp(32, 0, 10_549_892), 32);
        assert_eq!(round_spp(32, 170_000_000, 0), 32);
        for pixels in [1usize, 1000, 5_312_500, 5_312_501, 10_549_892, 400_000_000] {
            let spp = round_spp(32, 170_000_000, pixels);
            assert!((1..=32).contains(&spp));
            // Within the budget, or at the one path every pixel keeps; and never below it when more fit.
            assert!(spp as u64 * pixels as u64 <= 170_000_000 || spp == 1, "{pixels}: {spp}");
            assert!(spp == 32 || (spp as u64 + 1) * pixels as u64 > 170_000_000, "{pixels}: {spp}");
        }
    }

    #[test]
    fn a_triangle_with_many_pixels_takes_fewer_paths_each_within_its_budget() {
        let sample = |tri: u32| TriSample {
            pixel: PixelRef { view: 0, x: 0, y: 0 },
            target: Vec3::ZERO,
            tri,
            child: 0,
            interior: true,
            on_object: true,
            bary: glam::Vec2::ZERO,
        };
        // Triangle 0: 10 pixels, 1: 100, 2: 1000, 3: 100 000, each its own object; triangles 4 and 5 share
        // object 4 with 2000 pixels each; triangle 6 has none.
        let counts = [(0, 10), (1, 100), (2, 1000), (3, 100_000), (4, 2000), (5, 2000)];
        let samples: Vec<TriSample> = counts.iter().flat_map(|&(t, n)| (0..n).map(move |_| sample(t))).collect();
        let face_object = [0, 1, 2, 3, 4, 4, 5];
        let of = |spp: &[u32], t: u32| spp[samples.iter().position(|s| s.tri == t).expect("sample")];
        let paths =
            |spp: &[u32], t: u32| -> u32 { samples.iter().zip(spp).filter(|(s, _)| s.tri == t).map(|(_, &n)| n).sum() };
        // Without an object floor: below the triangle's budget every pixel keeps `spp`, above it ⌊8192 / n⌋, at
        // least 1, and no triangle takes more than the budget unless one path per pixel is more.
        let budget = PathBudget { spp: 32, per_triangle: 8192, per_object: 0 };
        let spp = paths_per_pixel(&samples, &face_object, 6, &budget);
        assert_eq!([0, 1, 2, 3, 4].map(|t| of(&spp, t)), [32, 32, 8, 1, 4]);
        for &(t, n) in &counts {
            assert!(paths(&spp, t) <= 8192.max(n), "triangle {t}: {} paths", paths(&spp, t));
        }
        // An object floor of 32 768 paths: object 4's 4000 pixels take ⌈32 768 / 4000⌉ = 9 each, more than
        // their triangles' 4; the others are above it already, or at `spp`.
        let budget = PathBudget { per_object: 32_768, ..budget };
        let spp = paths_per_pixel(&samples, &face_object, 6, &budget);
        assert_eq!([0, 1, 2, 3, 4, 5].map(|t| of(&spp, t)), [32, 32, 32, 1, 9, 9]);
        assert!(paths(&spp, 4) + paths(&spp, 5) >= 32_768);
        // A triangle budget of 0: no bound.
        let none = PathBudget { per_triangle: 0, ..budget };
        assert!(paths_per_pixel(&samples, &face_object, 6, &none).iter().all(|&n| n == 32));
    }

    #[test]
    fn the_passes_of_a_round_number_their_steps_on_without_overlap() {
        // Equal counts: pass p takes steps 3p..3p + 3, the numbering of one count for every pass.
        for p in 0..3 {
            assert_eq!(pass_steps(3, 3, p), 3 * p..3 * p + 3);
        }
        // Fewer steps after a light cycle: 0..3, then 3..4 and 4..5; a count of 0 still takes one step.
        assert_eq!(pass_steps(3, 1, 0), 0..3);
        assert_eq!(pass_steps(3, 1, 1), 3..4);
        assert_eq!(pass_steps(3, 1, 2), 4..5);
        assert_eq!(pass_steps(0, 2, 0), 0..1);
        assert_eq!(pass_steps(0, 2, 1), 1..3);
        // Any counts: consecutive passes are adjacent, so no key is used twice.
        for (a, b) in [(1, 5), (7, 2), (3, 3)] {
            for p in 0..4 {
                assert_eq!(pass_steps(a, b, p).end, pass_steps(a, b, p + 1).start);
            }
        }
    }

    #[test]
    fn an_object_whose_steps_reverse_takes_a_smaller_fraction_of_them() {
        // Two triangles of object 0 proposing +0.1 after a step of −0.1: half the step is taken; object 1's
        // steps keep their direction and are taken whole.
        let old = vec![Vec3::splat(0.5); 4];
        let mut rho = vec![Vec3::splat(0.6), Vec3::splat(0.6), Vec3::splat(0.55), Vec3::splat(0.55)];
        let mut relax = vec![DVec3::ONE; 2];
        let mut last = vec![DVec3::splat(-0.1), DVec3::splat(0.02)];
        relax_objects(&mut rho, &old, &[10.0; 4], &[true; 4], &[0, 0, 1, 1], &mut relax, &mut last);
        assert!((rho[0].x - 0.55).abs() < 1e-6 && (rho[1].x - 0.55).abs() < 1e-6, "{rho:?}");
        assert!((rho[2].x - 0.55).abs() < 1e-6, "{rho:?}");
        assert_eq!(relax[0], DVec3::splat(0.5));
        assert!((last[0].x - 0.05).abs() < 1e-6, "{last:?}");
        // The damped map of an overshooting iteration converges: x ← x + ω·(f(x) − x) with f(x) = 0.9 − 1.5·(x − 0.9),
        // whose undamped iterates diverge from 0.85.
        let mut x = vec![Vec3::splat(0.85)];
        let (mut relax, mut last) = (vec![DVec3::ONE], vec![DVec3::ZERO]);
        for _ in 0..40 {
            let old = x.clone();
            x[0] = Vec3::splat(0.9 - 1.5 * (old[0].x - 0.9));
            relax_objects(&mut x, &old, &[1.0], &[true], &[0], &mut relax, &mut last);
        }
        assert!((x[0].x - 0.9).abs() < 1e-3, "{x:?}");
    }

    #[test]
    fn one_factor_per_object_keeps_its_shape_and_matches_its_sums() {
        // Object 0: a texture 0.2 / 0.4 whose renders sum to half the photos' (factor 2 per channel); object 1
        // held (not free); triangle 3 of object 0 has no pixel and moves with its object all the same.
        let old = vec![Vec3::splat(0.2), Vec3::splat(0.4), Vec3::splat(0.5), Vec3::splat(0.3)];
        let t_sum = vec![DVec3::splat(2.0), DVec3::splat(6.0), DVec3::splat(1.0), DVec3::ZERO];
        let r_sum = vec![DVec3::splat(1.0), DVec3::splat(3.0), DVec3::splat(3.0), DVec3::ZERO];
        let mut out = old.clone();
        object_factor(&old, (&t_sum, &r_sum), &[true, true, false, true], &[0, 0, 1, 0], 2, &mut out);
        for (t, want) in [(0, 0.4), (1, 0.8), (2, 0.5), (3, 0.6)] {
            assert!((out[t].x - want).abs() < 1e-6, "triangle {t}: {out:?}");
        }
        // A factor that would pass 1 is clamped there; a channel with no render keeps its value.
        let r_none = vec![DVec3::new(1.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0), DVec3::ZERO, DVec3::ZERO];
        let mut out = old.clone();
        object_factor(&old, (&t_sum, &r_none), &[true, true, false, true], &[0, 0, 1, 0], 2, &mut out);
        assert_eq!(out[1], Vec3::new(1.0, 1.0, 0.4));
    }

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

    #[test]
    fn an_unseen_region_takes_its_objects_value_and_its_edge_blends_into_the_seen_part() {
        // Object 0 is a chain of 20 triangles, 0–3 seen (fitted to 0.2), 4–19 unseen at a stale 0.6 (the
        // value the object started from); object 1 (triangle 20, unseen) has no value; triangle 21 of object 0
        // is unseen but held (not free).
        let n = 22;
        let mut nbrs = vec![Vec::new(); n];
        for t in 0..19 {
            nbrs[t].push(t as u32 + 1);
            nbrs[t + 1].push(t as u32);
        }
        let face_object: Vec<u32> = (0..n).map(|t| u32::from(t == 20)).collect();
        let free: Vec<bool> = (0..n).map(|t| t != 21).collect();
        let count: Vec<f64> = (0..n).map(|t| if t < 4 { 50.0 } else { 0.0 }).collect();
        let ratio: Vec<Vec3> = (0..n).map(|t| Vec3::splat(if t < 4 { 0.2 } else { 0.6 })).collect();
        let mut rho = vec![Vec3::splat(0.6); n];
        let mean = [Some(DVec3::splat(0.2)), None];
        fill_unobserved(&mut rho, &count, &free, &face_object, &mean);
        smooth_solve(&mut rho, &ratio, &count, &nbrs, &free, 0.1);
        for (t, r) in rho.iter().enumerate().take(20) {
            assert!((r.x - 0.2).abs() < 1e-3, "triangle {t}: {r}");
        }
        assert_eq!((rho[20], rho[21]), (Vec3::splat(0.6), Vec3::splat(0.6)));
        // Without the fill the sweeps carry the seen value only part of the way: the far end stays near the stale
        // one (0.46 here).
        let mut stale = vec![Vec3::splat(0.6); n];
        smooth_solve(&mut stale, &ratio, &count, &nbrs, &free, 0.1);
        assert!(stale[19].x > 0.4, "{}", stale[19]);
    }

    /// Evidence of triangles that each saw 100 interior pixels with render = photo·ρ_old/ρ_true (so the ratio
    /// is the true value) and a pixel scatter giving ratio variance `v`.
    type Sums = (Vec<DVec3>, Vec<DVec3>, Vec<DVec3>, Vec<f64>, Vec<usize>);

    fn evidence(old: &[Vec3], truth: &[Vec3], v: f64) -> Sums {
        evidence_each(old, truth, &vec![v; old.len()])
    }

    /// [`evidence`] with its own ratio variance per triangle.
    fn evidence_each(old: &[Vec3], truth: &[Vec3], v: &[f64]) -> Sums {
        let n = 100.0;
        let t_sum: Vec<DVec3> = truth.iter().map(|_| DVec3::splat(n * 0.5)).collect();
        let r_sum: Vec<DVec3> =
            old.iter().zip(truth).map(|(o, t)| DVec3::splat(n * 0.5) * o.as_dvec3() / t.as_dvec3()).collect();
        // v = ρ²·n·s²/R² ⇒ Σd² ≈ (n − 1)·s² + n·mean_d².
        let d_sq: Vec<DVec3> = (0..old.len())
            .map(|t| {
                let rho = old[t].as_dvec3();
                let s2 = DVec3::splat(v[t]) * r_sum[t] * r_sum[t] / (rho * rho * n);
                let mean_d = (t_sum[t] - r_sum[t]) / n;
                s2 * (n - 1.0) + mean_d * mean_d * n
            })
            .collect();
        (t_sum, r_sum, d_sq, vec![n; old.len()], vec![100; old.len()])
    }

    /// Runs `f` on the [`Evidence`] of `sums`, with the per-object sums of [`Pooled`] taken over the same pixels
    /// as the per-triangle sums (every pixel sees its object alone).
    fn with_evidence<R>(
        old: &[Vec3],
        sums: &Sums,
        face_object: &[u32],
        objects: usize,
        f: impl FnOnce(&Evidence<'_>) -> R,
    ) -> R {
        let (t_sum, r_sum, d_sq, count, interior) = sums;
        let mut pooled = vec![Pooled::default(); objects];
        for t in 0..old.len() {
            let p = &mut pooled[face_object[t] as usize];
            p.t += t_sum[t];
            p.r_per_albedo += r_sum[t] / old[t].as_dvec3();
            p.d += t_sum[t] - r_sum[t];
            p.d_sq += d_sq[t];
            p.n += count[t];
        }
        f(&Evidence { old, t_sum, r_sum, d_sq, count, interior, pooled: &pooled })
    }

    #[test]
    fn a_uniform_object_keeps_its_value_and_a_textured_one_its_triangles_values() {
        // Object 0: uniform 0.5, triangle ratios scattered by exactly the noise (±0.01, v = 1e-4).
        // Object 1: a checker 0.2 / 0.8 (spread far beyond the same noise).
        let old = vec![Vec3::splat(0.5); 8];
        let ratio: Vec<Vec3> = [0.51, 0.49, 0.51, 0.49, 0.2, 0.8, 0.2, 0.8].iter().map(|&x| Vec3::splat(x)).collect();
        let face_object = [0, 0, 0, 0, 1, 1, 1, 1];
        let (v, out) = with_evidence(&old, &evidence(&old, &ratio, 1e-4), &face_object, 2, |ev| {
            (
                ev.ratio_variance(0).unwrap(),
                shrink_to_object(&ratio, ev, &face_object, &[true; 8], &object_values(ev, &face_object, &[true; 8], 2)),
            )
        });
        assert!((v.x - 1e-4).abs() < 1e-9, "{v}");
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
    fn a_few_triangles_with_huge_variance_do_not_flatten_a_textured_object() {
        // A checker 0.2 / 0.8 seen with noise v = 1e-4, plus two slivers whose ratio is almost unmeasured
        // (v = 100, a near-zero render). An unweighted mean of (r − m)² − v is −20 here (τ² = 0, every triangle
        // flattened to m); the inverse-variance weighted moments keep the checker.
        let truth: Vec<Vec3> =
            [0.2, 0.8, 0.2, 0.8, 0.2, 0.8, 0.2, 0.8, 0.5, 0.5].iter().map(|&x| Vec3::splat(x)).collect();
        let old = vec![Vec3::splat(0.5); truth.len()];
        let mut v = vec![1e-4; 8];
        v.extend([100.0, 100.0]);
        let mut ratio = truth.clone();
        // The slivers' ratios are far off, as unmeasured ones are.
        ratio[8] = Vec3::splat(0.0);
        ratio[9] = Vec3::splat(1.0);
        let out = with_evidence(&old, &evidence_each(&old, &truth, &v), &[0; 10], 1, |ev| {
            shrink_to_object(&ratio, ev, &[0; 10], &[true; 10], &object_values(ev, &[0; 10], &[true; 10], 1))
        });
        for t in 0..8 {
            assert!((out[t].x - truth[t].x).abs() < 1e-3, "triangle {t}: {out:?}");
        }
        // The slivers go (almost) to the object's value.
        for t in 8..10 {
            assert!((out[t].x - 0.5).abs() < 0.01, "triangle {t}: {out:?}");
        }
    }

    #[test]
    fn an_object_tessellated_finer_than_its_pixels_moves_to_its_pooled_value() {
        // 200 triangles of one uniform object (truth 0.3, current 0.5), each seen in 3 pixels none of which is
        // interior to it, but every one of which sees the object alone: no triangle has clean evidence, the
        // pooled update over the 600 pixels does. Render = photo·ρ_old/ρ_true with a ±2 % scatter.
        let tris = 200;
        let (old, truth) = (vec![Vec3::splat(0.5); tris], vec![Vec3::splat(0.3); tris]);
        let (mut t_sum, mut r_sum, mut d_sq) =
            (vec![DVec3::ZERO; tris], vec![DVec3::ZERO; tris], vec![DVec3::ZERO; tris]);
        let mut pooled = vec![Pooled::default()];
        for t in 0..tris {
            for j in 0..3 {
                let photo = DVec3::splat(0.3);
                let render = photo * (0.5 / 0.3) * (1.0 + 0.02 * (((t * 3 + j) % 5) as f64 - 2.0) / 2.0);
                t_sum[t] += photo;
                r_sum[t] += render;
                d_sq[t] += (photo - render) * (photo - render);
                pooled[0].add(photo, render, old[t].as_dvec3());
            }
        }
        let (count, interior) = (vec![3.0; tris], vec![0usize; tris]);
        let ev = Evidence {
            old: &old,
            t_sum: &t_sum,
            r_sum: &r_sum,
            d_sq: &d_sq,
            count: &count,
            interior: &interior,
            pooled: &pooled,
        };
        let ratio: Vec<Vec3> = (0..tris).map(|t| (old[t].as_dvec3() * t_sum[t] / r_sum[t]).as_vec3()).collect();
        let (objects, free) = (vec![0; tris], vec![true; tris]);
        let shrink =
            |ev: &Evidence<'_>| shrink_to_object(&ratio, ev, &objects, &free, &object_values(ev, &objects, &free, 1));
        let out = shrink(&ev);
        for (t, o) in out.iter().enumerate() {
            assert!((o.x - truth[t].x).abs() < 0.005, "triangle {t}: {o}");
        }
        // Fewer than MIN_POOLED pooled pixels: the object keeps its value.
        let few = [Pooled { n: MIN_POOLED - 1.0, ..pooled[0] }];
        let out = shrink(&Evidence { pooled: &few, ..ev });
        assert!(out.iter().all(|o| (o.x - 0.5).abs() < 1e-6), "{:?}", &out[..3]);
    }
}
