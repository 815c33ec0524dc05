//! What model selection's paired held-out comparisons share (`super::select`'s lobe and emission tests,
//! `super::family`'s metal test, `super::horizon`'s split test, and the per-triangle stage's lobe family look,
//! `crate::triangle::family`): the thresholds a term must pass, the two renders of the same pixels with common
//! random numbers that each test compares, the sequential looks that stop a test early when it cannot pass or
//! clearly passes, and the per-object lobe test built on them.

use super::jacobian::Ctx;
use super::linear::{self, paired_t};
use super::pixels::Sample;
use super::{FitError, ObjectFitSettings};
use crate::blocks::RENDER_BLOCK;
use crate::progress::check_stop;
use crate::streams::{self, draw};
use tracer::PixelRef;

/// The squared error's t at which it confirms an alternative that a test kept on the L1 (one-sided 5 %, the
/// conventional level of a confirmation: the discovery's level is [`T_KEEP`]'s).
pub(crate) const T_CONFIRM: f64 = 1.645;

/// A term is kept when the paired t-statistic of its held-out improvement exceeds 3 (one-sided p ≈ 0.1 %:
/// with tens of objects, a spurious acceptance is unlikely)…
pub(crate) const T_KEEP: f64 = 3.0;
/// …and the improvement is at least 0.5 % of the mean held-out |target| (a statistically clear but practically
/// invisible gain does not justify extra parameters; on the glossy fixture the floor's lobe gains 4.2 % and
/// the box's 12 %, while on it and on the default scene every diffuse wall's best lobe made the residual worse).
pub(crate) const MIN_GAIN: f64 = 0.005;

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

/// The two renders that stand for one at `spp` paths and key `key` where a statistic needs two independent
/// estimates: half the paths each (at least one), the second at `key` XOR [`streams::key::SECOND_ESTIMATE`].
pub(super) fn half_paths(spp: u32, key: u64) -> [(u32, u64); 2] {
    let half = (spp / 2).max(1);
    [(half, key), (half, key ^ streams::key::SECOND_ESTIMATE)]
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
pub(crate) enum Stop {
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
pub(crate) const FIRST_LOOK: usize = 256;
/// Times `object.holdout_spp` at which the tests between the lobe families (metal against dielectric or Lambert)
/// render their two models. A metal is the noisier model, the more so the sharper its lobe, and its tests are
/// a small part of the object stage (13 s of the corpus house's ~8 min at 1×), so they trace more paths than the
/// other held-out tests.
pub(crate) const METAL_TEST_PATHS: u32 = 4;

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

/// What a paired held-out test compares per pixel, between two models rendered with common random numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Statistic {
    /// The L1 distance to the photo of one render per model at `holdout_spp` paths. Its expectation is
    /// inflated by the render's Monte Carlo noise, the more so the brighter and sharper a lobe (by a third on
    /// a metal of the corpus house at 64 paths): a sharp, bright lobe is judged against a handicap.
    L1,
    /// For an alternative whose renders are the noisier (a metal lobe, against a dielectric or a diffuse
    /// surface): each model is rendered twice at half the paths each, and the alternative passes on either
    /// of two statistics. The L1 of the two renders' mean errs only against the noisier model, so where it
    /// passes the evidence is clear; the unbiased squared error (a₁ − t)·(a₂ − t), whose expectation is the
    /// squared error of the converged render, does not err either way, but its products of two residuals
    /// are heavy-tailed (a reflected lamp's pixels), and alone it lost first-look metals of the corpus house
    /// at t = 0.9–2.9, two of them at gains of 49 % and 69 % (docs/optim/design-measurements.md, "An unbiased
    /// test for metals"). Two tests at a one-sided 0.1 % each accept a spurious metal with a probability of at
    /// most 0.2 %. A pass on the L1 that the squared error refutes beyond doubt does not count
    /// ([`Verdict::passes`]): on the corpus house a diffuse box's metal alternative, its colour at the top of
    /// the domain in red, fitted the bulk of its pixels better (L1 t = 3.2 and 3.9 in two runs) and a minority
    /// far worse (squared error t = −3.8 and −3.6), and became a metal 0.44 off its true colour
    /// (docs/optim/design-measurements.md, "A pass on the L1 that the squared error refutes").
    L1OrSquaredError,
}

/// The squared-error half of a [`Statistic::L1OrSquaredError`] comparison: per pixel, the first model's
/// unbiased squared error minus the alternative's (summed over the channels), and each model's mean
/// per-channel unbiased squared error.
pub(crate) struct Squared {
    pub(crate) d: Vec<f64>,
    pub(crate) mean_squares: (f64, f64),
}

/// The paired differences of a test on `rows` (per pixel, summed over the channels; positive where the
/// alternative `i_t` fits better than `i_d`): the L1 differences, of the first render for [`Statistic::L1`]
/// and of the two renders' mean for [`Statistic::L1OrSquaredError`], and for the latter the squared errors.
/// `target(j)` is row j's photo value, and `i_d[j]` and `i_t[j]` hold its two renders (the second unused by
/// [`Statistic::L1`]).
pub(crate) fn differences(
    statistic: Statistic,
    target: impl Fn(usize) -> [f64; 3],
    rows: &[usize],
    i_d: &[[glam::Vec3; 2]],
    i_t: &[[glam::Vec3; 2]],
) -> (Vec<f64>, Option<Squared>) {
    let value = |v: &[glam::Vec3; 2]| match statistic {
        Statistic::L1 => v[0].as_dvec3().to_array(),
        Statistic::L1OrSquaredError => (0.5 * (v[0].as_dvec3() + v[1].as_dvec3())).to_array(),
    };
    let d_l1 = rows
        .iter()
        .map(|&j| {
            let t = target(j);
            l1(t, value(&i_d[j])) - l1(t, value(&i_t[j]))
        })
        .collect();
    if statistic == Statistic::L1 {
        return (d_l1, None);
    }
    let product = |t: [f64; 3], v: &[glam::Vec3; 2]| {
        (0..3).map(|c| (f64::from(v[0][c]) - t[c]) * (f64::from(v[1][c]) - t[c])).sum::<f64>()
    };
    let (mut sum_d, mut sum_t) = (0.0, 0.0);
    let d = rows
        .iter()
        .map(|&j| {
            let t = target(j);
            let (qd, qt) = (product(t, &i_d[j]), product(t, &i_t[j]));
            sum_d += qd;
            sum_t += qt;
            qd - qt
        })
        .collect();
    let per_channel = (3 * rows.len().max(1)) as f64;
    (d_l1, Some(Squared { d, mean_squares: (sum_d / per_channel, sum_t / per_channel) }))
}

impl Squared {
    /// The alternative's gain, the drop of the RMS error per channel as a fraction of the per-channel mean
    /// radiance (`mean_target` is summed over the channels), in the radiance's units as the L1 gain is, so
    /// that [`MIN_GAIN`] means the same for both; and the paired t-statistic.
    pub(crate) fn gain(&self, mean_target: f64) -> (f64, f64) {
        let (a, b) = self.mean_squares;
        (
            (linear::root_mean_square(a) - linear::root_mean_square(b)) / (mean_target / 3.0).max(f64::MIN_POSITIVE),
            paired_t(&self.d).1,
        )
    }

    /// [`MIN_GAIN`] of `mean_target` in the differences' units, at the models' current mean squares
    /// (a² − b² = (a − b)(a + b)).
    fn min_difference(&self, mean_target: f64) -> f64 {
        MIN_GAIN
            * mean_target
            * (linear::root_mean_square(self.mean_squares.0) + linear::root_mean_square(self.mean_squares.1))
    }
}

/// One object's paired held-out comparison in [`sequential_lobe_test`]: its L1 differences (the first model's
/// L1 minus the alternative's, per pixel looked at), its squared errors for [`Statistic::L1OrSquaredError`],
/// how many pixels it had, and why it stopped early.
pub(crate) struct Verdict {
    pub(crate) d: Vec<f64>,
    pub(crate) squared: Option<Squared>,
    pub(crate) n_full: usize,
    pub(crate) stopped: Option<Stop>,
}

/// Whether a gain `rel` (a fraction of the mean radiance) at paired t-statistic `t` keeps a term.
fn pays((rel, t): (f64, f64)) -> bool {
    t > T_KEEP && rel > MIN_GAIN
}

impl Verdict {
    /// The alternative's L1 gain as a fraction of the pixels' mean radiance `mean_target` (summed over the
    /// channels as the differences are), and the paired t-statistic.
    pub(crate) fn gain(&self, mean_target: f64) -> (f64, f64) {
        let (mean, t) = paired_t(&self.d);
        (mean / mean_target.max(f64::MIN_POSITIVE), t)
    }

    /// Whether the alternative is kept: t > [`T_KEEP`] and a gain above [`MIN_GAIN`] of `mean_target`, on the
    /// L1 or (for [`Statistic::L1OrSquaredError`]) on the squared error, unless the test stopped because it
    /// could not pass. A pass on the L1 does not count where the squared error refutes it (t < −[`T_KEEP`]):
    /// that statistic is unbiased, and finds the alternative worse beyond doubt, while the L1 of two renders'
    /// mean errs only against the noisier model, so its objection to a pass on the squared error is no
    /// evidence and does not count.
    pub(crate) fn passes(&self, mean_target: f64) -> bool {
        if self.stopped == Some(Stop::CannotPass) {
            return false;
        }
        let squared = self.squared.as_ref().map(|q| q.gain(mean_target));
        let refuted = squared.is_some_and(|(_, t)| t < -T_KEEP);
        (pays(self.gain(mean_target)) && !refuted) || squared.is_some_and(pays)
    }

    /// Whether the squared error shows the alternative's gain at t > [`T_CONFIRM`]: what a pass on the L1
    /// alone lacks where a rougher, richer model fits the bulk of an object's pixels better and the rest worse.
    /// False without squared errors.
    pub(crate) fn confirmed_by_squared_error(&self, mean_target: f64) -> bool {
        self.squared.as_ref().is_some_and(|q| q.gain(mean_target).1 > T_CONFIRM)
    }

    /// The test's figures, for a `why`: "L1 by +x % (t = a)" and, with squared errors, "and its RMS error by
    /// +y % (t = b)", the gains as percentages of the mean radiance.
    pub(crate) fn figures(&self, mean_target: f64) -> String {
        let (rel, t) = self.gain(mean_target);
        let l1 = format!("L1 by {:+.2} % (t = {t:.1})", 100.0 * rel);
        match &self.squared {
            Some(q) => {
                let (rel_q, t_q) = q.gain(mean_target);
                format!("{l1} and its RMS error by {:+.2} % (t = {t_q:.1})", 100.0 * rel_q)
            }
            None => l1,
        }
    }

    /// The pixels the verdict rests on, for a `why`.
    pub(super) fn on(&self) -> String {
        match self.stopped {
            Some(stop) => format!("{} of its {} pixels (stopped there: {})", self.d.len(), self.n_full, stop.reason()),
            None => format!("{} pixels", self.d.len()),
        }
    }
}

/// Whether a sequential test stops after the differences `d` (and `squared`) of the pixels it has looked at,
/// of `n_full`: where neither statistic can pass ([`cannot_pass`]) or either clearly passes
/// ([`clearly_passes`]), each against its least passing mean difference ([`MIN_GAIN`] of `mean_target`).
pub(crate) fn early_stop(d: &[f64], squared: Option<&Squared>, n_full: usize, mean_target: f64) -> Option<Stop> {
    // Each statistic's mean, standard error and least passing mean difference.
    let mut arms = vec![(linear::mean_se(d), MIN_GAIN * mean_target)];
    if let Some(q) = squared {
        arms.push((linear::mean_se(&q.d), q.min_difference(mean_target)));
    }
    if arms.iter().all(|&((mean, se), min)| cannot_pass(mean, se, d.len(), n_full, min)) {
        return Some(Stop::CannotPass);
    }
    if arms.iter().any(|&((mean, se), min)| clearly_passes(mean, se, d.len(), n_full, min)) {
        return Some(Stop::ClearlyPasses);
    }
    None
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
/// reflect each other), as the model that keeps them all would. `statistic` says what is compared per pixel:
/// for [`Statistic::L1OrSquaredError`] each model is rendered twice at half of `holdout_spp` each, the second
/// render at `key` XOR [`key::SECOND_ESTIMATE`], so a look costs the paths of one [`Statistic::L1`] look; an
/// object stops early where neither statistic can pass, or where either clearly passes.
#[allow(clippy::too_many_arguments)]
pub(super) fn sequential_lobe_test(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    statistic: Statistic,
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
    let mut i_d = vec![[glam::Vec3::ZERO; 2]; lobe_test.len()];
    let mut i_t = vec![[glam::Vec3::ZERO; 2]; lobe_test.len()];
    let two = half_paths(s.holdout_spp, key);
    let halves: &[(u32, u64)] = match statistic {
        Statistic::L1 => &[(s.holdout_spp, key)],
        Statistic::L1OrSquaredError => &two,
    };
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
        for (h, &(spp, key)) in halves.iter().enumerate() {
            let half = if halves.len() > 1 { format!(", render {}/{}", h + 1, halves.len()) } else { String::new() };
            let (a, b) = paired_renders(
                ctx,
                (&params_d, &params_t),
                &pix,
                spp,
                key,
                progress,
                &format!(
                    "model selection: {name}, look {look} ({} objects, {} pixels){half}, block",
                    open.len(),
                    pix.len()
                ),
            )?;
            for (i, &j) in new_rows.iter().enumerate() {
                (i_d[j][h], i_t[j][h]) = (a[i], b[i]);
            }
        }
        rendered += pix.len();
        open.retain(|&k| {
            looked[k] = rows_of[k].len().min(n_look);
            if looked[k] == rows_of[k].len() {
                return false;
            }
            let (d, squared) = differences(statistic, |j| target(&lobe_test[j]), &rows_of[k][..looked[k]], &i_d, &i_t);
            stopped[k] = early_stop(&d, squared.as_ref(), rows_of[k].len(), mean_target);
            stopped[k].is_none()
        });
        n_look *= 2;
        look += 1;
    }
    let renders = 2 * halves.len();
    tracing::debug!(
        name,
        rendered,
        all = lobe_test.len(),
        renders,
        "paired test pixels rendered, each `renders` times"
    );
    Ok((0..k_count)
        .map(|k| {
            tested[k].then(|| {
                let (d, squared) =
                    differences(statistic, |j| target(&lobe_test[j]), &rows_of[k][..looked[k]], &i_d, &i_t);
                Verdict { d, squared, n_full: rows_of[k].len(), stopped: stopped[k] }
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pixels of radiance 0.5 whose renders are `mean` plus zero-mean noise of spread `noise` (uniform,
    /// seeded), compared by [`Statistic::L1OrSquaredError`]: each row's two renders are independent draws, and
    /// each model has its own draws (as renders of different materials with the same random numbers have
    /// different noise).
    fn noisy_renders(n: usize, (mean_d, noise_d): (f32, f32), (mean_t, noise_t): (f32, f32)) -> Verdict {
        let test: Vec<Sample> = (0..n)
            .map(|i| Sample {
                pixel: PixelRef { view: 0, x: i as u32, y: 0 },
                target: glam::Vec3::splat(0.5),
                object: Some(0),
            })
            .collect();
        let draw = |i: usize, stream: u64| {
            let u = |c: u64| streams::uniform(9, stream, i as u64, c) as f32 - 0.5;
            glam::Vec3::new(u(0), u(1), u(2))
        };
        let render = |i: usize, (mean, noise): (f32, f32), stream: u64| {
            [glam::Vec3::splat(mean) + noise * draw(i, stream), glam::Vec3::splat(mean) + noise * draw(i, stream + 1)]
        };
        let i_d: Vec<_> = (0..n).map(|i| render(i, (mean_d, noise_d), 0)).collect();
        let i_t: Vec<_> = (0..n).map(|i| render(i, (mean_t, noise_t), 2)).collect();
        let rows: Vec<usize> = (0..n).collect();
        let (d, squared) = differences(Statistic::L1OrSquaredError, |j| target(&test[j]), &rows, &i_d, &i_t);
        Verdict { d, squared, n_full: n, stopped: None }
    }

    #[test]
    fn the_squared_error_is_not_biased_by_the_renders_noise() {
        let mean_target = 1.5; // 0.5 per channel, summed over the three
        // Both models 0.05 off the photos; the alternative renders with noise of spread 0.8, the model with
        // 0.1. The L1 refuses the noisier alternative beyond doubt; the squared error sees no difference.
        let v = noisy_renders(4096, (0.55, 0.1), (0.45, 0.8));
        let (l1_gain, l1_t) = v.gain(mean_target);
        let (gain, t) = v.squared.as_ref().unwrap().gain(mean_target);
        assert!(l1_t < -T_KEEP && l1_gain < -0.1, "L1: {l1_gain} {l1_t}");
        assert!(t.abs() < T_KEEP && gain.abs() < 0.02, "squared error: {gain} {t}");
        assert!(!v.passes(mean_target));
        // A noisy alternative 0.02 off against a quiet model 0.05 off: the L1 refuses it, the squared error
        // keeps it, and its gain is the drop of the RMS error, 0.03 or 6 % of the radiance 0.5 (±1 % for the
        // noise of 4096 pixels).
        let v = noisy_renders(4096, (0.55, 0.1), (0.52, 0.4));
        let (l1_gain, l1_t) = v.gain(mean_target);
        let (gain, t) = v.squared.as_ref().unwrap().gain(mean_target);
        assert!(l1_t < T_KEEP || l1_gain < MIN_GAIN, "L1: {l1_gain} {l1_t}");
        assert!(t > T_KEEP && (gain - 0.06).abs() < 0.01, "squared error: {gain} {t}");
        assert!(v.passes(mean_target));
        // The same alternative where it stopped because neither statistic could pass: refused.
        assert!(!Verdict { stopped: Some(Stop::CannotPass), ..v }.passes(mean_target));
    }

    /// The verdict on 4096 pixels of photo 0.5 (mean radiance 1.5 summed over the channels) between a model
    /// 0.05 off on every pixel and an alternative `off(j)` off on pixel j, both rendered without noise (both
    /// estimates equal), so the differences carry only the pixels' own spread.
    fn verdict_against_a_uniform_misfit(off: impl Fn(usize) -> f32) -> Verdict {
        let n = 4096;
        let rows: Vec<usize> = (0..n).collect();
        let i_d: Vec<[glam::Vec3; 2]> = (0..n).map(|_| [glam::Vec3::splat(0.55); 2]).collect();
        let i_t: Vec<[glam::Vec3; 2]> = (0..n).map(|j| [glam::Vec3::splat(0.5 + off(j)); 2]).collect();
        let (d, squared) = differences(Statistic::L1OrSquaredError, |_| [0.5; 3], &rows, &i_d, &i_t);
        Verdict { d, squared, n_full: n, stopped: None }
    }

    #[test]
    fn a_pass_on_the_l1_that_the_squared_error_refutes_does_not_count() {
        let mean_target = 1.5; // 0.5 per channel, summed over the three
        // The alternative 0.02 off on 97 % of the pixels and 0.6 off on every 33rd. Its L1 is lower (0.11 against
        // 0.15 summed over the channels), its squared error far higher (0.034 against 0.0075 per pixel).
        let v = verdict_against_a_uniform_misfit(|j| if j % 33 == 0 { 0.6 } else { 0.02 });
        let (l1_gain, l1_t) = v.gain(mean_target);
        let (_, t) = v.squared.as_ref().unwrap().gain(mean_target);
        assert!(l1_t > T_KEEP && l1_gain > MIN_GAIN, "L1: {l1_gain} {l1_t}");
        assert!(t < -T_KEEP, "squared error: {t}");
        assert!(!v.passes(mean_target));
        // Without the squared error (a plain L1 test) the same differences pass.
        assert!(Verdict { squared: None, ..v }.passes(mean_target));
    }

    #[test]
    fn only_a_gain_the_squared_error_shows_beyond_its_noise_confirms_a_pass() {
        let mean_target = 1.5; // 0.5 per channel, summed over the three
        // Alternatives off by `near` on most pixels and by `far` on every 20th.
        let verdict =
            |near: f32, far: f32| verdict_against_a_uniform_misfit(move |j| if j % 20 == 0 { far } else { near });
        // Better everywhere: the L1 passes and the squared error confirms it.
        let better = verdict(0.02, 0.04);
        assert!(better.passes(mean_target) && better.confirmed_by_squared_error(mean_target));
        // 0.02 off on 95 % of the pixels and 0.21 on the rest: a lower L1 (0.030 against 0.05 per channel) and
        // about the model's squared error (0.0026 against 0.0025, t ≈ −0.6). It passes on the L1 and is not
        // confirmed.
        let bulk = verdict(0.02, 0.21);
        let (_, t) = bulk.squared.as_ref().unwrap().gain(mean_target);
        assert!(t <= T_CONFIRM && t > -T_KEEP, "squared error: {t}");
        assert!(bulk.passes(mean_target) && !bulk.confirmed_by_squared_error(mean_target));
        // Without squared errors nothing confirms.
        assert!(!Verdict { squared: None, ..better }.confirmed_by_squared_error(mean_target));
    }

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
