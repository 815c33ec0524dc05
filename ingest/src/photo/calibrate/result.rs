//! From the solver's unknowns to a [`Calibration`]: the exponent of an estimated response (see
//! [`super::response`]), gains, vignetting, the response curve and the diagnostics.

use super::response::{self, GammaSource, KNOTS};
use super::solve::{Problem, Solution};
use super::{Calibration, CalibrationOptions, ResponseMode, Vignetting};
use crate::photo::response::{CURVE_LEN, ResponseCurve};

/// Layout of the unknowns (built by `super::model`, read back here).
pub(super) struct Layout {
    /// Estimated response curves, first in the unknowns: 0 (known response), 1 (shared) or 3 (per channel).
    pub curves: usize,
    /// First gain unknown of each solved photo.
    pub gain: Vec<Option<usize>>,
    /// Each photo's linked set (`None` = not solved), numbered from 0: each set's gains have their own gauge.
    pub set: Vec<Option<usize>>,
    /// Gains per photo: 0 (none), 1 (exposure) or 3 (per channel).
    pub per_photo: usize,
    /// First vignetting unknown of each group.
    pub beta: Vec<Option<usize>>,
    pub n: usize,
}

impl Layout {
    /// First knot unknown of channel `c`'s curve (with `curves > 0`).
    pub fn curve(&self, c: usize) -> usize {
        if self.curves == 3 { c * KNOTS } else { 0 }
    }

    /// How many linked sets the solved photos form.
    pub fn n_sets(&self) -> usize {
        self.set.iter().flatten().max().map_or(0, |&s| s + 1)
    }

    /// Channel `c`'s knot values.
    pub fn knots<'a>(&self, theta: &'a [f64], c: usize) -> &'a [f64] {
        &theta[self.curve(c)..self.curve(c) + KNOTS]
    }
}

/// Source observation and channel of every solver row.
pub(super) struct RowInfo {
    pub observation: Vec<usize>,
    pub channel: Vec<usize>,
}

/// `exp` arguments are clamped to this so that an extrapolated curve end stays a positive finite f32.
const MAX_LN: f64 = 60.0;
/// Below this mean squared log exposure (provisional units) the exposures hardly vary and cannot relate the
/// channels' exponents: the shape prior does it instead.
const MIN_EXPOSURE_VARIANCE: f64 = 1e-6;

/// Knots of two channels' curves that both channels' rows support, at least this many, relate the channels'
/// exponents ([`matched_curves`]): fewer leave a two-parameter line fit (scale and offset) barely determined.
const MIN_SHARED_KNOTS: usize = 4;

/// Each response knot's data weight: the rows' base × robust weights (those that take part) times their
/// interpolation weight on the knot.
fn knot_support(problem: &Problem, sol: &Solution, layout: &Layout) -> Vec<f64> {
    let mut support = vec![0.0; layout.curves * KNOTS];
    for (i, r) in problem.rows.iter().enumerate() {
        let take = problem.start.get(i).copied().unwrap_or(1.0) * sol.robust[i] * r.w;
        for e in 0..usize::from(r.len) {
            if let Some(s) = support.get_mut(r.idx[e] as usize) {
                *s += take * r.coef[e].abs();
            }
        }
    }
    support
}

/// The factor on channel c's log response that brings it onto green's, by a weighted line fit (with offset)
/// of green's knots on c's, each knot weighted by the smaller of the two channels' support: a camera applies
/// one tone curve to every channel after white balance, so the channels' estimates differ only by their
/// exponents, and the codes both channels hold say by how much. `None` with fewer than
/// [`MIN_SHARED_KNOTS`] shared knots.
fn matched_curves(theta: &[f64], support: &[f64], c: usize) -> Option<f64> {
    let h = |c: usize, k: usize| theta[c * KNOTS + k];
    let w: Vec<f64> = (0..KNOTS).map(|k| support[c * KNOTS + k].min(support[KNOTS + k])).collect();
    if w.iter().filter(|&&v| v > 0.0).count() < MIN_SHARED_KNOTS {
        return None;
    }
    let total: f64 = w.iter().sum();
    let mean = |ch: usize| (0..KNOTS).map(|k| w[k] * h(ch, k)).sum::<f64>() / total;
    let (mc, mg) = (mean(c), mean(1));
    let cg: f64 = (0..KNOTS).map(|k| w[k] * (h(c, k) - mc) * (h(1, k) - mg)).sum();
    let cc: f64 = (0..KNOTS).map(|k| w[k] * (h(c, k) - mc).powi(2)).sum();
    (cc > 0.0 && cg > 0.0).then(|| cg / cc)
}

/// Relative exponent of each channel with per-channel gains. With an estimated response, from the channels'
/// curves where both hold data ([`matched_curves`]): measured on four renders of the consumer-camera
/// fixture, this put each channel within 0.4–2.1 % of the factor its gains need, while relating the channels
/// through their log gains (white balance taken as independent of exposure, so that each channel's log gains
/// regress on green's with slope 1) was off by up to 6 %, because 18 photos' white balances correlate with
/// their exposures by chance (docs/photo/self-calibration.md, "Relating the channels"). The gains' regression
/// remains the fallback when two channels share too few codes.
fn channel_ratios(theta: &[f64], layout: &Layout, opts: &CalibrationOptions, rows: (&Problem, &Solution)) -> [f64; 3] {
    // Shared gains tie the channels' exponents; a shared curve is one exponent.
    if layout.per_photo != 3 || layout.curves != 3 {
        return [1.0; 3];
    }
    let prior: [f64; 3] = std::array::from_fn(|c| response::shape_prior_scale(&[layout.knots(theta, c)]));
    let from_prior = std::array::from_fn(|c| prior[c] / prior[1]);
    let support = knot_support(rows.0, rows.1, layout);
    let matched: [Option<f64>; 3] =
        std::array::from_fn(|c| if c == 1 { Some(1.0) } else { matched_curves(theta, &support, c) });
    if matched.iter().all(Option::is_some) {
        return matched.map(|m| m.unwrap_or(1.0));
    }
    if !opts.exposure {
        return from_prior;
    }
    let starts: Vec<usize> = layout.gain.iter().flatten().copied().collect();
    let green_var = starts.iter().map(|&g| theta[g + 1].powi(2)).sum::<f64>() / starts.len() as f64;
    if green_var < MIN_EXPOSURE_VARIANCE {
        return from_prior;
    }
    std::array::from_fn(|c| {
        let cg: f64 = starts.iter().map(|&g| theta[g + c] * theta[g + 1]).sum();
        let cc: f64 = starts.iter().map(|&g| theta[g + c].powi(2)).sum();
        if cc > 0.0 && cg > 0.0 { cg / cc } else { from_prior[c] }
    })
}

#[allow(clippy::too_many_arguments)]
pub(super) fn finish(
    n_groups: usize,
    opts: &CalibrationOptions,
    layout: &Layout,
    problem: &Problem,
    sol: &Solution,
    rows: &RowInfo,
    unconstrained: Vec<(u32, String)>,
    clipped_channels: usize,
    vignetting_estimated: Vec<bool>,
    chosen: Option<response::ScaleChoice>,
) -> Calibration {
    let theta = &sol.theta;
    let (mut scale, mut gamma_source, mut lattice_misfit, mut curve) = ([1.0; 3], GammaSource::Given, f64::NAN, None);
    let mut gamma_reliable = true;
    if opts.response == ResponseMode::Estimate {
        let rho = channel_ratios(theta, layout, opts, (problem, sol));
        let scaled: Vec<Vec<f64>> =
            (0..3).map(|c| layout.knots(theta, c).iter().map(|v| v * rho[c]).collect()).collect();
        let prior = response::shape_prior_scale(&[&scaled[0], &scaled[1], &scaled[2]]);
        let log_exposures: Vec<f64> = layout
            .gain
            .iter()
            .flatten()
            .map(|&g| match layout.per_photo {
                3 => (0..3).map(|c| rho[c] * theta[g + c]).sum::<f64>() / 3.0,
                _ => theta[g],
            })
            .collect();
        let choice = if let Some(choice) = chosen {
            choice
        } else if opts.exposure {
            response::choose_scale(prior, &log_exposures)
        } else {
            response::ScaleChoice { kappa: prior, source: GammaSource::ShapePrior, misfit: f64::NAN, reliable: false }
        };
        gamma_reliable = choice.reliable;
        scale = std::array::from_fn(|c| choice.kappa * rho[c]);
        gamma_source = choice.source;
        lattice_misfit = choice.misfit;
        let mut values: Vec<[f32; 3]> = (0..CURVE_LEN)
            .map(|z| {
                let code = z as f64 / (CURVE_LEN - 1) as f64;
                std::array::from_fn(|c| {
                    (scale[c] * response::eval(layout.knots(theta, c), code)).clamp(-MAX_LN, MAX_LN).exp() as f32
                })
            })
            .collect();
        // Monotone: a response never decreases; the running maximum removes wiggles of an unconstrained end.
        for z in 1..CURVE_LEN {
            for c in 0..3 {
                values[z][c] = values[z][c].max(values[z - 1][c]);
            }
        }
        curve = ResponseCurve::from_values(values).ok();
    }
    let gains = layout
        .gain
        .iter()
        .map(|g| {
            g.map(|g| {
                std::array::from_fn(|c| match layout.per_photo {
                    3 => (scale[c] * theta[g + c]).exp(),
                    _ => (scale[c] * theta[g]).exp(),
                })
            })
        })
        .map(|g| g.or(if layout.per_photo == 0 { Some([1.0; 3]) } else { None }))
        .collect::<Vec<Option<[f64; 3]>>>();
    // Photos without gain unknowns but solved (no gains requested) keep gain 1; unconstrained stay None.
    let unconstrained_set: Vec<u32> = unconstrained.iter().map(|u| u.0).collect();
    let gains = gains
        .into_iter()
        .enumerate()
        .map(|(p, g)| if unconstrained_set.contains(&(p as u32)) { None } else { g })
        .collect();
    let vignetting = (0..n_groups)
        .map(|k| match layout.beta[k] {
            Some(b) => Vignetting { beta: std::array::from_fn(|i| scale[1] * theta[b + i]) },
            None => Vignetting::none(),
        })
        .collect();
    let (mut se, mut sw) = (0.0, 0.0);
    let mut used = vec![false; rows.observation.iter().max().map_or(0, |&m| m + 1)];
    let mut rejected_channels = 0;
    for j in 0..problem.rows.len() {
        if sol.robust[j] > 0.0 {
            se += sol.robust[j] * (scale[rows.channel[j]] * sol.residual[j]).powi(2);
            sw += sol.robust[j];
            used[rows.observation[j]] = true;
        } else {
            rejected_channels += 1;
        }
    }
    Calibration {
        gains,
        linked_sets: layout.n_sets(),
        unconstrained,
        vignetting,
        vignetting_estimated,
        response: curve,
        gamma_source,
        gamma_reliable,
        lattice_misfit,
        residual_rms: if sw > 0.0 { (se / sw).sqrt() } else { 0.0 },
        used_observations: used.iter().filter(|&&u| u).count(),
        clipped_channels,
        rejected_channels,
        held_out: None,
    }
}
