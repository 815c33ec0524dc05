//! What model selection's paired held-out comparisons share (`super::select`'s lobe and emission tests,
//! `super::family`'s metal test, `super::horizon`'s split test): the thresholds a term must pass, the two
//! renders of the same pixels with common random numbers that each test compares, the sequential looks that
//! stop a test early when it cannot pass or clearly passes, and the per-object lobe test built on them.

use super::jacobian::Ctx;
use super::linear::{self, paired_t};
use super::pixels::Sample;
use super::{FitError, ObjectFitSettings};
use crate::blocks::RENDER_BLOCK;
use crate::progress::check_stop;
use crate::streams::{self, draw};
use tracer::PixelRef;

/// A term is kept when the paired t-statistic of its held-out improvement exceeds 3 (one-sided p ≈ 0.1 %:
/// with tens of objects, a spurious acceptance is unlikely)…
pub(super) const T_KEEP: f64 = 3.0;
/// …and the improvement is at least 0.5 % of the mean held-out |target| (a statistically clear but practically
/// invisible gain does not justify extra parameters; on the glossy fixture the floor's lobe gains 4.2 % and
/// the box's 12 %, while on it and on the default scene every diffuse wall's best lobe made the residual worse).
pub(super) const MIN_GAIN: f64 = 0.005;

/// Two renders of the same pixels with the same random numbers (`key`), in blocks of [`RENDER_BLOCK`]
/// pixels (a house's lobe test renders ~3·10⁵ pixels at `holdout_spp`, minutes per render), one progress step per block and arm in a phase `phase`. Random numbers are keyed by the pixel, so
/// the blocks give exactly the values of one render of all the pixels.
pub(super) fn paired_renders(
    ctx: &Ctx<'_>,
    (a, b): (&tracer::Params, &tracer::Params),
    pixels: &[PixelRef],
    spp: u32,
    key: u64,
    progress: &dyn crate::Progress,
    phase: &str,
) -> Result<(Vec<glam::Vec3>, Vec<glam::Vec3>), FitError> {
    let blocks = pixels.len().div_ceil(RENDER_BLOCK);
    progress.phase(phase, 2 * blocks as u64, 0);
    let (mut out_a, mut out_b) = (Vec::with_capacity(pixels.len()), Vec::with_capacity(pixels.len()));
    for (i, block) in pixels.chunks(RENDER_BLOCK).enumerate() {
        check_stop(progress)?;
        out_a.extend(ctx.render(a, block, spp, key)?);
        progress.set_position(2 * i as u64 + 1);
        out_b.extend(ctx.render(b, block, spp, key)?);
        progress.set_position(2 * i as u64 + 2);
    }
    Ok((out_a, out_b))
}

/// The L1 distance of two RGB values (summed over the channels).
pub(super) fn l1(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).sum()
}

/// A sample's photo value as f64 RGB.
pub(super) fn target(s: &Sample) -> [f64; 3] {
    [f64::from(s.target.x), f64::from(s.target.y), f64::from(s.target.z)]
}

/// Why a sequential test stopped before its last look.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stop {
    /// [`cannot_pass`].
    CannotPass,
    /// [`clearly_passes`].
    ClearlyPasses,
}

impl Stop {
    /// What the `why` of a stopped test says about the pixels it did not look at.
    pub(super) fn reason(self) -> &'static str {
        match self {
            Stop::CannotPass => "on all of them it could not pass",
            Stop::ClearlyPasses => "on all of them it would pass",
        }
    }
}

/// Pixels of an object at the lobe test's first look: the test looks at 256, 512, 1024, … of its pixels
/// until it has looked at them all or [`cannot_pass`] or [`clearly_passes`] stops it. 256 pixels put the
/// standard error of a wall's mean paired difference well under the 0.5 % of [`MIN_GAIN`] (a diffuse wall's
/// best lobe changes its L1 by 0.1–0.3 %, docs/optim/design-measurements.md), so most walls stop at the first
/// look.
pub(super) const FIRST_LOOK: usize = 256;

/// Whether a test can stop after `n` of its `n_full` pixels because on all of them it could not plausibly
/// pass: the upper confidence bound of the mean gain, `mean + T_KEEP · se` (one-sided 0.1 %), is below what a
/// pass needs, the gain `min_gain` or `T_KEEP` standard errors of the full sample (`se · √(n / n_full)`).
/// Stopping only tests that would fail keeps their false acceptances as they are; what it risks is a term
/// lost, with probability ≲ 0.1 % per test, that the full test would keep.
pub(super) fn cannot_pass(mean: f64, se: f64, n: usize, n_full: usize, min_gain: f64) -> bool {
    if n < 2 || n >= n_full {
        return false;
    }
    let upper = mean + T_KEEP * se;
    upper < min_gain || upper < T_KEEP * se * (n as f64 / n_full as f64).sqrt()
}

/// Whether a test can stop after `n` of its `n_full` pixels because on all of them it would pass beyond
/// reasonable doubt: the lower confidence bound of the mean gain, `mean − T_KEEP · se` (one-sided 0.1 %), is
/// above what a pass needs, both the gain `min_gain` and `T_KEEP` standard errors of the full sample. The
/// mirror of [`cannot_pass`]: a term the full test would reject is kept with probability ≲ 0.1 % per test, and
/// a stopped test's t-statistic and gain, on its `n` pixels, pass by themselves (t > `T_KEEP` and the gain
/// above `min_gain`).
pub(super) fn clearly_passes(mean: f64, se: f64, n: usize, n_full: usize, min_gain: f64) -> bool {
    if n < 2 || n >= n_full {
        return false;
    }
    let lower = mean - T_KEEP * se;
    lower > min_gain && lower > T_KEEP * se * (n as f64 / n_full as f64).sqrt()
}

/// The paired differences of the lobe test on `rows` of `test`: L1 of the diffuse render minus L1 of the
/// render with the lobes, per pixel (positive where the lobe fits better).
pub(super) fn lobe_differences(test: &[Sample], rows: &[usize], i_d: &[glam::Vec3], i_t: &[glam::Vec3]) -> Vec<f64> {
    rows.iter()
        .map(|&j| {
            let t = &test[j];
            l1(target(t), i_d[j].as_dvec3().to_array()) - l1(target(t), i_t[j].as_dvec3().to_array())
        })
        .collect()
}

/// One object's paired held-out comparison in [`sequential_lobe_test`]: its paired differences (L1 of the first
/// model minus L1 of the alternative, per pixel looked at), how many pixels it had, and why it stopped early.
pub(super) struct Verdict {
    pub(super) d: Vec<f64>,
    pub(super) n_full: usize,
    pub(super) stopped: Option<Stop>,
}

impl Verdict {
    /// Whether the alternative is kept: t > [`T_KEEP`] and a gain above [`MIN_GAIN`] of `mean_target`, unless
    /// the test stopped because it could not pass.
    pub(super) fn passes(&self, mean_target: f64) -> bool {
        let (gain, t) = paired_t(&self.d);
        let rel = gain / mean_target.max(f64::MIN_POSITIVE);
        self.stopped != Some(Stop::CannotPass) && t > T_KEEP && rel > MIN_GAIN
    }

    /// The pixels the verdict rests on, for a `why`.
    pub(super) fn on(&self) -> String {
        match self.stopped {
            Some(stop) => format!("{} of its {} pixels (stopped there: {})", self.d.len(), self.n_full, stop.reason()),
            None => format!("{} pixels", self.d.len()),
        }
    }
}

/// Paired held-out test of an alternative model `xt` against `x` for every object with `tested[k]`, on that
/// object's rows of `lobe_test`. Common random numbers for both renders: the paired differences then carry
/// little path noise. The test looks at each object's pixels in a fixed random order, first at [`FIRST_LOOK`]
/// of them, then at twice as many per look up to all of them; an object whose alternative cannot plausibly
/// pass on all of them stops ([`cannot_pass`]), and so does one whose alternative would pass on all of them
/// beyond reasonable doubt ([`clearly_passes`]: a large glossy object's lobe gains at t = 10–25 on its 2048
/// pixels). The rest are decided on exactly the pixels, random numbers and renders of a single look at all of
/// them (random numbers are keyed by the pixel). Both models are rendered whole: where several objects are
/// tested at once, each one's pixels also see the others' alternatives (the lobes of neighbouring objects
/// reflect each other), as the model that keeps them all would.
#[allow(clippy::too_many_arguments)]
pub(super) fn sequential_lobe_test(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    lobe_test: &[Sample],
    tested: &[bool],
    (x, xt): (&[f64], &[f64]),
    mean_target: f64,
    key: u64,
    progress: &dyn crate::Progress,
    name: &str,
) -> Result<Vec<Option<Verdict>>, FitError> {
    let k_count = tested.len();
    let order_rank = |t: &Sample| streams::uniform(ctx.seed, draw::LOBE_TEST_ORDER, streams::pixel_key(t.pixel), 0);
    let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); k_count];
    for (j, t) in lobe_test.iter().enumerate() {
        if let Some(k) = t.object.map(|o| o as usize).filter(|&k| k < k_count && tested[k]) {
            rows_of[k].push(j);
        }
    }
    for rows in &mut rows_of {
        rows.sort_by(|&a, &b| order_rank(&lobe_test[a]).total_cmp(&order_rank(&lobe_test[b])).then(a.cmp(&b)));
    }
    let (params_d, params_t) = (ctx.params(x), ctx.params(xt));
    let mut i_d = vec![glam::Vec3::ZERO; lobe_test.len()];
    let mut i_t = vec![glam::Vec3::ZERO; lobe_test.len()];
    let mut open: Vec<usize> = (0..k_count).filter(|&k| tested[k] && !rows_of[k].is_empty()).collect();
    let mut looked = vec![0usize; k_count];
    let mut stopped: Vec<Option<Stop>> = vec![None; k_count];
    let mut n_look = FIRST_LOOK;
    let mut rendered = 0usize;
    let mut look = 1;
    while !open.is_empty() {
        let new_rows: Vec<usize> =
            open.iter().flat_map(|&k| rows_of[k][looked[k]..rows_of[k].len().min(n_look)].iter().copied()).collect();
        let pix: Vec<PixelRef> = new_rows.iter().map(|&j| lobe_test[j].pixel).collect();
        let (a, b) = paired_renders(
            ctx,
            (&params_d, &params_t),
            &pix,
            s.holdout_spp,
            key,
            progress,
            &format!("model selection: {name}, look {look} ({} objects, {} pixels), block", open.len(), pix.len()),
        )?;
        rendered += pix.len();
        for (i, &j) in new_rows.iter().enumerate() {
            (i_d[j], i_t[j]) = (a[i], b[i]);
        }
        open.retain(|&k| {
            looked[k] = rows_of[k].len().min(n_look);
            if looked[k] == rows_of[k].len() {
                return false;
            }
            let d = lobe_differences(lobe_test, &rows_of[k][..looked[k]], &i_d, &i_t);
            let (mean, se) = linear::mean_se(&d);
            if cannot_pass(mean, se, d.len(), rows_of[k].len(), MIN_GAIN * mean_target) {
                stopped[k] = Some(Stop::CannotPass);
                return false;
            }
            if clearly_passes(mean, se, d.len(), rows_of[k].len(), MIN_GAIN * mean_target) {
                stopped[k] = Some(Stop::ClearlyPasses);
                return false;
            }
            true
        });
        n_look *= 2;
        look += 1;
    }
    tracing::debug!(name, rendered, all = lobe_test.len(), "paired test pixels rendered (two renders each)");
    Ok((0..k_count)
        .map(|k| {
            tested[k].then(|| Verdict {
                d: lobe_differences(lobe_test, &rows_of[k][..looked[k]], &i_d, &i_t),
                n_full: rows_of[k].len(),
                stopped: stopped[k],
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_test_stops_only_when_it_cannot_pass_on_all_its_pixels() {
        // A lobe that makes the fit worse: mean −1, se 0.1 after 256 of 2048 pixels.
        assert!(cannot_pass(-1.0, 0.1, 256, 2048, 0.0));
        // Clearly better: never stopped.
        assert!(!cannot_pass(1.0, 0.1, 256, 2048, 0.0));
        // A gain of 0.1 at se 0.1 (t = 1): could still reach t > 3 on 8× the pixels, whose se is 0.035.
        assert!(!cannot_pass(0.1, 0.1, 256, 2048, 0.0));
        // The same gain and noise when the pass also needs a gain of 0.5: the upper bound 0.4 is below it.
        assert!(cannot_pass(0.1, 0.1, 256, 2048, 0.5));
        // At the last look the test is decided by its own rule, not stopped.
        assert!(!cannot_pass(-1.0, 0.1, 2048, 2048, 0.0));
        // A mean of −0.5 at se 0.3: its upper bound 0.4 is above what a pass on all pixels needs, T_KEEP
        // standard errors of the full sample (3 · 0.3 · √(256/2048) ≈ 0.32): goes on.
        assert!(!cannot_pass(-0.5, 0.3, 256, 2048, 0.0));
        // …while a mean of −0.7 at that noise (upper 0.2) cannot reach it.
        assert!(cannot_pass(-0.7, 0.3, 256, 2048, 0.0));
    }

    #[test]
    fn a_test_passes_early_only_beyond_reasonable_doubt() {
        // A gain of 1 at se 0.1 after 256 of 2048 pixels: lower bound 0.7, above 3 · 0.1 · √(1/8) ≈ 0.11.
        assert!(clearly_passes(1.0, 0.1, 256, 2048, 0.0));
        // The same when the pass also needs a gain of 0.8: the lower bound 0.7 is below it, so the test goes on.
        assert!(!clearly_passes(1.0, 0.1, 256, 2048, 0.8));
        // t = 4 on 256 pixels (mean 0.4, se 0.1): lower bound 0.1, under the 0.11 a pass on all pixels needs.
        assert!(!clearly_passes(0.4, 0.1, 256, 2048, 0.0));
        // A worse fit never passes early, and the last look is decided by its own rule.
        assert!(!clearly_passes(-1.0, 0.1, 256, 2048, 0.0));
        assert!(!clearly_passes(1.0, 0.1, 2048, 2048, 0.0));
        // Wherever it stops, the gain on the pixels seen passes the test's own rule: t > T_KEEP and the gain
        // above the minimum.
        for (mean, se, min_gain) in [(1.0, 0.1, 0.0), (0.9, 0.05, 0.5), (0.2, 0.01, 0.1), (0.46, 0.1, 0.0)] {
            assert!(clearly_passes(mean, se, 512, 2048, min_gain), "{mean} ± {se} should pass early");
            assert!(mean / se > T_KEEP && mean > min_gain);
        }
    }
}
