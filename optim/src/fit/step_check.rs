//! The check every Gauss–Newton step of the refinement passes before it is taken (backtracking).
//!
//! The joint step ([`super::emission_solve`]) minimises a linearisation of the radiance — exact in emission,
//! first order in base colour — built from Monte Carlo Jacobians. Far from the solution, or along a direction
//! the photos hardly constrain (the albedo of a surface seen in a few pixels times the light it bounces), the
//! linearisation's minimiser can be worse than the point it started from, and the next step starts from
//! there: on the scale sweep's 8-box point the refinement's data term went 0.072 → 0.129 → 0.165 while the
//! light went from (31.9, 37.5, 19.2) to (42.3, 101.6, 45.8) and the ceiling's albedo jumped between 0 and 1
//! (docs/optim/design-measurements.md, "Checked Gauss–Newton steps").
//!
//! So the step's start and its candidate are both rendered on the step's own solve pixels with the same random
//! numbers (common random numbers: the difference of the two renders carries almost none of their Monte Carlo
//! noise), and their data terms are compared pixel by pixel — the solve's own data term, per-object Huber with
//! the corners of the start's residuals, row weights included. A candidate significantly worse than the start
//! (paired t above [`WORSE_T`]) is pulled halfway back, up to [`HALVINGS`] times; when no fraction of the step
//! passes, the parameters stay where they were. A step that only scatters around the solution is as often
//! better as worse on a draw and passes.
//!
//! A step can pass as a whole while one object's own pixels get much worse: a small object's few dozen rows
//! weigh little against a thousand others in the paired mean, and its gross misfit inflates the standard error
//! as much as the mean. So each object's own rows are also compared alone, and an object significantly worse
//! on them ([`WORSE_T_OBJECT`]) has its share of the step (its parameters) pulled halfway back, up to the same
//! number of times, and then returns to its start; the other objects keep theirs. Such a round renders again
//! only the pulled-back objects' own rows (the other rows keep their values from the round before, which the
//! pulled-back shares move only through interreflection), and what the rounds decide is confirmed by one render
//! of every row at the same fractions before it is acted on: the step is taken, or cut back as a whole, on a full
//! render, and objects still worse after the last halving return to their start without another render, as
//! they did before (docs/optim/design-measurements.md, "Step checks that render only the objects they pull
//! back").

use super::jacobian::Ctx;
use super::layout;
use super::linear::{corner_floor, group_corners, huber, paired_t};
use super::pixels::WeightedDraw;
use tracer::{PixelRef, TracerError};

/// A step is refused when its candidate's data term exceeds the start's by more than this many standard errors
/// of the paired per-pixel differences: a one-sided 2.3 % false-refusal rate for a step that changes nothing
/// on average, which then only loses that step's progress (the next step starts from the same point).
pub const WORSE_T: f64 = 2.0;

/// Halvings of a refused step before it is dropped: the last fraction tried is 1/8 of the step, below the ±1–2 %
/// scatter of converged steps on the small room, so a smaller fraction would be noise.
pub const HALVINGS: u32 = 3;

/// An object's own pixels refuse its share of a step when their data term is worse than at the start by more
/// than this many standard errors. Stricter than [`WORSE_T`] because it is applied once per object (with 31
/// objects, t > 3 refuses a step that changes nothing on average for one object in about 25 steps), and the
/// refusals it is for are gross: on Modern Hall single steps took a dark wood's base colour from 0.35 to 1 and
/// a wall's from 0.9 to 0.3 while the step as a whole passed, the object's few dozen rows outweighed by a
/// thousand others (docs/optim/design-measurements.md, "Small lamps and per-object step checks").
pub const WORSE_T_OBJECT: f64 = 3.0;

/// What the check did with one step.
#[derive(Debug, Clone, PartialEq)]
pub struct StepCheck {
    /// Fraction of the step taken by the objects the per-object check did not hold back: 1, 1/2, …,
    /// 1/2^[`HALVINGS`], or 0 when every fraction was refused.
    pub fraction: f64,
    /// Fraction of the step taken by each object's parameters (at most `fraction`).
    pub fractions: Vec<f64>,
    /// Weighted mean data term at the start and at the point taken, on the step's pixels.
    pub loss_start: f64,
    pub loss_taken: f64,
}

impl StepCheck {
    /// Objects whose own share of the step was cut below the common fraction.
    #[must_use]
    pub fn held_back(&self) -> usize {
        self.fractions.iter().filter(|&&f| f < self.fraction).count()
    }
}

/// Checks the step from `start` to `x` (flat parameter vectors of the same layout) on `draw` with `spp` paths
/// per pixel keyed by `key`, and moves `x` to the largest fraction of the step that is not significantly
/// worse than `start` (see the module docs), with the share of each object whose own pixels it makes
/// significantly worse cut back further. Both points lie in the parameter box, and so does every fraction.
pub fn check_step(
    ctx: &Ctx<'_>,
    start: &[f64],
    x: &mut [f64],
    draw: &WeightedDraw,
    spp: u32,
    key: u64,
) -> Result<StepCheck, TracerError> {
    let pixels: Vec<PixelRef> = draw.samples.iter().map(|s| s.pixel).collect();
    let m = pixels.len();
    let k_count = start.len() / layout::PER_OBJECT;
    let weights: Vec<f64> = if draw.weights.len() == m { draw.weights.clone() } else { vec![1.0; m] };
    let groups: Vec<u32> = draw.samples.iter().map(|s| s.object.unwrap_or(u32::MAX)).collect();
    let residuals = |values: &[glam::Vec3], c: usize| -> Vec<f64> {
        draw.samples.iter().zip(values).map(|(s, v)| f64::from(s.target[c]) - f64::from(v[c])).collect()
    };
    let v0 = ctx.render(&ctx.params(start), &pixels, spp, key)?;
    let r0: [Vec<f64>; 3] = std::array::from_fn(|c| residuals(&v0, c));
    // The solve's corners: per object, no smaller than the solve's floor for the channel.
    let corners: [Vec<f64>; 3] = std::array::from_fn(|c| {
        let mean_abs =
            draw.samples.iter().zip(&weights).map(|(s, w)| w * f64::from(s.target[c]).abs()).sum::<f64>() / m as f64;
        group_corners(&r0[c], Some(&groups), corner_floor(mean_abs))
    });
    let per_row = |r: &[Vec<f64>; 3]| -> Vec<f64> {
        (0..m).map(|j| weights[j] * (0..3).map(|c| huber(r[c][j], corners[c][j])).sum::<f64>()).collect()
    };
    let l0 = per_row(&r0);
    let loss_start = l0.iter().sum::<f64>() / (3 * m.max(1)) as f64;
    let candidate = x.to_vec();
    // Each object's rows, once: the per-object comparisons read them every round.
    let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); k_count];
    for (j, &g) in groups.iter().enumerate() {
        if let Some(rows) = rows_of.get_mut(g as usize) {
            rows.push(j);
        }
    }
    // x at object k's fraction of the step, for every k.
    let place = |x: &mut [f64], fractions: &[f64]| {
        for (k, f) in fractions.iter().enumerate() {
            for p in 0..layout::PER_OBJECT {
                let i = layout::idx(k, p);
                x[i] = start[i] + f * (candidate[i] - start[i]);
            }
        }
    };
    let mut fraction = 1.0;
    let mut fractions = vec![1.0; k_count];
    let mut rounds = 0;
    // The rows' values at the fractions last tried, and the rows the next round renders again: all of them
    // after a change of the common fraction, only the pulled-back objects' own rows after a per-object round
    // (a pixel's paths are keyed by the pixel, so a row rendered alone is the row rendered with all the others).
    let mut v: Vec<glam::Vec3> = Vec::new();
    let mut only: Option<Vec<usize>> = None;
    loop {
        place(x, &fractions);
        let partial = only.is_some();
        match only.take() {
            None => v = ctx.render(&ctx.params(x), &pixels, spp, key)?,
            Some(rows) => {
                let some: Vec<PixelRef> = rows.iter().map(|&j| pixels[j]).collect();
                let values = ctx.render(&ctx.params(x), &some, spp, key)?;
                rows.iter().zip(values).for_each(|(&j, value)| v[j] = value);
            }
        }
        let l1 = per_row(&std::array::from_fn(|c| residuals(&v, c)));
        let loss_taken = l1.iter().sum::<f64>() / (3 * m.max(1)) as f64;
        let diff: Vec<f64> = l1.iter().zip(&l0).map(|(a, b)| a - b).collect();
        let (_, t) = paired_t(&diff);
        let worse: Vec<usize> = if t > WORSE_T {
            Vec::new()
        } else {
            (0..k_count)
                .filter(|&k| fractions[k] > 0.0)
                .filter(|&k| {
                    let own: Vec<f64> = rows_of[k].iter().map(|&j| diff[j]).collect();
                    paired_t(&own).1 > WORSE_T_OBJECT
                })
                .collect()
        };
        // A round on some rows only goes on pulling objects back; every other decision waits for a render of
        // every row at the same fractions.
        if partial && !(t <= WORSE_T && !worse.is_empty() && rounds < HALVINGS) {
            continue;
        }
        if t <= WORSE_T && worse.is_empty() {
            return Ok(StepCheck { fraction, fractions, loss_start, loss_taken });
        }
        if rounds == HALVINGS {
            if t > WORSE_T {
                x.copy_from_slice(start);
                return Ok(StepCheck {
                    fraction: 0.0,
                    fractions: vec![0.0; k_count],
                    loss_start,
                    loss_taken: loss_start,
                });
            }
            // The step as a whole passes; the objects still worse on their own pixels return to their start
            // (not rendered again: `loss_taken` is that of the last fractions tried).
            worse.iter().for_each(|&k| fractions[k] = 0.0);
            place(x, &fractions);
            return Ok(StepCheck { fraction, fractions, loss_start, loss_taken });
        }
        rounds += 1;
        if t > WORSE_T {
            fraction *= 0.5;
            fractions.iter_mut().for_each(|f| *f = f.min(fraction));
        } else {
            worse.iter().for_each(|&k| fractions[k] *= 0.5);
            only = Some(worse.iter().flat_map(|&k| rows_of[k].iter().copied()).collect());
        }
    }
}
