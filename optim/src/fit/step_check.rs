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

/// What the check did with one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCheck {
    /// Fraction of the step taken: 1, 1/2, …, 1/2^[`HALVINGS`], or 0 when every fraction was refused.
    pub fraction: f64,
    /// Weighted mean data term at the start and at the point taken, on the step's pixels.
    pub loss_start: f64,
    pub loss_taken: f64,
}

/// Checks the step from `start` to `x` (flat parameter vectors of the same layout) on `draw` with `spp` paths
/// per pixel keyed by `key`, and moves `x` to the largest fraction of the step that is not significantly
/// worse than `start` (see the module docs). Both points lie in the parameter box, and so does every fraction.
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
    let weights: Vec<f64> = if draw.weights.len() == m { draw.weights.clone() } else { vec![1.0; m] };
    let groups: Vec<u32> = draw.samples.iter().map(|s| s.object.unwrap_or(u32::MAX)).collect();
    let residuals = |values: &[glam::Vec3], c: usize| -> Vec<f64> {
        draw.samples.iter().zip(values).map(|(s, v)| f64::from(s.target[c]) - f64::from(v[c])).collect()
    };
    let v0 = ctx.render(&layout::to_params(start), &pixels, spp, key)?;
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
    let mut fraction = 1.0;
    for _ in 0..=HALVINGS {
        for ((xi, &s), &c) in x.iter_mut().zip(start).zip(&candidate) {
            *xi = s + fraction * (c - s);
        }
        let v = ctx.render(&layout::to_params(x), &pixels, spp, key)?;
        let l1 = per_row(&std::array::from_fn(|c| residuals(&v, c)));
        let diff: Vec<f64> = l1.iter().zip(&l0).map(|(a, b)| a - b).collect();
        let (_, t) = paired_t(&diff);
        if t <= WORSE_T {
            return Ok(StepCheck { fraction, loss_start, loss_taken: l1.iter().sum::<f64>() / (3 * m.max(1)) as f64 });
        }
        fraction *= 0.5;
    }
    x.copy_from_slice(start);
    Ok(StepCheck { fraction: 0.0, loss_start, loss_taken: loss_start })
}
