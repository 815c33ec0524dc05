//! The solve helpers shared by the per-object loop ([`super::object`]) and model selection
//! ([`super::select`]): the options of the linearised solves, the pixels each solve draws, and the pixel count below which an object's material is unconstrained.

use super::emission_solve::{SolveOptions, Unknowns};
use super::linear::DataLoss;
use super::pixels::{self, PixelSets, Sample};
use super::settings::ObjectFitSettings;
use crate::streams::draw;

/// An object is "seen" (its material constrained by the photos) when at least this many training pixel
/// centres land on it: below that a handful of pixels would fix a whole material, so such an object is
/// reported as unconstrained instead.
pub(crate) const MIN_PIXELS: usize = 16;

/// IRLS rounds per linearised solve: the L1 solution of a 10–30 variable problem settles in well under 20.
const IRLS_ITERS: usize = 20;

/// Marquardt damping of the Gauss–Newton base-colour step (fraction of the diagonal): 0.1 keeps the first
/// step from a grey start stable and costs little once near the solution.
const GN_DAMPING: f64 = 0.1;

pub(crate) fn solve_options(s: &ObjectFitSettings, unknowns: Unknowns) -> SolveOptions {
    SolveOptions {
        unknowns,
        loss: DataLoss::L1,
        emission_l1: s.emission_l1,
        damping: GN_DAMPING,
        irls_iters: IRLS_ITERS,
    }
}

/// Solve pixels of solve number `key`: `solve_pixels` training pixels drawn uniformly.
pub(crate) fn solve_samples(sets: &PixelSets, s: &ObjectFitSettings, seed: u64, key: u64) -> Vec<Sample> {
    pixels::draw(&sets.train, s.solve_pixels as usize, seed, draw::SOLVE_PIXELS, key)
}
