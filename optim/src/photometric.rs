//! The photos' tone-curve exponent, judged by how well a fit's renders explain them.
//!
//! A display-referred scan whose response is estimated from the photos alone is linearised only up to a
//! power: the photos determine the response, the gains and the vignetting up to a common exponent (the
//! exponential ambiguity of radiometric self-calibration; `ingest::photo::calibrate`), so a prepared photo
//! may hold L^s instead of the radiance L. Light transport is linear, and that constrains s: a fit explains
//! photos raised to the right power better than photos raised to a wrong one. Materials absorb part of a
//! wrong power (photos with compressed contrast are met with higher albedos, whose interreflection flattens
//! the lighting), so the signal is a shallow minimum, measured as a log misfit.
//!
//! [`render_misfit`] renders the held-out pixels twice with independent random numbers and returns the mean
//! squared difference between log photo and log render less the renders' own Monte Carlo share (half the
//! mean squared log difference of the two renders, the variance of one render's log), in total and per
//! channel. Its random numbers are the same for every call, so that the trials of a search, whose misfits lie
//! a few tenths of a per cent apart near the minimum, differ by their fits and not by the judge's render
//! noise. [`trial_misfit`] judges one trial: it raises the held-out targets to the trial's exponent and divides
//! the misfit by the exponent's square, so that misfits of differently raised photos compare in the same
//! (original log) units. The caller searches one exponent for all channels (the calibration relates the
//! channels' exponents to each other) by [`relative_mean`], each channel relative to its first trial since
//! the darkest channel's log misfit is the largest and the noisiest, and judges comparison fits with a fixed
//! set of lights
//! (`optim::fit::FitMode::Comparison`), so that no faint emission absorbs a wrong exponent
//! (`workflow::stages::object`; measurements in docs/photo/self-calibration.md).

use glam::Vec3;
use tracer::{Camera, Params, PixelRef, Scene, TracerError, TracerSettings};

use crate::fit::pixels::{PixelSets, Sample};
use crate::streams::key;

/// The held-out misfit of a fit (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Misfit {
    /// Mean squared log residual between photo and render less the render noise's share, per pixel and
    /// channel, in the log units of the photos as given.
    pub value: f64,
    /// (Pixel, channel) pairs used: photo and both renders positive and finite.
    pub terms: usize,
    /// The same per channel: mean over that channel's usable pixels.
    pub channel: [f64; 3],
}

/// Renders `samples` (held-out pixels with their targets) twice at `spp` paths with `params`, with
/// independent random numbers (the same ones at every call), and returns the noise-corrected log misfit.
pub fn render_misfit(
    scene: &Scene,
    cameras: &[Camera],
    params: &Params,
    settings: &TracerSettings,
    samples: &[Sample],
    spp: u32,
    seed: u64,
) -> Result<Misfit, TracerError> {
    let renderer = tracer::Renderer::new(scene, params, settings)?;
    let pixels: Vec<PixelRef> = samples.iter().map(|s| s.pixel).collect();
    let (r1, _) = renderer.render_pixels(cameras, &pixels, spp, seed, key::EXPONENT)?;
    let (r2, _) = renderer.render_pixels(cameras, &pixels, spp, seed, key::EXPONENT ^ key::SECOND_ESTIMATE)?;
    Ok(log_misfit(samples, &r1, &r2))
}

/// The misfit of one trial of the search: `params` fitted to the photos raised to `exponent`, judged on
/// `holdout` (targets from the photos as given, raised here by the rule that raises the photos,
/// `ingest::photo::calibrate::raise_linear`) by [`render_misfit`], and returned in the photos' original log
/// units (raising to e scales every log residual by e, so each mean square is divided by e²).
#[allow(clippy::too_many_arguments)]
pub fn trial_misfit(
    scene: &Scene,
    cameras: &[Camera],
    params: &Params,
    settings: &TracerSettings,
    holdout: &[Sample],
    exponent: f64,
    spp: u32,
    seed: u64,
) -> Result<Misfit, TracerError> {
    let e = exponent as f32;
    let raised: Vec<Sample> = holdout
        .iter()
        .map(|s| Sample { target: s.target.map(|v| ingest::photo::calibrate::raise_linear(v, e)), ..*s })
        .collect();
    let m = render_misfit(scene, cameras, params, settings, &raised, spp, seed)?;
    let scale = exponent * exponent;
    Ok(Misfit { value: m.value / scale, terms: m.terms, channel: m.channel.map(|v| v / scale) })
}

/// The noise-corrected log misfit of photos against two independent renders.
fn log_misfit(samples: &[Sample], r1: &[Vec3], r2: &[Vec3]) -> Misfit {
    let (mut fit, mut noise, mut n) = ([0.0; 3], [0.0; 3], [0usize; 3]);
    for (s, (a, b)) in samples.iter().zip(r1.iter().zip(r2)) {
        for c in 0..3 {
            let (p, a, b) = (s.target[c], a[c], b[c]);
            if p.is_finite() && a.is_finite() && b.is_finite() && p > 0.0 && a > 0.0 && b > 0.0 {
                let (lp, la, lb) = (f64::from(p).ln(), f64::from(a).ln(), f64::from(b).ln());
                fit[c] += (la - lp).powi(2);
                noise[c] += (la - lb).powi(2);
                n[c] += 1;
            }
        }
    }
    let mean = |f: f64, q: f64, n: usize| if n == 0 { f64::NAN } else { (f - 0.5 * q) / n as f64 };
    let terms = n.iter().sum();
    Misfit {
        value: mean(fit.iter().sum(), noise.iter().sum(), terms),
        terms,
        channel: std::array::from_fn(|c| mean(fit[c], noise[c], n[c])),
    }
}

/// A whole fit's emitter is a light for the comparison fits when its emission is at least this share of the
/// radiance the photos hold on it: what a photo holds of a lamp, a screen or a window is mostly what it emits,
/// while an emission a fit leaves on a wall or a box to absorb a wrong exponent is a fraction of what that
/// object reflects. Half sits between the two wherever neither is a borderline case (measured shares in
/// docs/photo/self-calibration.md, "Comparison fits").
pub const LIGHT_SHARE: f64 = 0.5;

/// One emitter of a whole fit, as [`comparison_emitters`] judged it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterShare {
    /// The object's index.
    pub object: usize,
    /// Its emission (mean over channels) over the mean radiance of its training pixels (mean over channels);
    /// `None` when the photos do not measure it (fewer training pixels than a fit's free object needs).
    pub share: Option<f64>,
    /// Whether the comparison fits let it emit.
    pub light: bool,
}

/// Which objects the comparison fits of the search let emit, from a whole fit's `emission` and its pixel
/// `sets`: every emitter the photos do not measure (a light no photo sees is what the fit exists to find, and
/// no photo compares its emission with what it reflects), and every measured emitter whose share is at least
/// [`LIGHT_SHARE`]. When that leaves no object, every object may emit (the comparison fits then light the scene
/// as the whole fit's L1-penalised solve does). Also returns each emitter's share, for the record.
#[must_use]
pub fn comparison_emitters(emission: &[Vec3], sets: &PixelSets) -> (Vec<bool>, Vec<EmitterShare>) {
    let mut sum = vec![0.0f64; emission.len()];
    let mut n = vec![0usize; emission.len()];
    for t in &sets.train {
        if let Some(k) = t.object.map(|k| k as usize).filter(|&k| k < emission.len()) {
            if t.target.is_finite() {
                sum[k] += f64::from(t.target.element_sum()) / 3.0;
                n[k] += 1;
            }
        }
    }
    let emitters: Vec<EmitterShare> = emission
        .iter()
        .enumerate()
        .filter(|(_, e)| e.max_element() > 0.0)
        .map(|(k, e)| {
            let emitted = f64::from(e.element_sum()) / 3.0;
            let share =
                (n[k] >= crate::fit::solve::MIN_PIXELS && sum[k] > 0.0).then(|| emitted / (sum[k] / n[k] as f64));
            EmitterShare { object: k, share, light: share.is_none_or(|s| s >= LIGHT_SHARE) }
        })
        .collect();
    let mut lights = vec![false; emission.len()];
    for e in emitters.iter().filter(|e| e.light) {
        lights[e.object] = true;
    }
    if !lights.contains(&true) {
        lights = vec![true; emission.len()];
    }
    (lights, emitters)
}

/// What the exponent search minimises: the mean over channels of each channel's misfit relative to `first`
/// (its misfit in the first trial), so that each channel counts equally whatever its noise. The channels'
/// own minima straddle the right exponent: the comparison fits' interreflection absorbs part of a wrong power
/// in the brighter channels, whose minima lie low, while the darkest lies high (with the true response, red
/// / green / blue at 0.975 / 0.985 / 1.0 of the truth; with an estimated shared curve about 1.21 / 1.22 /
/// 1.30 where the gains need 1.25). The median kept the middle channel's bias; the mean uses all three
/// (measured in docs/photo/self-calibration.md, "The search's criterion").
#[must_use]
pub fn relative_mean(misfit: [f64; 3], first: [f64; 3]) -> f64 {
    (0..3).map(|c| misfit[c] / first[c]).sum::<f64>() / 3.0
}

/// Each step of the exponent search multiplies or divides the exponent by this: 1.25 brackets a display
/// curve's exponent relative to sRGB (0.4 to 2.5, a gamma 1 to a gamma 5.5 curve) within four steps either
/// way, and three misfits 25 % apart resolve the minimum's curvature above the fits' own scatter.
pub const EXPONENT_STEP: f64 = 1.25;
/// Fits tried before the final one: a bracket of up to four steps from the first point, then golden-section
/// probes until the bracket is narrow.
pub const MAX_EXPONENT_TRIALS: usize = 9;
/// Golden-section probes stop once the bracket around the best trial spans less than this ratio (±6 %): the
/// parabola through the three points then locates the minimum to a few per cent, while the misfit's own
/// scatter between fits would blur finer probes.
const MIN_BRACKET_RATIO: f64 = 1.12;
/// Golden-section fraction (2 − φ): the probe's share of the larger segment.
const GOLDEN: f64 = 0.381_966;

/// What the exponent search does next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NextExponent {
    /// Fit the photos raised to this exponent and measure its misfit.
    Try(f64),
    /// The search is over: the final fit uses this exponent.
    Final(f64),
}

/// The next step of the search over `trials` = (exponent, misfit in the original log units): walk by
/// [`EXPONENT_STEP`] downhill from the first trial until the misfit rises, narrow the bracket around the best
/// trial by golden-section probes, then take the vertex of the parabola through the best trial and its
/// neighbours (in log exponent), clamped between those neighbours.
#[must_use]
pub fn next_exponent(trials: &[(f64, f64)]) -> NextExponent {
    let mut t: Vec<(f64, f64)> =
        trials.iter().copied().filter(|(e, m)| e.is_finite() && *e > 0.0 && m.is_finite()).collect();
    t.sort_by(|a, b| a.0.total_cmp(&b.0));
    let Some(best) = (0..t.len()).min_by(|&a, &b| t[a].1.total_cmp(&t[b].1)) else {
        return NextExponent::Final(1.0);
    };
    let exhausted = trials.len() >= MAX_EXPONENT_TRIALS;
    if best == t.len() - 1 && best > 0 || t.len() == 1 {
        let up = t[best].0 * EXPONENT_STEP;
        return if exhausted { NextExponent::Final(t[best].0) } else { NextExponent::Try(up) };
    }
    if best == 0 {
        let down = t[0].0 / EXPONENT_STEP;
        return if exhausted { NextExponent::Final(t[0].0) } else { NextExponent::Try(down) };
    }
    let (x0, x1, x2) = (t[best - 1].0.ln(), t[best].0.ln(), t[best + 1].0.ln());
    // The misfit rises steeply above the right exponent (no material can add contrast the lighting lacks) and
    // gently below it (higher albedos flatten the lighting), so a parabola through a wide bracket is skewed:
    // the bracket is narrowed by golden-section probes in its larger segment first.
    if !exhausted && x2 - x0 > MIN_BRACKET_RATIO.ln() {
        let probe = if x2 - x1 > x1 - x0 { x1 + GOLDEN * (x2 - x1) } else { x1 - GOLDEN * (x1 - x0) };
        return NextExponent::Try(probe.exp());
    }
    let (y0, y1, y2) = (t[best - 1].1, t[best].1, t[best + 1].1);
    // Vertex of the parabola through the three points (divided differences).
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let curvature = (d12 - d01) / (x2 - x0);
    let vertex = if curvature > 0.0 { 0.5 * (x0 + x1) - d01 / (2.0 * curvature) } else { x1 };
    NextExponent::Final(vertex.clamp(x0, x2).exp())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::streams::{draw, uniform};

    /// Renders proportional to L with independent 30 % noise; photos L^s.
    fn case(s: f32) -> Misfit {
        let (mut samples, mut r1, mut r2) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..4000u64 {
            let l = 0.05 + 2.0 * uniform(1, draw::HOLDOUT, i, 0) as f32;
            let noise = |d: u64| 1.0 + 0.3 * (uniform(1, draw::HOLDOUT, i, d) as f32 - 0.5);
            let pixel = PixelRef { view: 0, x: i as u32, y: 0 };
            samples.push(Sample { pixel, target: Vec3::splat(l.powf(s)), object: Some(0) });
            r1.push(Vec3::splat(l * noise(1)));
            r2.push(Vec3::splat(l * noise(2)));
        }
        log_misfit(&samples, &r1, &r2)
    }

    #[test]
    fn render_noise_is_removed_and_a_wrong_exponent_is_seen() {
        let right = case(1.0);
        assert_eq!(right.terms, 12_000);
        // Render noise alone: the corrected misfit is ~0 (uncorrected it would be ~0.0075).
        assert!(right.value.abs() < 5e-4, "{right:?}");
        for s in [0.6, 1.5] {
            let wrong = case(s);
            assert!(wrong.value > 20.0 * right.value.abs().max(1e-4), "s = {s}: {wrong:?} vs {right:?}");
        }
    }

    #[test]
    fn search_walks_downhill_then_takes_the_parabola_vertex() {
        // Misfit (ln e − ln 1.9)² + 1: the search steps up from 1 and ends near 1.9.
        let misfit = |e: f64| (e.ln() - 1.9f64.ln()).powi(2) + 1.0;
        let mut trials = vec![(1.0, misfit(1.0))];
        let last = loop {
            match next_exponent(&trials) {
                NextExponent::Try(e) => trials.push((e, misfit(e))),
                NextExponent::Final(e) => break e,
            }
            assert!(trials.len() <= MAX_EXPONENT_TRIALS, "{trials:?}");
        };
        assert!((last - 1.9).abs() < 1e-6, "exact for a parabola in ln e: {last} after {trials:?}");
        // An asymmetric minimum (steep above, gentle below, as measured on scans) is still found closely.
        let skewed = |e: f64| {
            let x = e.ln() - 1.9f64.ln();
            if x > 0.0 { 20.0 * x * x } else { x * x }
        };
        let mut trials = vec![(1.0, skewed(1.0))];
        let last = loop {
            match next_exponent(&trials) {
                NextExponent::Try(e) => trials.push((e, skewed(e))),
                NextExponent::Final(e) => break e,
            }
        };
        assert!((last / 1.9 - 1.0).abs() < 0.04, "{last} after {trials:?}");
        // Downhill the other way.
        let misfit = |e: f64| (e.ln() - 0.7f64.ln()).powi(2);
        let mut trials = vec![(1.0, misfit(1.0))];
        let last = loop {
            match next_exponent(&trials) {
                NextExponent::Try(e) => trials.push((e, misfit(e))),
                NextExponent::Final(e) => break e,
            }
        };
        assert!((last - 0.7).abs() < 1e-6, "{last}");
        // A minimum beyond the trials' reach ends at the last one tried.
        let mut trials = vec![(1.0, 0.0)];
        while let NextExponent::Try(e) = next_exponent(&trials) {
            trials.push((e, -e));
        }
        assert_eq!(trials.len(), MAX_EXPONENT_TRIALS);
        assert_eq!(next_exponent(&trials), NextExponent::Final(EXPONENT_STEP.powi(MAX_EXPONENT_TRIALS as i32 - 1)));
    }

    #[test]
    fn every_channel_counts_equally_whatever_its_noise() {
        let first = [8.8e-4, 6.4e-4, 1.7e-3];
        assert_eq!(relative_mean(first, first), 1.0);
        // Blue's log misfit is twice red's: a 10 % gain in red weighs as much as a 10 % gain in blue.
        let red = relative_mean([0.9 * 8.8e-4, 6.4e-4, 1.7e-3], first);
        let blue = relative_mean([8.8e-4, 6.4e-4, 0.9 * 1.7e-3], first);
        assert!((red - blue).abs() < 1e-12 && (red - (1.0 - 0.1 / 3.0)).abs() < 1e-12, "{red} {blue}");
        // Red and green better, blue worse: each moves the criterion by its own relative change.
        let c = relative_mean([0.9 * 8.8e-4, 0.8 * 6.4e-4, 1.2 * 1.7e-3], first);
        assert!((c - (0.9 + 0.8 + 1.2) / 3.0).abs() < 1e-12, "{c}");
    }

    #[test]
    fn unusable_pixels_are_skipped() {
        let samples = [Sample { pixel: PixelRef { view: 0, x: 0, y: 0 }, target: Vec3::ZERO, object: Some(0) }];
        let m = log_misfit(&samples, &[Vec3::ONE], &[Vec3::ONE]);
        assert_eq!(m.terms, 0);
        assert!(m.value.is_nan() && m.channel.iter().all(|v| v.is_nan()), "{m:?}");
    }

    /// A room: a wall (object 0) photographed at radiance 0.3 with a faint emission 0.02 left on it, a lamp
    /// (object 1) photographed at 4.0 emitting 3.6, a light no photo sees (object 2) and a box that emits
    /// nothing (object 3, seen).
    fn room(wall_emission: f32) -> (Vec<Vec3>, PixelSets) {
        let mut sets = PixelSets::default();
        for (object, radiance, count) in [(0u32, 0.3f32, 100u32), (1, 4.0, 40), (2, 1.0, 3), (3, 0.2, 50)] {
            for x in 0..count {
                let pixel = PixelRef { view: object, x, y: 0 };
                sets.train.push(Sample { pixel, target: Vec3::splat(radiance), object: Some(object) });
            }
        }
        let emission = vec![Vec3::splat(wall_emission), Vec3::splat(3.6), Vec3::new(8.0, 7.0, 5.0), Vec3::ZERO];
        (emission, sets)
    }

    #[test]
    fn comparison_fits_keep_lights_and_drop_glows() {
        let (emission, sets) = room(0.02);
        let (lights, shares) = comparison_emitters(&emission, &sets);
        assert_eq!(lights, [false, true, true, false]);
        assert_eq!(shares.iter().map(|e| e.object).collect::<Vec<_>>(), [0, 1, 2]);
        assert!((shares[0].share.unwrap() - 0.02 / 0.3).abs() < 1e-6);
        assert!((shares[1].share.unwrap() - 0.9).abs() < 1e-6);
        assert_eq!(shares[2].share, None, "3 training pixels do not measure it");
        // A wall that emits as much as half of what it shows is a light (a backlit panel).
        let (emission, sets) = room(0.15);
        assert_eq!(comparison_emitters(&emission, &sets).0, [true, true, true, false]);
    }

    #[test]
    fn with_no_light_every_object_may_emit() {
        let (mut emission, sets) = room(0.02);
        emission[1] = Vec3::ZERO;
        emission[2] = Vec3::ZERO;
        assert_eq!(comparison_emitters(&emission, &sets).0, [true; 4]);
    }
}
