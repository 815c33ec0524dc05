//! Model selection per object: every object starts diffuse without emission and keeps an emission
//! term or gains a specular lobe only when that lowers the residual on held-out pixels significantly (a
//! paired t-test over the held-out pixels, plus a minimum relative improvement). An emission of an object
//! the photos see must also beat the object's best lobe without emission, dielectric or metal (measured:
//! docs/optim/design-measurements.md, "An emission against the best lobe without it"). A small lamp lights
//! the room too faintly for the test on the pixels it lights, so an emitter that test does not keep is tested
//! again on the pixels that see it, against its best base colour and lobe without emission fitted there
//! (measured: the same file, "Small lamps and per-object step checks"). Where the best material without the
//! emission is white (its base colour at the top of its domain in every channel), that alternative is the
//! brightest reflector there is rather than a fit, and the emission needs t > 2 instead of 3 (measured: the same
//! file, "An emission against a white alternative").
//! A sideways emitter that the horizon step could split is tested again with its emission split when the
//! pixels its light reaches do not keep it as one radiance in every direction: a window pane's uniform emission
//! sends the ceiling light that the ground outside never sent, and on those pixels it can do worse than no
//! emission at all. The split is kept only where it also beats one radiance fitted on the same pixels
//! (measured: the same file, "A window pane tested split").
//! Then a kept emitter that faces sideways may be split at the horizon (`super::horizon`): the closing re-fit
//! runs with every such emitter split, and each keeps its split only where the held-out pixels its light
//! reaches pay for it. Last, under that settled light, `super::family` takes a second look at the lobe family
//! of every object that ended dielectric, and keeps a metal lobe where the held-out pixels ask for one; then
//! every dielectric lobe faces the object's best Lambert surface, which replaces it unless the held-out pixels
//! ask for the lobe.

use super::emission_solve::{SolveOptions, Support, Unknowns, solve_step_pinned};
use super::family;
use super::horizon;
use super::jacobian::{self, Ctx};
use super::layout::{
    self, BASE_COLOR, EMISSION, EMISSION_GROUND, EMISSION_MAX, EMISSION_ZENITH, METALLIC, PER_OBJECT, ROUGHNESS,
    SPECULAR, Split, idx,
};
use super::linear::{self, paired_t};
use super::paired::{
    self, FIRST_LOOK, MIN_GAIN, Statistic, Stop, T_KEEP, cannot_pass, clearly_passes, l1, sequential_lobe_test, target,
};
use super::pixels::{PixelSets, Sample};
use super::roughness::{self, FLAT_PROFILE, TRIAL_ROUGHNESS, TRIAL_SPECULAR, lobe_test_samples, profile_samples};
use super::solve::{self, solve_options};
use super::step_check;
use super::{FitError, ObjectFitSettings, ObjectModel};
use crate::progress::check_stop;
use crate::streams::{self, draw, key};
use tracer::PixelRef;

/// Pilot columns of the emission test rendered together: each path of a render is traced once for all of
/// them, and the columns held at once (16 × 12 bytes per test pixel: 33 MB for a house's 171 k test pixels)
/// stay small, where all of a house's emitters × test pixels would not.
const PILOT_COLUMNS: usize = 16;
/// A dropped emission whose object's best base colour without it differs by more than this triggers a re-fit
/// of emission and base colour under the chosen model: 0.02 is 4× the fit's per-object albedo noise on the
/// default scene (mean L1 0.0023), so the tiny emissions that walls are routinely given and denied (≤ 0.003
/// radiance, base colour change ≲ 0.005) cost nothing, while an emission that replaced albedo is undone.
const REFIT_MATERIAL: f64 = 0.02;

/// A model without an object's emission whose base colour ends within this of 1, the top of its domain, in
/// every channel is saturated: the photos ask more light of the object than any reflectance gives it, so that
/// model is the brightest material there is rather than a fit. (The solves' box bound is 1; their iterates
/// end on it, or within rounding of it, when the photos ask for more.)
const SATURATED: f64 = 1.0 - 1e-3;
/// An emission whose alternative without it is saturated is kept at a lower bar than [`T_KEEP`]: t > 2
/// (one-sided p ≈ 2 %). The test's null hypothesis, a material without emission, sits there on the edge of
/// its domain, where it explains the object's pixels only as far as the bound lets it, and the paired test,
/// which treats it as a free fit, holds the emission to too much: on the corpus house (seed 1), a seen window
/// pane lost its emission at t = 3.0 to a white base colour at the bound, under a specular lobe at its own
/// bound, and its room's light with it (docs/optim/design-measurements.md, "An emission against a white
/// alternative").
const T_SATURATED: f64 = 2.0;

/// Whether a base colour is at the top of its domain in every channel ([`SATURATED`]).
fn saturated(base: [f64; 3]) -> bool {
    base.iter().all(|&v| v >= SATURATED)
}

/// Whether an emission's relative gain `rel` at paired t-statistic `t` keeps it against the model without it,
/// whose base colour is `alternative` (`None` when the object's base colour is not an unknown): t > [`T_KEEP`]
/// and a gain above [`MIN_GAIN`] of a percent, or t > [`T_SATURATED`] against a [`saturated`] alternative.
fn emission_beats(alternative: Option<[f64; 3]>, t: f64, rel: f64) -> bool {
    let bar = if alternative.is_some_and(saturated) { T_SATURATED } else { T_KEEP };
    t > bar && rel > MIN_GAIN * 1e-2
}

/// Gauss–Newton steps on emission (and base colour, per `unknowns`) after a model change, each on freshly drawn
/// solve pixels, with base colour and emission averaged over the second half of the steps (as the
/// refinement's result is): the closing re-fits of the specular trial and of a dropped emission.
struct AveragedSteps {
    unknowns: Unknowns,
    /// The emitters of the joint steps: those that emit as each step starts, and under
    /// [`Support::KeepHidden`] every hidden light `apply` does not hold at 0.
    support: Support,
    /// Number of steps (≥ 1); step i ∈ 1..=steps uses random-number key `key + i`, its check
    /// `key + SELECT_STEP_CHECK + i`.
    steps: u32,
    key: u64,
}

impl AveragedSteps {
    /// Runs the steps on `x` with the emission of every object with `no_emission[k]` held at 0.
    fn apply(
        &self,
        ctx: &Ctx<'_>,
        s: &ObjectFitSettings,
        sets: &PixelSets,
        x: &mut [f64],
        free: &[bool],
        no_emission: &[bool],
        progress: &dyn crate::Progress,
    ) -> Result<(), FitError> {
        let opts = SolveOptions { support: self.support, ..solve_options(s, self.unknowns) };
        let mut sum = vec![0.0; x.len()];
        let mut n_avg = 0.0;
        for step in 1..=self.steps {
            check_stop(progress)?;
            let key = self.key + u64::from(step);
            let samples = solve::step_samples(sets, s, self.unknowns, ctx.seed, key);
            let start = x.to_vec();
            solve_step_pinned(ctx, x, &samples, s.solve_spp, key, free, no_emission, &opts)?;
            // Checked like the refinement's steps (`step_check`): unchecked, a re-fit after a dropped
            // emission on Modern Hall took a wall's albedo from 0.89 to 0.11 and an unseen light ×4.
            let check =
                step_check::check_step(ctx, &start, x, &samples, solve::check_spp(s), key + key::SELECT_STEP_CHECK)?;
            if check.fraction < 1.0 || check.held_back() > 0 {
                tracing::debug!(
                    step,
                    fraction = check.fraction,
                    held_back = check.held_back(),
                    "model-selection re-fit step shortened"
                );
            }
            if step > self.steps / 2 {
                sum.iter_mut().zip(x.iter()).for_each(|(a, v)| *a += v);
                n_avg += 1.0;
            }
            progress.set_position(u64::from(step));
        }
        for k in 0..x.len() / PER_OBJECT {
            for p in (BASE_COLOR..BASE_COLOR + 3)
                .chain(EMISSION..EMISSION + 3)
                .chain(EMISSION_GROUND..EMISSION_GROUND + 3)
                .chain(EMISSION_ZENITH..EMISSION_ZENITH + 3)
            {
                x[idx(k, p)] = sum[idx(k, p)] / n_avg;
            }
        }
        Ok(())
    }
}

/// Times the profile's paths ([`roughness::profile_spp`]) at which [`best_lobe_without_emission`] searches. Its
/// ranking, the unbiased RMS error of two renders at half the paths each, is unbiased but noisy: at the
/// profile's own paths the metal-lamp fixture's box (roughness 0.30) was searched to 0.21, kept that lobe, and
/// ended with its base colour 0.10 bright; at four times them it is searched to 0.28, 0.035 off
/// (docs/optim/design-measurements.md, "An emission's lobe alternative searched by its unbiased error").
const SEARCH_PATHS: u32 = 4;

/// The best lobe of object k with its emission off, dielectric (metallic 0) or metal (metallic 1), each by
/// [`roughness::search_unbiased`] from a mid-range lobe at [`SEARCH_PATHS`] times the profile's paths: what an
/// object that reflects a light looks like when it does not emit. The searches and the choice between the
/// families rank by the profile's unbiased RMS error: the L1 of one render leans to the roughest lobe where the
/// pixels' noise hides the lobe's shape, and a polished metal box of the corpus house, mirroring its room, was
/// held to a metal of roughness 0.85 (truth 0.20) that its emission beat by 12.6 %. The metal's search starts at
/// the base colour whose render matches the pixels' summed radiance ([`family::metal_start`]), as the second
/// look's metal probes do: an object fitted with an emission has a dark base colour, and a metal's profile
/// solves, one linearised step each, end where their start sends them, so the emission was held to a metal of
/// the wrong colour (docs/optim/design-measurements.md, "The emission's metal alternative starts bright").
/// Returns `x` with that lobe (the lower unbiased RMS error of the two) and no emission for k.
pub fn best_lobe_without_emission(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    samples: &[Sample],
    x: &[f64],
    k: usize,
) -> Result<Vec<f64>, FitError> {
    let mut best: Option<(Vec<f64>, f64)> = None;
    let spp = roughness::profile_spp(s.solve_spp);
    for metallic in [0.0, 1.0] {
        let mut base = x.to_vec();
        for c in 0..3 {
            base[idx(k, EMISSION + c)] = 0.0;
        }
        base[idx(k, SPECULAR)] = TRIAL_SPECULAR;
        base[idx(k, ROUGHNESS)] = TRIAL_ROUGHNESS;
        base[idx(k, METALLIC)] = metallic;
        let search_key = key::SELECT_EMISSION_LOBE + 2 * k as u64 + metallic as u64;
        if metallic == 1.0 {
            let start = family::metal_start(ctx, &base, k, (samples, spp, search_key))?;
            for c in 0..3 {
                base[idx(k, BASE_COLOR + c)] = start[c];
            }
        }
        let (p, _) = roughness::search_unbiased(ctx, &base, k, (samples, SEARCH_PATHS * spp, search_key))?;
        for c in 0..3 {
            base[idx(k, BASE_COLOR + c)] = p.base_color[c];
        }
        base[idx(k, ROUGHNESS)] = p.roughness;
        base[idx(k, SPECULAR)] = p.specular;
        tracing::debug!(object = k, metallic, ?p, "lobe without emission");
        let rms = p.rms_or_loss();
        if best.as_ref().is_none_or(|(_, l)| rms < *l) {
            best = Some((base, rms));
        }
    }
    Ok(best.expect("two candidates").0)
}

/// Object k's base-colour column ∂I/∂ρ_k at `px`, per pixel and channel, at `solve_spp` gradient paths keyed
/// by the pixel (so a pixel's entry does not depend on which other pixels are asked for).
fn base_color_column(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    params: &tracer::Params,
    k: usize,
    px: &[PixelRef],
) -> Result<Vec<[f64; 3]>, FitError> {
    let only_k: Vec<bool> = (0..params.materials.len()).map(|o| o == k).collect();
    let sparse =
        jacobian::base_color_columns_of(ctx, params, px, s.solve_spp, key::SELECT_PIXEL_ROWS + k as u64, &only_k)?
            .swap_remove(k);
    let mut dense = vec![[0.0; 3]; px.len()];
    for (j, v) in sparse {
        dense[j as usize] = v;
    }
    Ok(dense)
}

/// The model without object k's emission gets its own best base colour on the test pixels (photo values `tgt`,
/// row weights `w` at mean 1): a 1-variable L1 fit per channel of the change of k's base colour, within
/// [0, 1], from k's base-colour column `col` at these pixels ([`base_color_column`]). `without` holds the
/// render without k's emission and receives the change's effect; returns the change.
fn refit_on_column(
    x: &[f64],
    k: usize,
    col: &[[f64; 3]],
    tgt: &[[f64; 3]],
    w: &[f64],
    without: &mut [[f64; 3]],
) -> [f64; 3] {
    let mut delta = [0.0; 3];
    for c in 0..3 {
        let col = vec![col.iter().map(|v| v[c]).collect::<Vec<f64>>()];
        let t_c: Vec<f64> = tgt.iter().zip(without.iter()).map(|(t, o)| t[c] - o[c]).collect();
        let rho = x[idx(k, BASE_COLOR + c)];
        let mut v = [0.0];
        linear::solve_box_l1(&col, &t_c, Some(w), (&[-rho], &[1.0 - rho]), &mut v, 20);
        delta[c] = v[0];
        for (j, o) in without.iter_mut().enumerate() {
            o[c] += col[0][j] * v[0];
        }
    }
    delta
}

/// One arm of an emission test: `params` rendered on `pixels` at `holdout_spp` with the test's random numbers,
/// which are keyed by the pixel alone, so every arm of every emitter's tests (the main test's, the lobe
/// alternative's, [`glimpse_test`]'s) gets the same estimates on the same pixels (common random numbers), and
/// the fitted model's arm at a pixel is one estimate that all emitters' tests share ([`ModelArm`]).
fn emission_test_arm(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    params: &tracer::Params,
    pixels: &[PixelRef],
) -> Result<Vec<[f64; 3]>, FitError> {
    Ok(ctx
        .render(params, pixels, s.holdout_spp, key::SELECT_EMISSION_TEST)?
        .iter()
        .map(|v| v.as_dvec3().to_array())
        .collect())
}

/// The fitted model's arm of the emission tests ([`emission_test_arm`] of the model with every emission),
/// rendered once per pixel and kept: it does not depend on which emitter is tested, and the emitters' tests
/// draw their pixels in one shared order (each among the pixels its light reaches), so the emitters of a room
/// test largely the same pixels and render the model there once.
struct ModelArm<'p> {
    params: &'p tracer::Params,
    at: std::collections::HashMap<PixelRef, [f64; 3]>,
}

impl ModelArm<'_> {
    /// The arm at `pixels`, rendering those not yet rendered.
    fn on(&mut self, ctx: &Ctx<'_>, s: &ObjectFitSettings, pixels: &[PixelRef]) -> Result<Vec<[f64; 3]>, FitError> {
        let mut new: Vec<PixelRef> = pixels.iter().copied().filter(|p| !self.at.contains_key(p)).collect();
        new.sort_unstable_by_key(|p| streams::pixel_key(*p));
        new.dedup();
        if !new.is_empty() {
            let values = emission_test_arm(ctx, s, self.params, &new)?;
            self.at.extend(new.into_iter().zip(values));
        }
        Ok(pixels.iter().map(|p| self.at[p]).collect())
    }
}

/// The rank of a test pixel in the order in which every emission test draws its pixels (the emitter's own
/// pixels and the others it lights, each in this order; [`glimpse_test`]'s likewise): one order for all
/// emitters, so that their tests share pixels and with them the model's arm ([`ModelArm`]).
fn emission_test_rank(seed: u64, pixel: PixelRef) -> f64 {
    streams::uniform(seed, draw::EMISSION_TEST, streams::pixel_key(pixel), 0)
}

/// An emission test's estimates at one pixel: the render of the model, the render without the emission, and
/// the emitter's base-colour column.
struct ArmsAt {
    pred: [f64; 3],
    without: [f64; 3],
    column: [f64; 3],
}

/// The last look of an emitter's test on the pixels its light reaches: the drawn test rows `on` (indices into
/// the test pixels), the change `delta` of the emitter's base colour refitted without its emission, and the
/// stratified mean gain with its t; `stopped` when the look was not the last one planned, and why.
struct EmissionLook {
    on: Vec<usize>,
    /// The mean photo L1 over all lit pixels (the stratified estimate), which the gain is relative to.
    mean_lit: f64,
    delta: [f64; 3],
    gain: f64,
    t: f64,
    stopped: Option<Stop>,
}

/// An emitter's test on the pixels its light reaches with its emission split at the horizon (`horizon`): the
/// two halves fitted on the test rows, the base-colour change of the model without the emission refitted on
/// the same rows, the stratified gain of the split model over that model with its t, and the gain of the split
/// model over one radiance fitted on the same rows with its t.
struct SplitLook {
    sky: [f64; 3],
    ground: [f64; 3],
    /// The one radiance fitted on the same rows.
    one: [f64; 3],
    delta: [f64; 3],
    /// The rows it was tested on (every drawn row).
    rows: usize,
    /// Against the model without the emission: gain relative to the rows' mean radiance, and t.
    rel: f64,
    t: f64,
    /// Against one radiance fitted on the same rows: gain relative to the rows' mean radiance, and t; None
    /// where the split does not beat no emission (not rendered).
    against_one: Option<(f64, f64)>,
    /// The split model's arm per test row.
    pred: std::collections::HashMap<usize, [f64; 3]>,
    /// The split model.
    params: tracer::Params,
}

impl SplitLook {
    /// Whether the split pays for its second radiance as the horizon test requires of a split ([`T_KEEP`],
    /// [`MIN_GAIN`]). A gain of the split model over no emission alone may be the gain of fitting a radiance on
    /// the test rows, not of splitting it: on `data-fixtures/scenes/window.toml` two walls whose uniform
    /// emission from the refinement made their lit pixels worse (t = −9.5 and −9.1) gained 1.0–1.1 % over no
    /// emission (t = 11.6 and 13.0) with halves fitted there, and 0.08–0.23 % over one radiance fitted there.
    fn split_pays(&self) -> bool {
        self.against_one.is_some_and(|(rel, t)| t > T_KEEP && rel > MIN_GAIN)
    }
}

/// The emission test of emitter k again, with its emission split at the horizon `up`, on all its drawn test
/// rows `rows` (their arms without the emission and base-colour columns in `cache`; strata weights `w_own`,
/// `w_other` as in the main test). A window pane sends the sky's light down and the ground's up: its uniform
/// emission, fitted to the photos over the whole room, sends the ceiling light it does not get, and on the
/// pixels its light reaches can do worse than no emission at all (a pane of the corpus house, t = −2.2). The
/// halves are fitted per channel by an L1 solve on the rows themselves, as the model without the emission
/// gets its base colour ([`refit_on_column`]), from their columns at `solve_spp` paths, and so is one radiance
/// (the two columns' sum), which the split must also beat ([`SplitLook::split_pays`]); each model is rendered
/// with the test's random numbers, paired with the others.
#[allow(clippy::too_many_arguments)]
fn split_look(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    (params, x, k, free): (&tracer::Params, &[f64], usize, bool),
    up: glam::Vec3,
    rows: &[usize],
    (pix, test): (&[PixelRef], &[Sample]),
    cache: &std::collections::HashMap<usize, ArmsAt>,
    (w_own, w_other): (f64, f64),
) -> Result<SplitLook, FitError> {
    let px: Vec<PixelRef> = rows.iter().map(|&j| pix[j]).collect();
    let tgt: Vec<[f64; 3]> = rows.iter().map(|&j| target(&test[j])).collect();
    let is_own: Vec<bool> = rows.iter().map(|&j| test[j].object == Some(k as u32)).collect();
    let row_w: Vec<f64> = is_own.iter().map(|&o| if o { w_own } else { w_other }).collect();
    let solve_w: Vec<f64> = row_w.iter().map(|w| w * row_w.len() as f64).collect();
    let without_k: Vec<[f64; 3]> = rows.iter().map(|j| cache[j].without).collect();
    let col: Vec<[f64; 3]> = rows.iter().map(|j| cache[j].column).collect();
    let mut without = without_k.clone();
    let delta = if free { refit_on_column(x, k, &col, &tgt, &solve_w, &mut without) } else { [0.0; 3] };
    let e = params.emission[k];
    let mut split = params.clone();
    split.split_at_horizon(up, [(k as u32, e)]);
    let ground_slot = split.horizon.ground_of(k as u32).expect("k was just split");
    let cols = jacobian::entry_columns(
        ctx,
        &split,
        &px,
        s.solve_spp,
        key::SELECT_SPLIT_COLUMNS + k as u64,
        &[k as u32, ground_slot],
    )?;
    // Per channel, an L1 fit of the emission's entries with these columns to the rows' photos less the model
    // without the emission, each entry in [0, EMISSION_MAX], from the uniform emission.
    let fit = |c: usize, cc: &[Vec<f64>]| -> Vec<f64> {
        let n = cc.len();
        let t_c: Vec<f64> = tgt.iter().zip(&without_k).map(|(t, o)| t[c] - o[c]).collect();
        let mut v = vec![f64::from(e[c]); n];
        linear::solve_box_l1(cc, &t_c, Some(&solve_w), (&vec![0.0; n], &vec![EMISSION_MAX; n]), &mut v, 20);
        v
    };
    let (mut sky, mut ground, mut one) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let halves: Vec<Vec<f64>> = cols.iter().map(|col| col.iter().map(|v| v[c]).collect()).collect();
        let both: Vec<f64> = halves[0].iter().zip(&halves[1]).map(|(a, b)| a + b).collect();
        let v = fit(c, &halves);
        (sky[c], ground[c]) = (v[0], v[1]);
        one[c] = fit(c, &[both])[0];
    }
    let as_vec3 = |v: [f64; 3]| glam::DVec3::from_array(v).as_vec3();
    split.emission[k] = as_vec3(sky);
    split.emission[ground_slot as usize] = as_vec3(ground);
    let arm = emission_test_arm(ctx, s, &split, &px)?;
    let mean_lit = tgt.iter().zip(&row_w).map(|(t, w)| w * l1(*t, [0.0; 3])).sum::<f64>().max(f64::MIN_POSITIVE);
    let versus = |other: &[[f64; 3]]| {
        let d: Vec<f64> = tgt.iter().zip(other.iter().zip(&arm)).map(|(t, (o, p))| l1(*t, *o) - l1(*t, *p)).collect();
        let (gain, se) = linear::stratified_mean_se(&d, &is_own, w_own, w_other);
        (gain / mean_lit, linear::t_statistic(gain, se))
    };
    let (rel, t) = versus(&without);
    // One radiance is rendered only where the split passes against no emission at the lowest bar there is
    // (a white alternative's): elsewhere the split is dropped whatever that comparison says.
    let against_one = if emission_beats(Some([1.0; 3]), t, rel) {
        let mut uniform = params.clone();
        uniform.emission[k] = as_vec3(one);
        Some(versus(&emission_test_arm(ctx, s, &uniform, &px)?))
    } else {
        None
    };
    Ok(SplitLook {
        sky,
        ground,
        one,
        delta,
        rows: rows.len(),
        rel,
        t,
        against_one,
        pred: rows.iter().copied().zip(arm).collect(),
        params: split,
    })
}

/// Drawn pixels of a stratum (the emitter's own pixels, or the others it lights) before the emission test may
/// stop on a clear pass, unless all of the stratum's pixels are in: the standard error of a stratum's mean
/// from fewer is itself too uncertain to rule out chance (with 16 values, the sample standard deviation is
/// within ±35 % of the true one at 95 %).
const STRATUM_PIXELS: usize = 16;

/// Whether every stratum's spread is known well enough for a clear pass: each `(drawn, all)` stratum has at
/// least [`STRATUM_PIXELS`] of its pixels in the look, or all of them. The standard error of a stratum seen in
/// a handful of pixels (a lamp's few own pixels at the first look) can be far too small.
fn strata_known(strata: &[(usize, usize)]) -> bool {
    strata.iter().all(|&(drawn, all)| drawn == all || drawn >= STRATUM_PIXELS)
}

/// Pixels an object must be seen in for its emission to be tested on them ([`glimpse_test`]): with fewer, a
/// paired t-statistic has under 3 degrees of freedom.
const MIN_GLIMPSE_PIXELS: usize = 4;

/// A seen emitter's best lobe without emission ([`best_lobe_without_emission`]) and how it fared on the
/// emitter's own pixels: (relative gain, t) of the emission against the lobe by the L1 of one render each and
/// by the unbiased squared error of two renders at half the paths each (the drop of its root, as in
/// [`Statistic::L1OrSquaredError`]), and of the lobe against the diffuse model without emission.
struct LobeAlternative {
    x: Vec<f64>,
    emission_against_lobe: (f64, f64),
    emission_against_lobe_squared: (f64, f64),
    lobe_against_diffuse: (f64, f64),
}

impl LobeAlternative {
    /// Whether the emission beats the lobe: on the L1 ([`emission_beats`], the lower bar where the lobe's base
    /// colour is white), unless the lobe beats the emission on the unbiased squared error (t > [`T_KEEP`] and a
    /// gain above [`MIN_GAIN`], as a noisier alternative passes in [`Statistic::L1OrSquaredError`]). The L1 of
    /// one render leans to the less noisy model, the emission's, by the lobe's Monte Carlo noise alone: a
    /// polished metal box of the corpus house kept its emission at +10.7 % of the L1 (t = 7.2) against a metal
    /// that fits its pixels 11.3 % better by the squared error (t = 3.6). The squared error alone has little
    /// power on a lamp's few own pixels (a lamp of Modern Hall seen in 4 held-out pixels: +30.9 %, t = 2.9), so
    /// against a lobe inside its domain it decides only against the emission. Against a [`saturated`] lobe it
    /// also decides for it ([`Self::wins_squared_against_white`]).
    fn emission_beats_it(&self, k: usize) -> bool {
        let (rel_q, t_q) = self.emission_against_lobe_squared;
        let lobe_wins_squared = -t_q > T_KEEP && -rel_q > MIN_GAIN;
        (self.passes_on_l1(k) || self.wins_squared_against_white(k)) && !lobe_wins_squared
    }

    /// Whether the emission beats the lobe on the L1 ([`emission_beats`], the lower bar where the lobe's base
    /// colour is white).
    fn passes_on_l1(&self, k: usize) -> bool {
        let (rel, t) = self.emission_against_lobe;
        emission_beats(Some(layout::base_color(&self.x, k)), t, rel)
    }

    /// Whether the emission beats a lobe whose base colour is [`saturated`] on the unbiased squared error (t >
    /// [`T_KEEP`] and a gain above [`MIN_GAIN`]), whatever the L1 says. Such a lobe is the brightest reflector
    /// there is, not a fit: where the photos show more light than it can reflect (a window's sky) it falls short
    /// by much on those pixels, which the squared error weighs and the L1 of the bulk does not. On the corpus
    /// house at seed 4 a seen window pane lost its emission to a white lobe by the L1 (−4.3 %, t = −1.2) that the
    /// squared error refuted (+26.1 %, t = 5.4), and its room went unlit; over 29 object stages of the corpus
    /// house in the cache no other dropped emission had a white lobe (docs/optim/design-measurements.md, "An
    /// emission against a white lobe, by the squared error").
    fn wins_squared_against_white(&self, k: usize) -> bool {
        let (rel_q, t_q) = self.emission_against_lobe_squared;
        saturated(layout::base_color(&self.x, k)) && t_q > T_KEEP && rel_q > MIN_GAIN
    }

    /// "by x % (t = a) of the L1 and y % (t = b) of the RMS error", for a `why`.
    fn figures(&self) -> String {
        let ((rel, t), (rel_q, t_q)) = (self.emission_against_lobe, self.emission_against_lobe_squared);
        format!(
            "by {:+.3} % of the L1 (t = {t:.1}) and {:+.3} % of the RMS error (t = {t_q:.1})",
            100.0 * rel,
            100.0 * rel_q
        )
    }
}

/// The verdict of [`glimpse_test`].
struct Glimpse {
    pixels: usize,
    /// The mean over the tested pixels of their photo radiance summed over the channels (the L1 from 0).
    mean_radiance: f64,
    /// The object's best base colour without emission on the tested pixels (the diffuse alternative).
    base_without: [f64; 3],
    /// Whether the pixels are its own held-out pixels alone (at least [`solve::MIN_PIXELS`] of them), not a
    /// glimpse of a few training and held-out pixels.
    held_only: bool,
    /// Relative gain and t of the emission against the best base colour without it, and against the best lobe
    /// without it (searched only when the first passes).
    against_diffuse: (f64, f64),
    against_lobe: Option<(f64, f64)>,
}

impl Glimpse {
    /// Which pixels, for a `why`: "held-out" or "training and held-out".
    fn kind(&self) -> &'static str {
        if self.held_only { "held-out" } else { "training and held-out" }
    }
}

/// The emission test of an object on the pixels where it is seen, for an emitter that the test on the pixels
/// it lights does not keep: a small lamp lights the room too faintly for that test (Modern Hall's disk and
/// strip lamps: 0.001–0.01 % of the lit pixels' L1, t < 2), while the pixels that see it carry its emission at
/// first order. They are its own held-out pixels when it has at least [`solve::MIN_PIXELS`] of them (up to
/// the test budget); otherwise, a glimpse, its own training and held-out pixels together. Training pixels
/// were fitted with the emission, so each alternative is fitted on the test pixels too, which if anything
/// favours it: the best base colour without emission, and the best lobe without emission (dielectric or
/// metal, which can mirror a light into a small object's pixels). Returns `None` below
/// [`MIN_GLIMPSE_PIXELS`], and for an emission too faint to reach [`MIN_OWN_GAIN`] on any pixel. An emission
/// this test keeps on held-out pixels alone must still carry [`MIN_OWN_SHARE`] of their radiance once the scene
/// is re-fitted.
#[allow(clippy::too_many_arguments)]
fn glimpse_test(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    model: &mut ModelArm<'_>,
    x: &[f64],
    k: usize,
) -> Result<Option<Glimpse>, FitError> {
    let params = model.params;
    let mine = |t: &&Sample| t.object == Some(k as u32);
    let held: Vec<Sample> = sets.holdout.iter().filter(mine).copied().collect();
    let held_only = held.len() >= solve::MIN_PIXELS;
    let rank = |t: &Sample| emission_test_rank(ctx.seed, t.pixel);
    let mut own: Vec<Sample> = if held_only {
        // Enough held-out pixels of its own: the test is on them alone, within the test budget.
        super::pixels::cap_per_object(held, s.holdout_pixels as usize, rank).0
    } else {
        sets.train_of(Some(k as u32)).into_iter().chain(held).collect()
    };
    if own.len() < MIN_GLIMPSE_PIXELS {
        return Ok(None);
    }
    // In rank order, so that the first n pixels of a look are a draw of n.
    own.sort_by(|a, b| rank(a).total_cmp(&rank(b)));
    let tgt: Vec<[f64; 3]> = own.iter().map(target).collect();
    let mean = (tgt.iter().map(|t| l1(*t, [0.0; 3])).sum::<f64>() / tgt.len() as f64).max(f64::MIN_POSITIVE);
    // What the emission adds to a pixel that sees the object fully is Σ_c e_c (and the little of its light that
    // comes back to the object), which bounds its L1 gain on a pixel. Far below the floor, the renders are
    // skipped: the faint emissions the lasso leaves on walls (1e-3 of their radiance on the default scene).
    let e_sum: f64 = (0..3).map(|c| x[idx(k, EMISSION + c)]).sum();
    if e_sum < 0.5 * MIN_OWN_GAIN * mean {
        return Ok(None);
    }
    let no_k = {
        let mut p = params.clone();
        p.emission[k] = glam::Vec3::ZERO;
        p
    };
    // Looks at FIRST_LOOK pixels, then twice as many, like the test on the pixels the light reaches, stopping
    // when the emission cannot reach a significant MIN_OWN_GAIN on all of them ([`cannot_pass`]).
    let n_full = own.len();
    let (mut pred, mut without_fitted, mut col) = (Vec::new(), Vec::new(), Vec::new());
    let mut n = FIRST_LOOK.min(n_full);
    let (against_diffuse, pred, delta) = loop {
        let new_px: Vec<PixelRef> = own[pred.len()..n].iter().map(|t| t.pixel).collect();
        pred.extend(model.on(ctx, s, &new_px)?);
        without_fitted.extend(emission_test_arm(ctx, s, &no_k, &new_px)?);
        col.extend(base_color_column(ctx, s, params, k, &new_px)?);
        let mut without = without_fitted.clone();
        let delta = refit_on_column(x, k, &col, &tgt[..n], &vec![1.0; n], &mut without);
        let d: Vec<f64> = (0..n).map(|j| l1(tgt[j], without[j]) - l1(tgt[j], pred[j])).collect();
        let (gain, se) = linear::mean_se(&d);
        if n == n_full || cannot_pass(gain, se, n, n_full, MIN_OWN_GAIN * mean) {
            break ((gain / mean, linear::t_statistic(gain, se)), pred, delta);
        }
        n = (2 * n).min(n_full);
    };
    let own = &own[..n];
    let tgt = &tgt[..n];
    let paired = |a: &[[f64; 3]]| {
        let d: Vec<f64> = (0..tgt.len()).map(|j| l1(tgt[j], a[j]) - l1(tgt[j], pred[j])).collect();
        let (gain, t) = paired_t(&d);
        (gain / mean, t)
    };
    // The lobe's two roughness searches only when the emission beats the diffuse alternative: most candidates
    // the pixels they light did not keep (walls given a faint emission by the lasso) stop here.
    let px: Vec<PixelRef> = own.iter().map(|t| t.pixel).collect();
    let against_lobe = if glimpse_gain(against_diffuse) {
        let alt = ctx.params(&best_lobe_without_emission(ctx, s, own, x, k)?);
        Some(paired(&emission_test_arm(ctx, s, &alt, &px)?))
    } else {
        None
    };
    let base = layout::base_color(x, k);
    let base_without = std::array::from_fn(|c| (base[c] + delta[c]).clamp(0.0, 1.0));
    Ok(Some(Glimpse { pixels: own.len(), mean_radiance: mean, base_without, held_only, against_diffuse, against_lobe }))
}

/// The smallest relative gain on an object's own pixels for which [`glimpse_test`] keeps its emission: 5 % of
/// their L1. The lamps this test is for gain 16–62 % (Modern Hall's disk and strip lamps, t = 3.6–14), while
/// a surface whose shading the model misses gains a little from a faint emission too: Daylight Room's wall and
/// ceiling, lit through windows whose panes the scan models as uniform emitters, gained 1.0–1.4 % at t = 7–10
/// (docs/optim/design-measurements.md, "Small lamps and per-object step checks"). An emission that changes its own
/// object's fit by less than 5 % is not told apart from such a misfit.
const MIN_OWN_GAIN: f64 = 0.05;

/// The smallest share of its own pixels' radiance that an emission kept by [`glimpse_test`] on its own held-out
/// pixels alone must carry once the scene is re-fitted around the chosen models: its emission summed over the
/// channels over the mean of those pixels' radiance summed the same way. A lamp's own pixels show mostly its
/// emission: the seen lamps and window panes of the corpus house and Daylight Room carry 0.78–3.5 of it (more
/// than 1 where pixel centres straddle a lamp's silhouette). An emission that the pixels it lights do not need
/// and that is a fraction of what its own, well-seen pixels show stands in for a reflection the model misses: a
/// metal box of the corpus house kept the lamps' reflection as an emission of 0.50 of the radiance of its 363
/// held-out pixels, and a ceiling beside a window one of 0.44 on 2048 (docs/scale/README.md, "A share rule for
/// emissions kept by their own pixels"). The threshold sits between the largest false share and the smallest
/// lamp's, near their geometric mean (0.62). A glimpse of a few training and held-out pixels is not held to it:
/// the share of a lamp fitted on 4–49 pixel centres is too noisy to judge (Modern Hall's lamps: 0.60–1.58).
const MIN_OWN_SHARE: f64 = 0.6;

/// Whether an emission's (relative gain, t) on the pixels that see it is significant and large enough.
fn glimpse_gain((gain, t): (f64, f64)) -> bool {
    t > T_KEEP && gain > MIN_OWN_GAIN
}

/// Object k's emission summed over the channels over `mean_radiance` (a mean photo radiance summed the same
/// way, [`Glimpse::mean_radiance`]); for an emitter split at the horizon, the mean of its halves' sums (a sky half
/// graded with elevation counts at the horizon).
fn own_share(x: &[f64], split: &Split, k: usize, mean_radiance: f64) -> f64 {
    let sum = |at: usize| layout::rgb(x, k, at).iter().sum::<f64>();
    let emitted = if split.of(k) { 0.5 * (sum(EMISSION) + sum(EMISSION_GROUND)) } else { sum(EMISSION) };
    emitted / mean_radiance.max(f64::MIN_POSITIVE)
}

/// Decides every object's model; returns the final parameters, the decisions and the emitters split at the
/// horizon ([`horizon`], the last step). Reports its phases to `progress`: the lobe searches (one step per
/// object), the lobe test (blocks of its pixels), the closing re-fits (one step per Gauss–Newton step), the
/// emission test (one step per emitter) and the horizon test.
pub fn choose_models(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    sets: &PixelSets,
    x_fit: &[f64],
    free: &[bool],
    progress: &dyn crate::Progress,
) -> Result<(Vec<f64>, Vec<ObjectModel>, Split), FitError> {
    let k_count = x_fit.len() / PER_OBJECT;
    let mut x = x_fit.to_vec();
    // Without held-out pixels (holdout_fraction = 0) the tests run on training pixels, within the same budget
    // per object, and say so.
    let budget = s.holdout_pixels as usize;
    let capped_train;
    let (test, test_name): (&[Sample], &str) = if sets.holdout.is_empty() {
        let rank = |t: &Sample| streams::uniform(ctx.seed, draw::HOLDOUT, streams::pixel_key(t.pixel), 1);
        capped_train = super::pixels::cap_per_object(sets.train.clone(), budget, rank).0;
        (&capped_train, "training")
    } else {
        (&sets.holdout, "held-out")
    };
    let pix: Vec<PixelRef> = test.iter().map(|t| t.pixel).collect();
    let mean_target = test.iter().map(|t| l1(target(t), [0.0; 3])).sum::<f64>() / test.len().max(1) as f64;
    let mut why: Vec<Vec<String>> = vec![Vec::new(); k_count];

    // Specular lobe trial.
    let mut glossy = vec![false; k_count];
    // The emitters that the re-fit with the lobes took to 0 in every channel (for their `why`).
    let mut refit_zeroed = vec![false; k_count];
    let try_lobes = s.try_specular && free.iter().any(|&f| f);
    // The pixels of the lobe tests, for the first look below and the second look at the end.
    let lobe_test = if try_lobes { lobe_test_samples(ctx, sets, test, budget) } else { Vec::new() };
    if try_lobes {
        // Each object's lobe from a 1-D search on roughness with base colour and specular profiled out
        // ([`roughness`]), on its own training pixels, the other objects diffuse as fitted.
        // Half of every object's training pixels choose its lobe; the other half join the held-out pixels in
        // the test that decides whether to keep it (the lobe was not fitted on them, and a small glossy object
        // has too few held-out pixels alone: the box of the glossy fixture has ~60, and its highlight pixels
        // make the paired differences noisy). The test's pixels per object stay within the held-out budget:
        // all of its held-out pixels, then training pixels up to the budget (2048 detect a 4 % gain on glossy
        // highlights at t > 3, `object.holdout_pixels` in configs/README.md; a large object's 4096 doubled the
        // test's renders, the largest cost of a 213-object house's object stage).
        let mut xt = x.clone();
        let mut tested: Vec<bool> = free.to_vec();
        let n_free = free.iter().filter(|&&f| f).count();
        progress.phase("model selection: lobe search, object", n_free as u64, 0);
        for (done, k) in (0..k_count).filter(|&k| free[k]).enumerate() {
            check_stop(progress)?;
            let samples = profile_samples(ctx, sets, k);
            let mut base = x.clone();
            base[idx(k, SPECULAR)] = TRIAL_SPECULAR;
            base[idx(k, ROUGHNESS)] = TRIAL_ROUGHNESS;
            let (best, evals) = roughness::search_lobe(
                ctx,
                &base,
                k,
                &samples,
                roughness::profile_spp(s.solve_spp),
                key::SELECT_ROUGHNESS + k as u64,
            )?;
            tracing::debug!(object = k, ?best, evals = evals.len(), "lobe search");
            progress.set_position(done as u64 + 1);
            // A lobe that lowers the object's profile loss below its best Lambert surface's by less than the lobe
            // test's gain needs (per channel: `mean_target` sums the channels) at every roughness searched is not
            // tested: the held-out gain of a lobe chosen on other pixels is if anything smaller. Nor where it
            // buys less than the search's own margin on the object's pixels, below which the search calls its
            // lobe's effect on the photos flat (`roughness::FLAT_PROFILE`). Its alternative stays diffuse.
            let needs = (FLAT_PROFILE * roughness::mean_target(&samples)).min(MIN_GAIN * mean_target / 3.0);
            if !roughness::lobe_pays(&evals, needs) {
                tested[k] = false;
                why[k].push(format!(
                    "diffuse: no specular lobe searched lowers its profile L1 below its Lambert surface's by \
                     {:.2} % of the mean radiance (at most {:.2} %; the lobe test needs {:.1} %)",
                    100.0 * needs / (mean_target / 3.0),
                    100.0 * roughness::lobe_gain(&evals).unwrap_or(0.0) / (mean_target / 3.0),
                    100.0 * MIN_GAIN,
                ));
                continue;
            }
            for c in 0..3 {
                xt[idx(k, BASE_COLOR + c)] = best.base_color[c];
            }
            xt[idx(k, ROUGHNESS)] = best.roughness;
            xt[idx(k, SPECULAR)] = best.specular;
            xt[idx(k, METALLIC)] = best.metallic;
        }
        let verdicts = sequential_lobe_test(
            ctx,
            s,
            Statistic::L1,
            &lobe_test,
            &tested,
            (&x, &xt),
            mean_target,
            key::SELECT_LOBE_TEST,
            progress,
            "lobe test",
        )?;
        for (k, v) in verdicts.iter().enumerate().filter_map(|(k, v)| v.as_ref().map(|v| (k, v))) {
            let (rel, t) = v.gain(mean_target);
            let on = v.on();
            if v.passes(mean_target) {
                glossy[k] = true;
                layout::copy_material(&mut x, &xt, k);
                why[k].push(format!(
                    "specular lobe (roughness {:.3}, specular {:.3}, metallic {:.3}) kept: it lowers the {test_name} L1 by {:.1} % of the mean radiance on {on} (t = {t:.1})",
                    xt[idx(k, ROUGHNESS)],
                    xt[idx(k, SPECULAR)],
                    xt[idx(k, METALLIC)],
                    100.0 * rel,
                ));
            } else {
                why[k].push(format!(
                    "diffuse: the best specular lobe (roughness {:.3}, specular {:.3}, metallic {:.3}) changed the {test_name} L1 by {:+.2} % on {on} (t = {t:.1}; needs t > {T_KEEP} and > {:.1} %)",
                    xt[idx(k, ROUGHNESS)],
                    xt[idx(k, SPECULAR)],
                    xt[idx(k, METALLIC)],
                    -100.0 * rel,
                    100.0 * MIN_GAIN
                ));
            }
        }
        if glossy.iter().any(|&g| g) {
            // With the lobes in place, the emission is re-solved (materials fixed; the default), or
            // `specular_trial_steps` Gauss–Newton steps re-fit emission and base colour (lobes fixed), averaged
            // over their second half like the refinement. The steps were needed while the L1 refinement gave
            // the glossy floor's reflected light to the other surfaces (light 2–5 % low); with the per-object
            // Huber data term the refinement's light is right before the lobes, and the steps, which pin the
            // light by the lobe's noisy specular strength, moved it by up to +10 %
            // (docs/optim/design-measurements.md, "Solve pixels per object and the checker light").
            let steps = s.specular_trial_steps;
            let unknowns = if steps == 0 { Unknowns::Emission } else { Unknowns::EmissionAndBaseColor };
            // A re-fit, not a choice of emitters: the emitters the refinement left, unpenalised, and every
            // other object held at 0; which of them emit is the emission test's decision, below. Penalised, this
            // solve dropped a 19.5 m² lamp that no photo sees, which the refinement had within 12 % of its truth, and
            // made 54 new emitters of a house's walls and boxes for the emission test to reject
            // (docs/optim/design-measurements.md, "The re-fit with the lobes chooses no emitters").
            let emits_nothing = |x: &[f64], k: usize| {
                (0..3).all(|c| x[idx(k, EMISSION + c)] == 0.0 && x[idx(k, EMISSION_GROUND + c)] == 0.0)
            };
            let dark: Vec<bool> = (0..k_count).map(|k| emits_nothing(&x, k)).collect();
            let unpenalised = ObjectFitSettings { emission_l1: 0.0, ..s.clone() };
            let run = AveragedSteps {
                unknowns,
                support: Support::Current,
                steps: steps.max(1),
                key: key::SELECT_SPECULAR_STEPS,
            };
            progress.phase("model selection: re-fit with the lobes, step", u64::from(run.steps), 0);
            run.apply(ctx, &unpenalised, sets, &mut x, free, &dark, progress)?;
            for k in (0..k_count).filter(|&k| !dark[k]) {
                refit_zeroed[k] = emits_nothing(&x, k);
            }
        }
    }

    // Emission test, per emitter k, on the test pixels its light reaches: a pilot basis render of every
    // emitter's column over all test pixels (radiance is linear in emission: the column is ∂I/∂e_k) marks the
    // pixels where k's light arrives; up to `holdout_pixels` of them (seeded draws, see below) are rendered
    // with the fitted model and without k's emission at `holdout_spp`. The pilot gets one object's path
    // budget per column (`basis_spp`), a path or two per pixel on a house: enough to find where a light
    // arrives, while testing on the pilot's own noisy columns dropped hidden lights (a house's uplights,
    // t < 3 against 171 k pixels at 1.5 paths each). The pixels are chosen with the pilot's random numbers
    // and tested with fresh ones.
    let params = ctx.params(&x);
    let emitters: Vec<usize> = (0..k_count).filter(|&k| (0..3).any(|c| x[idx(k, EMISSION + c)] != 0.0)).collect();
    progress.phase(
        &format!("model selection: emission test on {} pixels, emitter", pix.len()),
        emitters.len() as u64,
        0,
    );
    let pilot_spp = super::emission_solve::basis_spp(s.solve_spp, budget, pix.len());
    // Where each emitter's light arrives, from the pilot columns (fixed by the materials the test starts from,
    // so all are rendered up front), PILOT_COLUMNS columns per render: their paths are traced once per
    // render, and the columns in memory stay a bounded number × the test pixels.
    let mut lit_of: Vec<Vec<usize>> = vec![Vec::new(); k_count];
    for chunk in emitters.chunks(PILOT_COLUMNS) {
        let wanted: Vec<bool> = (0..k_count).map(|o| chunk.contains(&o)).collect();
        let pilot = jacobian::emission_columns_of(
            ctx,
            &params.materials,
            &pix,
            pilot_spp,
            key::SELECT_EMISSION_COLUMNS,
            &wanted,
        )?;
        for &k in chunk {
            lit_of[k] = (0..test.len()).filter(|&j| pilot[k][j].iter().any(|&v| v != 0.0)).collect();
        }
    }
    let mut model = ModelArm { params: &params, at: std::collections::HashMap::new() };
    let mut emits = vec![false; k_count];
    // The test rows an emitter's light reaches, kept for the horizon test of the kept emitters that face
    // sideways (`horizon`).
    let sided = horizon::sided(ctx);
    let mut horizon_lit: Vec<Vec<usize>> = vec![Vec::new(); k_count];
    // The emitters that the horizon step could split, and the halves of those whose emission only the split
    // kept ([`split_look`]): the re-fit after the test starts from them.
    let emitting: Vec<bool> = (0..k_count).map(|k| emitters.contains(&k)).collect();
    let splittable = horizon::splittable(ctx, sets, &emitting);
    let mut kept_split: Vec<Option<([f64; 3], [f64; 3])>> = vec![None; k_count];
    let mut material_refit = false;
    // Per emitter kept by its own held-out pixels alone: the mean radiance of the pixels that kept it and its
    // best base colour without emission there (for the share rule after the re-fit, [`MIN_OWN_SHARE`]).
    let mut glimpse_kept_by: Vec<Option<(f64, [f64; 3])>> = vec![None; k_count];
    let mut tested = 0;
    for k in 0..k_count {
        let e = [x[idx(k, EMISSION)], x[idx(k, EMISSION + 1)], x[idx(k, EMISSION + 2)]];
        if e.iter().all(|&v| v == 0.0) {
            why[k].push(if refit_zeroed[k] {
                "no emission: the re-fit of the emission with the lobes in place (materials fixed, unpenalised) \
                 took it to 0"
                    .into()
            } else {
                "no emission: the L1-penalised emission solve set it to 0".into()
            });
            continue;
        }
        progress.set_position(tested);
        check_stop(progress)?;
        tested += 1;
        let lit = std::mem::take(&mut lit_of[k]);
        // The emitter's own pixels (where its emission is seen directly) and the others it lights, each drawn
        // up to half the budget plus the other's unused share: drawn from all lit pixels alike, a small visible
        // lamp's few dozen own pixels, which carry most of the evidence, were a heavy tail of the paired
        // differences (a house's visible ceiling lights, 12 % gains at t = 2.5, were dropped).
        let rank = |j: usize| emission_test_rank(ctx.seed, pix[j]);
        // Each stratum in rank order, so that its first n pixels are a draw of n.
        let ranked = |mut v: Vec<usize>, n: usize| -> Vec<usize> {
            v.sort_by(|&a, &b| rank(a).total_cmp(&rank(b)).then(a.cmp(&b)));
            v.truncate(n);
            v
        };
        let (own, other): (Vec<usize>, Vec<usize>) = lit.iter().partition(|&&j| test[j].object == Some(k as u32));
        let n_own = own.len().min((budget / 2).max(budget.saturating_sub(other.len())));
        let n_other = other.len().min(budget - n_own);
        // Each stratum stands for its share of the lit pixels (stratified sampling): the test estimates the
        // mean over all lit pixels, as an unstratified test would, only with less variance. Weighting the
        // two halves equally instead kept faint emissions on Daylight Room's ceiling and wall (0.2–0.6 %
        // gains on their own pixels, which the rest of the room they light does not share).
        let share = |n_total: usize, n_drawn: usize| n_total as f64 / lit.len().max(1) as f64 / n_drawn.max(1) as f64;
        let (n_lit_own, n_lit_other) = (own.len(), other.len());
        let (own, other) = (ranked(own, n_own), ranked(other, n_other));
        let n_full = n_own + n_other;
        if n_full < 2 {
            why[k].push(format!(
                "emission {e:.4?} dropped: its light reaches {n_full} {test_name} pixels, too few to test"
            ));
            continue;
        }
        // The fitted model and the model without k's emission, rendered with the same random numbers: both arms
        // carry the same kind of Monte Carlo noise. (The render minus a separately estimated J_k e_k has the
        // column's noise in one arm only; the L1 of the noisier arm is larger on average, which kept spurious
        // faint emissions on Daylight Room's ceiling and wall.)
        let arm_on = |params: &tracer::Params, pixels: &[PixelRef]| emission_test_arm(ctx, s, params, pixels);
        let no_k = {
            let mut p = params.clone();
            p.emission[k] = glam::Vec3::ZERO;
            p
        };
        // The test looks at FIRST_LOOK of the drawn pixels, then twice as many per look (each stratum in
        // proportion), and stops when it cannot pass on all of them ([`cannot_pass`]) or would pass on all of
        // them beyond reasonable doubt ([`clearly_passes`]: a visible lamp or window gains at t = 7–240 on its
        // 2048 pixels, docs/optim/design-measurements.md); a test that goes on to all of them is decided on
        // exactly the renders of a single look (every estimate is keyed by the pixel).
        // Per test pixel: the two arms and k's base-colour column.
        let mut cache: std::collections::HashMap<usize, ArmsAt> = std::collections::HashMap::new();
        // Renders the arms (and, for a free base colour, the column) of the test rows `rows` not yet in `cache`.
        let fill = |cache: &mut std::collections::HashMap<usize, ArmsAt>,
                    model: &mut ModelArm<'_>,
                    rows: &[usize]|
         -> Result<(), FitError> {
            let new: Vec<usize> = rows.iter().copied().filter(|j| !cache.contains_key(j)).collect();
            if new.is_empty() {
                return Ok(());
            }
            let new_px: Vec<PixelRef> = new.iter().map(|&j| pix[j]).collect();
            let new_pred = model.on(ctx, s, &new_px)?;
            let new_without = arm_on(&no_k, &new_px)?;
            let new_col =
                if free[k] { base_color_column(ctx, s, &params, k, &new_px)? } else { vec![[0.0; 3]; new.len()] };
            for (i, &j) in new.iter().enumerate() {
                cache.insert(j, ArmsAt { pred: new_pred[i], without: new_without[i], column: new_col[i] });
            }
            Ok(())
        };
        let mut look_size = FIRST_LOOK.min(n_full);
        let EmissionLook { on, mean_lit, delta, gain, t, stopped } = loop {
            let part = |n: usize| if look_size >= n_full { n } else { (n * look_size).div_ceil(n_full) };
            let (a, b) = (part(n_own), part(n_other));
            let mut on: Vec<usize> = own[..a].iter().chain(&other[..b]).copied().collect();
            on.sort_unstable();
            fill(&mut cache, &mut model, &on)?;
            let (w_own, w_other) = (share(n_lit_own, a), share(n_lit_other, b));
            let tgt: Vec<[f64; 3]> = on.iter().map(|&j| target(&test[j])).collect();
            let is_own: Vec<bool> = on.iter().map(|&j| test[j].object == Some(k as u32)).collect();
            // Row weights summing to 1 over the drawn pixels.
            let row_w: Vec<f64> = is_own.iter().map(|&o| if o { w_own } else { w_other }).collect();
            // The same weights at mean 1 for the refit's solve.
            let solve_w: Vec<f64> = row_w.iter().map(|w| w * row_w.len() as f64).collect();
            let pred: Vec<[f64; 3]> = on.iter().map(|j| cache[j].pred).collect();
            let mut without: Vec<[f64; 3]> = on.iter().map(|j| cache[j].without).collect();
            let col: Vec<[f64; 3]> = on.iter().map(|j| cache[j].column).collect();
            // The model without an object's emission gets its own best base colour: a visible surface's
            // emission and albedo both explain its brightness, and comparing at the albedo fitted *with* the
            // emission favours keeping it. Measured on a room lit by a small lamp 1e4× brighter than the walls
            // (tests/stability_extremes.rs): without the refit the ceiling kept an emission of 1.6e-4 of the
            // lamp (held-out gain 1.1 %, t > 3) and an albedo 0.09–0.17 too dark. The refit is a 1-variable L1
            // fit per channel on the test pixels themselves, which if anything favours the smaller model.
            let delta = if free[k] { refit_on_column(&x, k, &col, &tgt, &solve_w, &mut without) } else { [0.0; 3] };
            let d: Vec<f64> =
                tgt.iter().zip(without.iter().zip(&pred)).map(|(t, (w, p))| l1(*t, *w) - l1(*t, *p)).collect();
            let (gain, se) = linear::stratified_mean_se(&d, &is_own, w_own, w_other);
            let mean_lit = tgt.iter().zip(&row_w).map(|(t, w)| w * l1(*t, [0.0; 3])).sum::<f64>();
            let full = on.len() == n_full;
            let min_gain = MIN_GAIN * 1e-2 * mean_lit;
            let stopped = if full {
                None
            } else if cannot_pass(gain, se, on.len(), n_full, min_gain) {
                Some(Stop::CannotPass)
            } else if strata_known(&[(a, n_own), (b, n_other)]) && clearly_passes(gain, se, on.len(), n_full, min_gain)
            {
                Some(Stop::ClearlyPasses)
            } else {
                None
            };
            if full || stopped.is_some() {
                let t = linear::t_statistic(gain, se);
                break EmissionLook { on, mean_lit, delta, gain, t, stopped };
            }
            look_size *= 2;
        };
        let rel = gain / mean_lit.max(f64::MIN_POSITIVE);
        let beats = |t: f64, rel: f64| emission_beats(None, t, rel);
        let base = layout::base_color(&x, k);
        let base_without: [f64; 3] = std::array::from_fn(|c| base[c] + delta[c]);
        let light_keeps = emission_beats(free[k].then_some(base_without), t, rel);
        // A sideways emitter that the horizon step could split and that this test does not keep as one
        // radiance in every direction is tested again split, on every drawn row ([`split_look`]).
        let split = if !light_keeps && splittable.of(k) {
            let mut rows: Vec<usize> = own.iter().chain(&other).copied().collect();
            rows.sort_unstable();
            fill(&mut cache, &mut model, &rows)?;
            let weights = (share(n_lit_own, n_own), share(n_lit_other, n_other));
            let up = splittable.up;
            Some(split_look(ctx, s, (&params, &x, k, free[k]), up, &rows, (&pix, test), &cache, weights)?)
        } else {
            None
        };
        let split_keeps = split.as_ref().is_some_and(|l| {
            let base_without: [f64; 3] = std::array::from_fn(|c| base[c] + l.delta[c]);
            emission_beats(free[k].then_some(base_without), l.t, l.rel) && l.split_pays()
        });
        // The kept model's test: the split one's where only it keeps the emission.
        let (t_kept, delta_kept) = match &split {
            Some(l) if split_keeps => (l.t, l.delta),
            _ => (t, delta),
        };
        // An object the photos see may look like an emitter because it mirrors one: a rough metal beside a
        // lamp is bright from most views, and with a diffuse lobe only an emission reproduces it (Modern Hall's
        // `Metal` kept the colour of the light above it as its emission). So a seen emitter's emission must
        // also beat its best lobe without emission, dielectric or metal, with the same random numbers, on its
        // own pixels: there the two models differ to first order, while the pixels it lights were fitted
        // around the incumbent model (a metal box under a lamp lost to its own emission by 4.8 % on all the
        // lit pixels and won by a wide margin on its own).
        // The comparison is on all the drawn own pixels, also when the test stopped on a clear pass before it
        // looked at them all: a light that clearly lights the room is still held to its lobe alternative on
        // every own pixel the full test would have used (their arms are rendered here if the looks had not).
        let mut lobe: Option<LobeAlternative> = None;
        let mut own_rows: Vec<usize> = own.clone();
        own_rows.sort_unstable();
        if (light_keeps || split_keeps) && free[k] && own_rows.len() >= 2 {
            fill(&mut cache, &mut model, &own_rows)?;
            let x_alt = best_lobe_without_emission(ctx, s, &profile_samples(ctx, sets, k), &x, k)?;
            let own_px: Vec<PixelRef> = own_rows.iter().map(|&j| pix[j]).collect();
            let own_tgt: Vec<[f64; 3]> = own_rows.iter().map(|&j| target(&test[j])).collect();
            let own_pred: Vec<[f64; 3]> = own_rows
                .iter()
                .map(|j| match &split {
                    Some(l) if split_keeps => l.pred[j],
                    _ => cache[j].pred,
                })
                .collect();
            // The diffuse model without emission at the base colour refitted by the test (`delta_kept`).
            let own_without: Vec<[f64; 3]> = own_rows
                .iter()
                .map(|j| {
                    let (w, col) = (cache[j].without, cache[j].column);
                    std::array::from_fn(|c| w[c] + col[c] * delta_kept[c])
                })
                .collect();
            let alt_params = ctx.params(&x_alt);
            let alt = arm_on(&alt_params, &own_px)?;
            // Both models rendered twice more at half the paths each, for the unbiased squared error: the kept
            // model (the split one where only it keeps the emission) and the lobe.
            let kept_params = match &split {
                Some(l) if split_keeps => &l.params,
                _ => &params,
            };
            let halves = |p: &tracer::Params| -> Result<Vec<[glam::Vec3; 2]>, FitError> {
                let [(spp_a, key_a), (spp_b, key_b)] = paired::half_paths(s.holdout_spp, key::SELECT_EMISSION_TEST);
                let (a, b) = (ctx.render(p, &own_px, spp_a, key_a)?, ctx.render(p, &own_px, spp_b, key_b)?);
                Ok(a.into_iter().zip(b).map(|(a, b)| [a, b]).collect())
            };
            let (kept_halves, alt_halves) = (halves(kept_params)?, halves(&alt_params)?);
            let rows: Vec<usize> = (0..own_px.len()).collect();
            let (_, squared) =
                paired::differences(Statistic::L1OrSquaredError, |i| own_tgt[i], &rows, &alt_halves, &kept_halves);
            let mean_own = own_tgt.iter().map(|t| l1(*t, [0.0; 3])).sum::<f64>() / own_rows.len() as f64;
            let mean_own = mean_own.max(f64::MIN_POSITIVE);
            let paired = |a: &[[f64; 3]], b: &[[f64; 3]]| {
                let d: Vec<f64> = (0..own_tgt.len()).map(|i| l1(own_tgt[i], a[i]) - l1(own_tgt[i], b[i])).collect();
                let (gain, t) = paired_t(&d);
                (gain / mean_own, t)
            };
            // The emission against the lobe, and the lobe against the diffuse model without emission (the
            // refitted `without` arm). Random numbers are keyed by the pixel, so the own pixels of the arms
            // rendered above are the same estimates as a render of these pixels alone.
            lobe = Some(LobeAlternative {
                emission_against_lobe: paired(&alt, &own_pred),
                emission_against_lobe_squared: squared.expect("two renders per model").gain(mean_own),
                lobe_against_diffuse: paired(&own_without, &alt),
                x: x_alt,
            });
        }
        let lobe_wins = lobe.as_ref().is_some_and(|l| !l.emission_beats_it(k));
        // A kept emission's comparison with its lobe alternative on its own pixels, and where the lower bar for a
        // white alternative decided it (its test on the pixels its light reaches at `t`, `rel`), for its reason.
        let kept_note = |t: f64, rel: f64| -> String {
            let mut note = lobe.as_ref().map_or(String::new(), |a| {
                format!("; against its best lobe without emission {} on its {} own pixels", a.figures(), own_rows.len())
            });
            // Kept against a white lobe by the squared error, the L1 not passing even at the lower bar.
            let by_squared = lobe.as_ref().is_some_and(|a| a.wins_squared_against_white(k) && !a.passes_on_l1(k));
            if by_squared {
                note.push_str(
                    "; its best lobe without emission has a base colour at the top of its domain (white), and the \
                     emission beats it on the RMS error, whatever the L1 says",
                );
            } else if !beats(t, rel)
                || lobe.as_ref().is_some_and(|a| !beats(a.emission_against_lobe.1, a.emission_against_lobe.0))
            {
                note.push_str(&format!(
                    "; its best material without emission has a base colour at the top of its domain (white), which \
                     holds the emission to t > {T_SATURATED} instead of {T_KEEP}"
                ));
            }
            note
        };
        // An emitter the pixels it lights do not keep is tested where it is seen ([`glimpse_test`]).
        let glimpse = if !light_keeps && !split_keeps { glimpse_test(ctx, s, sets, &mut model, &x, k)? } else { None };
        let glimpse_kept = glimpse
            .as_ref()
            .filter(|g| glimpse_gain(g.against_diffuse))
            .and_then(|g| g.against_lobe.filter(|&l| glimpse_gain(l)).map(|l| (g, l)));
        if let Some((g, lobe)) = glimpse_kept {
            emits[k] = true;
            if g.held_only {
                glimpse_kept_by[k] = Some((g.mean_radiance, g.base_without));
            }
            why[k].push(format!(
                "emission kept: the {} {} pixels that see it are fitted better with it than with its best base \
                 colour without emission (L1 {:.1} % lower, t = {:.1}) and than with its best lobe without emission \
                 ({:.1} % lower, t = {:.1}); the pixels its light reaches alone would not keep it ({:+.4} %, t = \
                 {t:.1})",
                g.pixels,
                g.kind(),
                100.0 * g.against_diffuse.0,
                g.against_diffuse.1,
                100.0 * lobe.0,
                lobe.1,
                -100.0 * rel
            ));
        } else if let Some(l) = split.as_ref().filter(|_| split_keeps && !lobe_wins) {
            emits[k] = true;
            kept_split[k] = Some((l.sky, l.ground));
            let against_lobe = kept_note(l.t, l.rel);
            let (rel_one, t_one) = l.against_one.expect("a kept split beat one radiance (SplitLook::split_pays)");
            why[k].push(format!(
                "emission kept split at the horizon: as one radiance in every direction it changes the {test_name} \
                 L1 of the {} pixels its light reaches (of {}) by {:+.3} % (t = {t:.1}), but with its two halves \
                 fitted on all {} drawn (sky {:.4?}, ground {:.4?}) it lowers it by {:.3} % of their mean radiance \
                 (t = {:.1}), and by {:.3} % (t = {t_one:.1}) against one radiance {:.4?} fitted there{against_lobe}",
                on.len(),
                lit.len(),
                -100.0 * rel,
                l.rows,
                l.sky,
                l.ground,
                100.0 * l.rel,
                l.t,
                100.0 * rel_one,
                l.one
            ));
        } else if light_keeps && !lobe_wins {
            emits[k] = true;
            let against_lobe = kept_note(t, rel);
            let stop = if let Some(stop @ Stop::ClearlyPasses) = stopped {
                format!(" (stopped there, of {n_full} drawn: {})", stop.reason())
            } else {
                String::new()
            };
            why[k].push(format!(
                "emission kept: without it the {test_name} L1 of the {} pixels its light reaches (of {}){stop} rises \
                 by {:.3} % of their mean radiance (t = {t:.1}){against_lobe}",
                on.len(),
                lit.len(),
                100.0 * rel
            ));
        } else if let Some(alternative) = lobe.filter(|_| lobe_wins) {
            let figures = alternative.figures();
            let LobeAlternative { x: x_alt, lobe_against_diffuse: (rel_lobe, t_lobe), .. } = alternative;
            let (r, m, sp) = (x_alt[idx(k, ROUGHNESS)], x_alt[idx(k, METALLIC)], x_alt[idx(k, SPECULAR)]);
            let kind = if m > 0.5 { "metal" } else { "dielectric" };
            let adopt = t_lobe > T_KEEP && rel_lobe > MIN_GAIN;
            if adopt {
                glossy[k] = true;
                layout::copy_material(&mut x, &x_alt, k);
                // The rest of the scene was fitted around the emission (a metal box's emission had the lamp
                // 11 % bright and the walls 5 % dark): emission and base colours are re-fitted below.
                material_refit = true;
            } else if delta_kept.iter().any(|d| d.abs() > REFIT_MATERIAL) {
                material_refit = true;
            }
            let early = if split_keeps {
                " split at the horizon".to_owned()
            } else if stopped == Some(Stop::ClearlyPasses) {
                format!(" on {} of the {n_full} pixels drawn among those its light reaches", on.len())
            } else {
                String::new()
            };
            why[k].push(format!(
                "emission {e:.4?} dropped: it beats the diffuse model without it{early} (t = {t_kept:.1}) but not its best \
                 {kind} lobe without emission on its {} own pixels (roughness {r:.3}, specular {sp:.3}: the emission \
                 changes the {test_name} pixels' fit {figures}; it needs t > {T_KEEP} on the L1, or on the RMS error \
                 against a white lobe, and the lobe wins where its RMS error is lower at t > {T_KEEP}); {}",
                own_rows.len(),
                if adopt {
                    format!(
                        "the lobe is kept (it lowers the L1 by {:.2} % against diffuse, t = {t_lobe:.1})",
                        100.0 * rel_lobe
                    )
                } else {
                    format!("diffuse, as the lobe does not beat it (t = {t_lobe:.1})")
                }
            ));
        } else {
            if delta.iter().any(|d| d.abs() > REFIT_MATERIAL) {
                material_refit = true;
            }
            let glimpsed = glimpse.as_ref().map_or(String::new(), |g| {
                let lobe = g.against_lobe.map_or(String::new(), |(gain, t)| {
                    format!(" and its best lobe without emission by {:.1} % (t = {t:.1})", 100.0 * gain)
                });
                format!(
                    "; on the {} {} pixels that see it, it beats its best base colour without emission by {:.1} % (t = \
                     {:.1}){lobe} (each needs t > {T_KEEP} and > {:.0} %)",
                    g.pixels,
                    g.kind(),
                    100.0 * g.against_diffuse.0,
                    g.against_diffuse.1,
                    100.0 * MIN_OWN_GAIN
                )
            });
            let stop = if let Some(stop @ Stop::CannotPass) = stopped {
                format!(" (stopped there, of {n_full} drawn: {})", stop.reason())
            } else {
                String::new()
            };
            let split_tried = split.as_ref().map_or(String::new(), |l| {
                let one = l.against_one.map_or(String::new(), |(rel_one, t_one)| {
                    format!(
                        ", {:+.4} % (t = {t_one:.1}) against one radiance {:.4?} fitted there (a split needs t > \
                         {T_KEEP} and > {:.1} % against it)",
                        -100.0 * rel_one,
                        l.one,
                        100.0 * MIN_GAIN
                    )
                });
                format!(
                    "; split at the horizon with its halves fitted on all {} drawn (sky {:.4?}, ground {:.4?}), \
                     {:+.4} % (t = {:.1}){one}",
                    l.rows,
                    l.sky,
                    l.ground,
                    -100.0 * l.rel,
                    l.t
                )
            });
            why[k].push(format!(
                "emission {e:.4?} dropped: on the {} {test_name} pixels its light reaches (of {}){stop} it changes \
                 the L1 by {:+.4} % (t = {t:.1}; needs t > {T_KEEP}){split_tried}; without it the best base colour \
                 differs by {delta:+.3?}{glimpsed}",
                on.len(),
                lit.len(),
                -100.0 * rel
            ));
        }
        if emits[k] && sided[k] {
            horizon_lit[k] = lit;
        }
    }
    progress.set_position(tested);
    for k in (0..k_count).filter(|&k| !emits[k]) {
        for c in 0..3 {
            x[idx(k, EMISSION + c)] = 0.0;
        }
    }
    // Emitters that face sideways may send their light one way down and another up (`horizon`): the re-fit
    // below runs with every candidate split, then each is tested.
    let all = horizon::candidates(&splittable, &horizon_lit, &mut x, &emits);
    // An emission that only its split kept starts the re-fit from the halves its test fitted.
    for (k, (sky, ground)) in kept_split.iter().enumerate().filter_map(|(k, h)| h.map(|h| (k, h))) {
        if all.of(k) {
            for c in 0..3 {
                (x[idx(k, EMISSION + c)], x[idx(k, EMISSION_GROUND + c)]) = (sky[c], ground[c]);
                x[idx(k, EMISSION_ZENITH + c)] = sky[c];
            }
        }
    }
    let ctx_all = Ctx { split: &all, ..*ctx };
    if material_refit || !all.is_empty() {
        // A dropped emission had been standing in for albedo, or the albedos were fitted under uniform emitters
        // that the horizon test may split: re-fit emission and base colour under the chosen model
        // (non-emitters pinned at 0), averaging the steps' second half like the refinement. A hidden light the
        // emission test kept is still an unknown of the next step after one that takes it to 0.
        let no_emission: Vec<bool> = emits.iter().map(|e| !e).collect();
        let run = AveragedSteps {
            unknowns: Unknowns::EmissionAndBaseColor,
            support: Support::KeepHidden,
            steps: s.refine_steps.max(2),
            key: key::SELECT_EMISSION_REFIT,
        };
        let why_refit = match (material_refit, all.is_empty()) {
            (true, true) => "a dropped emission",
            (false, _) => "splitting emitters at the horizon",
            (true, false) => "a dropped emission, with emitters split at the horizon",
        };
        progress.phase(&format!("model selection: re-fit after {why_refit}, step"), u64::from(run.steps), 0);
        run.apply(&ctx_all, s, sets, &mut x, free, &no_emission, progress)?;
        // The re-fit may take a kept emission to 0 (the solve's bounds): its model then has none.
        for k in 0..k_count {
            let ground_dark = !all.of(k)
                || (0..3).all(|c| x[idx(k, EMISSION_GROUND + c)] == 0.0 && x[idx(k, EMISSION_ZENITH + c)] == 0.0);
            if emits[k] && (0..3).all(|c| x[idx(k, EMISSION + c)] == 0.0) && ground_dark {
                emits[k] = false;
                why[k].push("the re-fit after a dropped emission set this emission to 0".into());
            }
        }
    }
    // The share rule ([`MIN_OWN_SHARE`]) on the emissions that their own held-out pixels alone kept, as the
    // re-fit left them: the emission the test started from is larger than the one the scene keeps around it. A
    // dropped one takes the best base colour without emission that its own pixels gave; the rest of the scene
    // keeps its fit, since the pixels its light reaches did not need the emission (a second re-fit of the whole
    // scene for it took a lamp no photo sees from 35 % to 100 % off in blue on the corpus house:
    // docs/scale/README.md, "A share rule for emissions kept by their own pixels").
    let mut all = all;
    for k in 0..k_count {
        let Some((mean_radiance, base_without)) = glimpse_kept_by[k].filter(|_| emits[k]) else { continue };
        let share = own_share(&x, &all, k, mean_radiance);
        if share >= MIN_OWN_SHARE {
            why[k].push(format!(
                "after the re-fit its emission is {share:.2} of the mean radiance of the pixels that kept it (needs \
                 at least {MIN_OWN_SHARE})"
            ));
            continue;
        }
        let e = layout::rgb(&x, k, EMISSION);
        why[k].push(format!(
            "emission {e:.4?} dropped after the re-fit: it is {share:.2} of the mean radiance of the pixels that kept \
             it (an emission that only its own pixels keep must carry at least {MIN_OWN_SHARE} of it; less stands in \
             for a reflection the model misses); base colour {base_without:.3?}, the best without emission there"
        ));
        emits[k] = false;
        for at in [EMISSION, EMISSION_GROUND, EMISSION_ZENITH] {
            layout::set_rgb(&mut x, k, at, [0.0; 3]);
        }
        layout::set_rgb(&mut x, k, BASE_COLOR, base_without);
        if let Some(split) = all.split.get_mut(k) {
            *split = false;
        }
    }
    let ctx_all = Ctx { split: &all, ..*ctx };
    let split = if all.is_empty() {
        all
    } else {
        horizon::test(&ctx_all, s, (test, test_name), &horizon_lit, &mut x, &mut why, progress)?
    };
    if try_lobes {
        let ctx_split = Ctx { split: &split, ..*ctx };
        family::second_look(
            &ctx_split,
            s,
            sets,
            &lobe_test,
            mean_target,
            &mut x,
            (free, &emits),
            &mut glossy,
            &mut why,
            progress,
        )?;
    }
    lambert_lobes_are_diffuse(&mut x, &mut glossy, &mut why);
    let models = (0..k_count)
        .map(|k| {
            let mut reasons = why[k].clone();
            if !free[k] {
                let n = sets.train_per_object.get(k).copied().unwrap_or(0);
                let seen = if n == 0 {
                    "seen by no training pixel".to_owned()
                } else {
                    format!("seen in only {n} training pixels")
                };
                reasons.insert(0, format!(
                    "material unconstrained: {seen} (fewer than {}); its roughness and specular are the start values, \
                     not estimates",
                    solve::MIN_PIXELS
                ));
            }
            let model = match (glossy[k], emits[k]) {
                (false, false) => "diffuse",
                (true, false) => "specular",
                (false, true) => "diffuse+emission",
                (true, true) => "specular+emission",
            };
            ObjectModel { model: model.into(), why: reasons.join("; "), constrained: free[k] }
        })
        .collect();
    Ok((x, models, split))
}

/// Objects whose lobe has neither specular strength nor metallic (both at the profile solve's bound 0) are
/// diffuse: such a lobe is exactly Lambert (`tracer::bsdf`), whatever its roughness. Their roughness goes back to
/// the start value [`layout::START_ROUGHNESS`] that every diffuse object carries, and `why` says so. Labelled
/// `specular`, such an object reported a roughness that nothing used, and the export's detail texture, which
/// takes diffuse objects only, left it out (on the house 2 objects at each of three seeds, a wall and a box
/// among them).
fn lambert_lobes_are_diffuse(x: &mut [f64], glossy: &mut [bool], why: &mut [Vec<String>]) {
    for k in 0..glossy.len() {
        if glossy[k] && x[idx(k, METALLIC)] == 0.0 && x[idx(k, SPECULAR)] == 0.0 {
            glossy[k] = false;
            x[idx(k, ROUGHNESS)] = layout::START_ROUGHNESS;
            why[k].push(
                "diffuse after all: its lobe has no specular reflection (specular and metallic 0), which is \
                 exactly Lambert"
                    .into(),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lobe_without_specular_reflection_is_diffuse() {
        let mut x = layout::initial(3);
        for (k, (m, sp)) in [(0.0, 0.0), (0.0, 0.3), (1.0, 0.0)].into_iter().enumerate() {
            x[idx(k, ROUGHNESS)] = 0.62;
            x[idx(k, METALLIC)] = m;
            x[idx(k, SPECULAR)] = sp;
        }
        let mut glossy = vec![true; 3];
        let mut why = vec![Vec::new(); 3];
        lambert_lobes_are_diffuse(&mut x, &mut glossy, &mut why);
        assert_eq!(glossy, [false, true, true]);
        assert_eq!(x[idx(0, ROUGHNESS)], layout::START_ROUGHNESS);
        assert_eq!((x[idx(1, ROUGHNESS)], x[idx(2, ROUGHNESS)]), (0.62, 0.62));
        assert!(why[0][0].contains("exactly Lambert") && why[1].is_empty() && why[2].is_empty(), "{why:?}");
    }

    #[test]
    fn an_emissions_share_of_its_pixels_counts_both_halves_of_a_split_emitter() {
        let mut x = layout::initial(2);
        for k in 0..2 {
            layout::set_rgb(&mut x, k, EMISSION, [0.3, 0.2, 0.1]);
            layout::set_rgb(&mut x, k, EMISSION_GROUND, [0.9, 0.6, 0.3]);
        }
        let split = Split::flat(glam::Vec3::Z, vec![false, true]);
        // Uniform: Σe = 0.6 against pixels of mean Σ radiance 1.2; the ground entry is not its emission.
        assert!((own_share(&x, &split, 0, 1.2) - 0.5).abs() < 1e-12);
        // Split: the mean of the halves' sums, (0.6 + 1.8) / 2 = 1.2.
        assert!((own_share(&x, &split, 1, 1.2) - 1.0).abs() < 1e-12);
        // Pixels without radiance: no division by zero, and any emission passes.
        assert!(own_share(&x, &split, 0, 0.0) > MIN_OWN_SHARE);
    }

    #[test]
    fn an_emission_against_a_white_alternative_needs_less_evidence() {
        let white = Some([1.0, 1.0, 1.0 - 1e-4]);
        // Against an alternative inside its domain (or none) the bar is T_KEEP…
        for alternative in [None, Some([0.9, 1.0, 1.0]), Some([0.4, 0.5, 0.6])] {
            assert!(!emission_beats(alternative, 2.9, 0.05));
            assert!(emission_beats(alternative, 3.1, 0.05));
        }
        // …and against one at the top of its domain in every channel, T_SATURATED.
        assert!(emission_beats(white, 2.1, 0.05));
        assert!(!emission_beats(white, 1.9, 0.05));
        // The gain must still be more than a trace, whatever t.
        assert!(!emission_beats(white, 10.0, 1e-6));
        assert!(!emission_beats(None, 10.0, -0.01));
    }

    #[test]
    fn the_squared_error_decides_against_an_emission_and_for_it_against_a_white_lobe() {
        let mut x = layout::initial(1);
        let alternative = |x: &[f64], l1: (f64, f64), squared: (f64, f64)| LobeAlternative {
            x: x.to_vec(),
            emission_against_lobe: l1,
            emission_against_lobe_squared: squared,
            lobe_against_diffuse: (0.0, 0.0),
        };
        // A polished metal box that its emission beat by the L1 (the lobe's noise) and lost to by the squared error.
        assert!(!alternative(&x, (0.107, 7.2), (-0.113, -3.6)).emission_beats_it(0));
        assert!(alternative(&x, (0.107, 7.2), (-0.113, -2.5)).emission_beats_it(0));
        assert!(alternative(&x, (0.107, 7.2), (-0.004, -3.6)).emission_beats_it(0));
        // A lamp in 4 own pixels: the squared error agrees without reaching t = 3; it does not decide for it.
        assert!(alternative(&x, (0.311, 4.7), (0.309, 2.9)).emission_beats_it(0));
        assert!(!alternative(&x, (0.01, 0.8), (0.3, 9.0)).emission_beats_it(0));
        assert!(alternative(&x, (0.3, 12.0), (0.5, 6.0)).figures().contains("+50.000 % of the RMS error (t = 6.0)"));
        // Against a white lobe the L1 needs t > T_SATURATED only…
        assert!(!alternative(&x, (0.3, 2.5), (0.0, 0.0)).emission_beats_it(0));
        // …and the squared error decides for the emission too (a window pane whose sky no reflector reaches),
        // which it does not against a lobe inside its domain.
        assert!(!alternative(&x, (-0.043, -1.2), (0.261, 5.4)).emission_beats_it(0));
        for c in 0..3 {
            x[idx(0, BASE_COLOR + c)] = 1.0;
        }
        assert!(alternative(&x, (0.3, 2.5), (0.0, 0.0)).emission_beats_it(0));
        assert!(alternative(&x, (-0.043, -1.2), (0.261, 5.4)).emission_beats_it(0));
        assert!(alternative(&x, (-0.043, -1.2), (0.261, 5.4)).wins_squared_against_white(0));
        assert!(!alternative(&x, (-0.043, -1.2), (0.261, 2.9)).emission_beats_it(0));
        assert!(!alternative(&x, (-0.043, -1.2), (0.004, 5.4)).emission_beats_it(0));
    }

    #[test]
    fn a_clear_pass_waits_for_every_stratum_to_be_seen() {
        // A lamp's 40 own pixels at the first look of 2048: 5 of them, too few for their spread.
        assert!(!strata_known(&[(5, 40), (251, 2008)]));
        // 16 of them will do, and so will all of a stratum of 3.
        assert!(strata_known(&[(16, 128), (240, 1920)]));
        assert!(strata_known(&[(3, 3), (253, 2045)]));
        // An empty stratum is all of itself.
        assert!(strata_known(&[(0, 0), (256, 2048)]));
    }
}
