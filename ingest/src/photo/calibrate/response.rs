//! The response model of self-calibration and the choice of its exponent.
//!
//! `h_c(z) = ln f_c⁻¹(z)` is piecewise linear over [`KNOTS`] knots uniform in `t = √z` (z the code in [0, 1]):
//! knots are dense at the dark end, where `ln f⁻¹` bends fastest (≈ γ ln z), and sparse near white. A
//! second-difference penalty on the knot values keeps it smooth (Debevec & Malik's λ term), which also
//! extrapolates it linearly over codes no observation reaches.
//!
//! **Exponential ambiguity.** With unknown exposures, `γ·h`, `γ·ln g`, `γ·ln v`, `γ·ln L` fit the data
//! exactly as well as `h`, `ln g`, `ln v`, `ln L` (Grossberg & Nayar 2003): nothing in the photos alone fixes
//! γ. The solver fixes it provisionally with a gauge, then [`choose_scale`] picks γ from two kinds of prior
//! knowledge, measured in `docs/photo/self-calibration.md`:
//! 1. the **shape prior**: the γ for which `h` is closest (least squares in `ln`, over mid codes) to the sRGB
//!    curve's `ln` — right when the camera encodes roughly as sRGB, off by the ratio of log-log slopes otherwise;
//! 2. the **exposure lattice**: cameras set exposure (shutter, aperture, ISO) in steps of ⅓ EV, so the log
//!    exposure ratios are multiples of `ln 2 / 3`. When exactly one γ near the shape prior puts every
//!    recovered exposure onto that lattice, it is exact whatever the curve. It needs ≥ 3 distinct exposures.
//! 3. the **bracket's own step** ([`fit_bracket_steps`]): a bracket is shot in equal steps (or multiples of
//!    one), so the recovered exposures are `a + n_p·s` with integer `n_p` even when they are too noisy for the
//!    ⅓-EV test (real shutters and film reciprocity put them a few percent off nominal). The step is then made
//!    the multiple of ⅓ EV nearest the shape prior's value: exact for a ⅓-EV step whatever the curve, and for
//!    a step of k/3 EV only when the prior is within ±1/(2k) — so reliable only for k = 1.
//!
//! With either lattice the exposures are then fixed to their lattice points and the response is refitted
//! alone (no exponential ambiguity is left); with neither, the shape prior stands and the result is flagged
//! unreliable.

use std::f64::consts::{LN_2, PI};

use crate::srgb;

/// Knots of the response model per channel: 48 knots uniform in √z are ~1.5 codes apart near code 10 and
/// ~10 codes apart near white, where every tone curve is nearly straight in `ln`.
pub(super) const KNOTS: usize = 48;

/// Knot interval and interpolation weight of code `z` ∈ [0, 1]: `h(z) = (1−w)·h[k] + w·h[k+1]`.
pub(super) fn knot_weights(z: f64) -> (usize, f64) {
    let t = z.clamp(0.0, 1.0).sqrt() * (KNOTS - 1) as f64;
    let k = (t.floor() as usize).min(KNOTS - 2);
    (k, t - k as f64)
}

/// Evaluates the knot values `h` (one channel) at code `z` ∈ [0, 1].
pub(super) fn eval(h: &[f64], z: f64) -> f64 {
    let (k, w) = knot_weights(z);
    (1.0 - w) * h[k] + w * h[k + 1]
}

/// `ln` of the sRGB decoding curve, the shape prior.
fn ln_srgb(z: f64) -> f64 {
    f64::from(srgb::decode(z as f32)).max(f64::MIN_POSITIVE).ln()
}

/// Codes over which the shape prior compares curves: the well-exposed middle (32..=224 of 255), where every
/// photo constrains the curve and neither quantisation (dark end) nor clipping (white end) dominates.
const PRIOR_CODES: (u32, u32) = (32, 224);

/// The factor κ that brings `κ·h` closest to `ln srgb` over [`PRIOR_CODES`], both taken relative to their
/// mean (the curves' offsets are free); summed over the given channels' knot vectors.
pub(super) fn shape_prior_scale(channels: &[&[f64]]) -> f64 {
    let codes: Vec<f64> = (PRIOR_CODES.0..=PRIOR_CODES.1).map(|z| f64::from(z) / 255.0).collect();
    let v: Vec<f64> = codes.iter().map(|&z| ln_srgb(z)).collect();
    let v_mean = v.iter().sum::<f64>() / v.len() as f64;
    let (mut uv, mut uu) = (0.0, 0.0);
    for h in channels {
        let u: Vec<f64> = codes.iter().map(|&z| eval(h, z)).collect();
        let u_mean = u.iter().sum::<f64>() / u.len() as f64;
        for (a, b) in u.iter().zip(&v) {
            uv += (a - u_mean) * (b - v_mean);
            uu += (a - u_mean) * (a - u_mean);
        }
    }
    if uu > 0.0 && uv > 0.0 { uv / uu } else { 1.0 }
}

/// Difference `ln srgb(hi) − ln srgb(lo)` used as the provisional scale gauge of the solver, so that the
/// provisional solution is already of the right magnitude.
pub(super) fn gauge_span(lo: f64, hi: f64) -> f64 {
    ln_srgb(hi) - ln_srgb(lo)
}

/// The exposure lattice step: ⅓ EV, the finest step of camera exposure controls.
pub(super) const LATTICE_STEP: f64 = LN_2 / 3.0;
/// Search window around the shape prior, as a factor either side: it covers the prior's error on the curves
/// measured where a lattice exists (≈ 20 % filmic, ≈ 5 % gamma 2.2; docs/photo/self-calibration.md), and is
/// narrow enough that a ⅓-EV bracket has one lattice fit in it (the next is at twice the true γ).
const LATTICE_WINDOW: f64 = 1.3;
/// A γ fits the lattice when `1 − |mean exp(2πi·γ·ln e_p / step)|` is below this: 0.02 allows an rms
/// deviation of ≈ 0.03 step (`√(2·0.02)/2π`), i.e. 0.7 % in exposure, far above the estimation noise and far
/// below a misfit (≈ 1 for exposures off the lattice).
const LATTICE_FIT_MAX: f64 = 0.02;
/// Grid of the γ search in `ln γ`: the misfit's minima are ≈ 1/(3·span in stops) wide in `ln γ`; 1e-4 resolves
/// them for spans up to 30 stops before the parabolic refinement.
const LATTICE_GRID: f64 = 1e-4;

/// How γ was fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum GammaSource {
    /// The response is given (`Linear`, `Srgb`): no ambiguity.
    Given,
    /// Exposure ratios snapped to ⅓-EV steps: reliable.
    ExposureLattice,
    /// The exposures lie on a common step (a bracket), whose size in ⅓-EV steps is the one nearest the shape
    /// prior: reliable only when that step is ⅓ EV (the next candidate, ⅔ EV, is twice as far as any prior
    /// error measured); for a step of k/3 EV the prior must be within ±1/(2k) of the truth.
    BracketSteps,
    /// Only the sRGB shape prior: the curve's exponent (and so the gains' and the vignetting's) may be off by
    /// the ratio of the true curve's log-log slope to sRGB's.
    ShapePrior,
}

/// The scale chosen for the provisional solution, its source, and the lattice misfit at it.
#[derive(Debug, Clone, Copy)]
pub(super) struct ScaleChoice {
    pub kappa: f64,
    pub source: GammaSource,
    pub misfit: f64,
    /// Whether the exponent is trustworthy ([`super::Calibration::gamma_reliable`]).
    pub reliable: bool,
}

/// The ⅓-EV lattice points nearest to `κ·x_p`, divided by κ (provisional units), sharing the exposures'
/// circular mean phase.
pub(super) fn snap_to_lattice(kappa: f64, log_exposures: &[f64]) -> Vec<f64> {
    let (mut re, mut im) = (0.0, 0.0);
    for e in log_exposures {
        let phase = 2.0 * PI * kappa * e / LATTICE_STEP;
        re += phase.cos();
        im += phase.sin();
    }
    let offset = im.atan2(re) / (2.0 * PI) * LATTICE_STEP;
    log_exposures
        .iter()
        .map(|e| (((kappa * e - offset) / LATTICE_STEP).round() * LATTICE_STEP + offset) / kappa)
        .collect()
}

fn lattice_misfit(log_exposures: &[f64], kappa: f64) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for e in log_exposures {
        let phase = 2.0 * PI * kappa * e / LATTICE_STEP;
        re += phase.cos();
        im += phase.sin();
    }
    1.0 - (re * re + im * im).sqrt() / log_exposures.len() as f64
}

/// Chooses κ (multiplying the provisional `h`, log gains, vignetting): the one κ within [`LATTICE_WINDOW`] of
/// the shape prior that puts the exposures on the lattice; the shape prior itself when none or several do
/// (`misfit` is then the lowest lattice misfit in the window).
pub(super) fn choose_scale(prior: f64, log_exposures: &[f64]) -> ScaleChoice {
    let fallback = ScaleChoice { kappa: prior, source: GammaSource::ShapePrior, misfit: f64::NAN, reliable: false };
    // Distinct exposures: with two, some γ near any prior puts them on the lattice; three are the least that
    // can contradict a wrong γ.
    let mut sorted = log_exposures.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.dedup_by(|a, b| (*a - *b).abs() < 0.5 * LATTICE_STEP / LATTICE_WINDOW / prior);
    if sorted.len() < 3 {
        return fallback;
    }
    let lo = prior.ln() - LATTICE_WINDOW.ln();
    let steps = (2.0 * LATTICE_WINDOW.ln() / LATTICE_GRID).ceil() as usize;
    let f = |i: usize| lattice_misfit(log_exposures, (lo + i as f64 * LATTICE_GRID).exp());
    let mut best: Option<f64> = None;
    let mut candidates = 0;
    let mut lowest = f64::INFINITY;
    let (mut prev, mut cur) = (f(0), f(1));
    for i in 1..steps {
        let next = f(i + 1);
        lowest = lowest.min(cur);
        if cur <= prev && cur <= next && cur < LATTICE_FIT_MAX {
            // Parabolic refinement of the minimum through the three grid points.
            let denom = prev - 2.0 * cur + next;
            let shift = if denom > 0.0 { 0.5 * (prev - next) / denom } else { 0.0 };
            let kappa = (lo + (i as f64 + shift.clamp(-1.0, 1.0)) * LATTICE_GRID).exp();
            candidates += 1;
            best = Some(kappa);
        }
        (prev, cur) = (cur, next);
    }
    // Two lattice fits within the window (a bracket in whole stops fits every ⅓-multiple of the true γ) and
    // the prior cannot tell which: refuse rather than guess.
    match best {
        Some(kappa) if candidates == 1 => ScaleChoice {
            kappa,
            source: GammaSource::ExposureLattice,
            misfit: lattice_misfit(log_exposures, kappa),
            reliable: true,
        },
        _ => ScaleChoice { misfit: lowest, ..fallback },
    }
}

/// Largest deviation of a recovered log exposure from its bracket-step lattice point, as a fraction of the
/// step: below a quarter step, rounding to the nearest lattice point is unambiguous with a margin of a quarter
/// step for estimation error (measured on the Memorial bracket: ≤ 0.15 of a one-stop step).
const STEP_TOLERANCE: f64 = 0.25;

/// Exposures of a bracket on a common step: `x_p ≈ a + n_p·s` with integer `n_p`.
#[derive(Debug, Clone)]
pub(super) struct StepFit {
    /// Scale that makes the step a whole number of ⅓-EV lattice steps.
    pub kappa: f64,
    /// The step in ⅓ EV after scaling (≥ 1).
    pub thirds: u32,
    /// `a + n_p·s` per input exposure (provisional units).
    pub snapped: Vec<f64>,
    /// Largest |x_p − a − n_p·s| / s.
    pub misfit: f64,
}

/// Fits the provisional log exposures to a lattice of unknown step (a bracket taken in equal steps, or in
/// multiples of one step), then chooses the exponent that makes the step the multiple of ⅓ EV nearest to the
/// shape prior's. `None` when fewer than three distinct exposures or no step fits within [`STEP_TOLERANCE`].
pub(super) fn fit_bracket_steps(prior: f64, log_exposures: &[f64]) -> Option<StepFit> {
    let mut sorted = log_exposures.to_vec();
    sorted.sort_by(f64::total_cmp);
    // Exposures closer than a sixth of a ⅓-EV step (at the prior's scale) are the same setting.
    let same = 0.5 * LATTICE_STEP / LATTICE_WINDOW / prior;
    sorted.dedup_by(|a, b| (*a - *b).abs() < same);
    if sorted.len() < 3 {
        return None;
    }
    let mut diffs: Vec<f64> = sorted.windows(2).map(|w| w[1] - w[0]).collect();
    diffs.sort_by(f64::total_cmp);
    let x0 = sorted[0];
    // The step is one of the spacings between neighbouring exposures; the smallest that fits is the lattice's.
    for &d in &diffs {
        let n: Vec<f64> = log_exposures.iter().map(|x| ((x - x0) / d).round()).collect();
        // Least squares x = a + s·n.
        let m = n.len() as f64;
        let (sn, sx) = (n.iter().sum::<f64>(), log_exposures.iter().sum::<f64>());
        let snn: f64 = n.iter().map(|v| v * v).sum();
        let snx: f64 = n.iter().zip(log_exposures).map(|(a, b)| a * b).sum();
        let det = m * snn - sn * sn;
        if det <= 0.0 {
            continue;
        }
        let s = (m * snx - sn * sx) / det;
        let a = (sx - s * sn) / m;
        if s <= 0.0 {
            continue;
        }
        let misfit = n.iter().zip(log_exposures).map(|(k, x)| (x - a - s * k).abs()).fold(0.0, f64::max) / s;
        if misfit < STEP_TOLERANCE {
            let thirds = (prior * s / LATTICE_STEP).round().max(1.0);
            let kappa = thirds * LATTICE_STEP / s;
            let snapped = n.iter().map(|k| a + s * k).collect();
            return Some(StepFit { kappa, thirds: thirds as u32, snapped, misfit });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_interpolate_linearly_in_sqrt_code() {
        let h: Vec<f64> = (0..KNOTS).map(|k| k as f64).collect();
        for z in [0.0, 0.01, 0.3, 0.77, 1.0] {
            assert!((eval(&h, z) - z.sqrt() * (KNOTS - 1) as f64).abs() < 1e-9, "{z}");
        }
    }

    #[test]
    fn lattice_recovers_the_scale_near_a_rough_prior() {
        // Exposures in ⅓-EV steps, seen through γ = 0.8 (so the truth is κ = 1.25); the prior is 12 % off.
        let truth: [f64; 5] = [-3.0, -1.0, 0.0, 2.0, 7.0];
        let seen: Vec<f64> = truth.iter().map(|n| 0.8 * n * LATTICE_STEP + 0.1).collect();
        let choice = choose_scale(1.25 * 1.12, &seen);
        assert_eq!(choice.source, GammaSource::ExposureLattice);
        assert!((choice.kappa - 1.25).abs() < 1e-3, "{choice:?}");
        // Two exposures never decide.
        assert_eq!(choose_scale(1.0, &seen[..2]).source, GammaSource::ShapePrior);
        // Whole-stop steps fit every third of the true κ: several candidates in the window, no decision.
        let stops: Vec<f64> = [0.0, 3.0, 6.0, 9.0, 12.0].iter().map(|n| 0.8 * n * LATTICE_STEP).collect();
        assert_eq!(choose_scale(1.25 * 1.12, &stops).source, GammaSource::ShapePrior);
    }

    #[test]
    fn bracket_steps_snap_noisy_whole_stops() {
        // One-stop steps seen through γ = 0.8 (truth κ = 1.25), each exposure off by up to 0.1 stop; prior 10 % off.
        let noise = [0.05, -0.1, 0.08, 0.0, -0.06, 0.1, -0.03];
        let seen: Vec<f64> = noise.iter().enumerate().map(|(n, d)| 0.8 * (n as f64 + d) * LN_2 + 0.3).collect();
        let fit = fit_bracket_steps(1.25 * 1.1, &seen).unwrap();
        assert_eq!(fit.thirds, 3);
        assert!((fit.kappa - 1.25).abs() < 0.02, "{fit:?}");
        let steps: Vec<f64> = fit.snapped.windows(2).map(|w| fit.kappa * (w[1] - w[0]) / LN_2).collect();
        assert!(steps.iter().all(|s| (s - 1.0).abs() < 1e-9), "{steps:?}");
        // Exposures off any common step: no fit.
        assert!(fit_bracket_steps(1.0, &[0.0, 1.0, 1.37, 2.0]).is_none());
    }

    #[test]
    fn shape_prior_of_scaled_srgb_is_the_inverse_scale() {
        let h: Vec<f64> =
            (0..KNOTS).map(|k| 0.5 * ln_srgb(((k as f64) / (KNOTS - 1) as f64).powi(2).max(1e-4))).collect();
        let kappa = shape_prior_scale(&[&h]);
        assert!((kappa - 2.0).abs() < 0.02, "{kappa}");
    }
}
