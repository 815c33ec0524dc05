//! The solve helpers shared by the per-object loop ([`super::object`]) and model selection
//! ([`super::select`]): the options of the linearised solves, the pixels each solve draws, and the pixel count
//! below which an object's material is unconstrained.

use super::emission_solve::{SolveOptions, Support, Unknowns};
use super::linear::DataLoss;
use super::pixels::{PixelSets, WeightedDraw};
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
        support: Support::Current,
        // Huber with one corner per object, not L1: on an object whose pixels have two colours L1's minimum is
        // flat between them (docs/optim/design-measurements.md, "Solve pixels per object and the checker
        // light").
        loss: DataLoss::GroupHuber,
        emission_l1: s.emission_l1,
        damping: GN_DAMPING,
        irls_iters: IRLS_ITERS,
        basis_rows: s.solve_pixels as usize,
    }
}

/// Paths per Jacobian entry of the Adam phase's emission solve after iteration `it` (0: the solve before the
/// first iteration): `interim_solve_spp` (at most `solve_spp`) when a later solve of the phase replaces it,
/// `solve_spp` for the last, whose emitters the refinement starts from
/// ([`ObjectFitSettings::interim_solve_spp`]).
pub(crate) fn adam_solve_spp(s: &ObjectFitSettings, it: u32) -> u32 {
    let replaced = s.emission_solve_every > 0 && it + s.emission_solve_every < s.iterations;
    if replaced { s.interim_solve_spp.min(s.solve_spp) } else { s.solve_spp }
}

/// Paths per pixel of a Gauss–Newton step's check ([`super::step_check::check_step`]): `check_spp`, at most
/// `solve_spp` ([`ObjectFitSettings::check_spp`]).
pub(crate) fn check_spp(s: &ObjectFitSettings) -> u32 {
    s.check_spp.min(s.solve_spp)
}

/// Solve pixels per object (and for the pixels that see no object) before the rest of `solve_pixels` is shared
/// in proportion to the objects' pixel counts. Drawn uniformly, 1024 pixels left each object of a 57-object scan
/// a handful of rows, and its hidden light was lost (emission error 1.0). 32 rows × 3 channels put an object's
/// albedo within about its per-pixel residual spread / √32 (5–10 % at `solve_spp` = 128, so 1–2 %); measured
/// on the scale sweep's objects axis: albedo L1 0.020–0.053 and light within 4–7 % with 8 to 48 extra boxes,
/// where the uniform draw ended at 0.16–0.31 and light errors of 1.0–2.5 (docs/optim/design-measurements.md,
/// "Solve pixels per object and the checker light").
pub(crate) const SOLVE_FLOOR: usize = 32;

/// Solve pixels of solve number `key`: [`SOLVE_FLOOR`] training pixels per object, the rest of `solve_pixels`
/// in proportion to the objects' training pixels, weighted so that every solve's data term is an unbiased
/// estimate of the loss over all training pixels ([`pixels::draw_stratified`]).
fn solve_samples(sets: &PixelSets, s: &ObjectFitSettings, seed: u64, key: u64) -> WeightedDraw {
    sets.draw_train_stratified(s.solve_pixels as usize, SOLVE_FLOOR, seed, draw::SOLVE_PIXELS, key)
}

/// Solve pixels of a linearised step on `unknowns` with random-number key `key`: [`solve_samples`] for a step on
/// the emission alone, [`joint_samples`] for a step on emission and base colour together.
pub(crate) fn step_samples(
    sets: &PixelSets,
    s: &ObjectFitSettings,
    unknowns: Unknowns,
    seed: u64,
    key: u64,
) -> WeightedDraw {
    match unknowns {
        Unknowns::Emission => solve_samples(sets, s, seed, key),
        Unknowns::EmissionAndBaseColor => joint_samples(sets, s, seed, key),
    }
}

/// Solve pixels of a joint step (emission and base colour together: the refinement and the model-selection
/// re-fits): as [`solve_samples`], but at least twice the floors' total, the second half shared by pixel count.
/// A joint step has three base-colour unknowns per object besides the lights, and with the floor alone its
/// draw of rows, not its paths, set where the step lands: on the 213-object house, re-fits from one state at
/// 32 rows per object × 128 paths ended at object-level albedo L1 0.058–0.064, at × 512 paths 0.054, and with
/// as many rows again by pixel count at 0.042–0.046 for 1.6× the time (docs/optim/design-measurements.md,
/// "Rows, not paths, for the joint steps"). On a scan of few objects `solve_pixels` already exceeds this and the
/// draw is [`solve_samples`]'s.
fn joint_samples(sets: &PixelSets, s: &ObjectFitSettings, seed: u64, key: u64) -> WeightedDraw {
    let rows = (s.solve_pixels as usize).max(2 * SOLVE_FLOOR * sets.strata.len());
    sets.draw_train_stratified(rows, SOLVE_FLOOR, seed, draw::SOLVE_PIXELS, key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::pixels::Sample;
    use glam::Vec3;
    use tracer::PixelRef;

    /// Training pixels of `objects` objects, object k seen by 400 + 10·k of them, and 400 that see no object.
    fn sets(objects: u32) -> PixelSets {
        let sample = |view: u32, x: u32, object: Option<u32>| Sample {
            pixel: PixelRef { view, x, y: 0 },
            target: Vec3::ONE,
            object,
        };
        let mut train: Vec<Sample> =
            (0..objects).flat_map(|k| (0..400 + 10 * k).map(move |x| sample(k, x, Some(k)))).collect();
        train.extend((0..400).map(|x| sample(objects, x, None)));
        PixelSets::of_train(train)
    }

    /// Every emission solve of the Adam phase but its last takes `interim_solve_spp`, never more than
    /// `solve_spp`; the only solve of a phase without re-solves takes `solve_spp`.
    #[test]
    fn only_the_adam_solves_that_a_later_one_replaces_take_the_interim_paths() {
        let s = ObjectFitSettings::default();
        let (interim, full) = (s.interim_solve_spp, s.solve_spp);
        assert!(interim < full);
        // Iterations 100, a solve every 25: before the first iteration and after 25, 50 and 75.
        assert_eq!([0, 25, 50, 75].map(|it| adam_solve_spp(&s, it)), [interim, interim, interim, full]);
        let once = ObjectFitSettings { emission_solve_every: 0, ..s.clone() };
        assert_eq!(adam_solve_spp(&once, 0), full, "the only solve is not replaced");
        let rarely = ObjectFitSettings { emission_solve_every: 60, ..s.clone() };
        assert_eq!([0, 60].map(|it| adam_solve_spp(&rarely, it)), [interim, full]);
        let few = ObjectFitSettings { solve_spp: 16, ..s.clone() };
        assert_eq!(adam_solve_spp(&few, 0), 16);
    }

    /// A step's check takes `check_spp` paths, never more than the solve's own `solve_spp`.
    #[test]
    fn the_step_check_takes_its_own_paths_and_never_more_than_the_solve() {
        let s = ObjectFitSettings::default();
        assert!(s.check_spp < s.solve_spp);
        assert_eq!(check_spp(&s), s.check_spp);
        let few = ObjectFitSettings { solve_spp: 16, ..s.clone() };
        assert_eq!(check_spp(&few), 16);
        let all = ObjectFitSettings { check_spp: 512, ..s.clone() };
        assert_eq!(check_spp(&all), s.solve_spp);
    }

    /// A step on the emission draws `solve_pixels` rows or the floors' total, whichever is larger; a joint step
    /// at least twice the floors' total, every stratum with at least its floor; on a scan of few objects both
    /// draw the same rows.
    #[test]
    fn a_joint_step_draws_twice_the_floors_and_few_objects_draw_as_an_emission_step() {
        let s = ObjectFitSettings::default();
        let (seed, key) = (3, 11);
        for objects in [5u32, 40, 200] {
            let sets = sets(objects);
            let strata = sets.strata.len();
            assert_eq!(strata, objects as usize + 1);
            let emission = step_samples(&sets, &s, Unknowns::Emission, seed, key);
            let joint = step_samples(&sets, &s, Unknowns::EmissionAndBaseColor, seed, key);
            let solve_pixels = s.solve_pixels as usize;
            assert_eq!(emission.samples.len(), solve_pixels.max(SOLVE_FLOOR * strata), "{objects} objects");
            assert_eq!(joint.samples.len(), solve_pixels.max(2 * SOLVE_FLOOR * strata), "{objects} objects");
            for st in &sets.strata {
                let got = joint.samples.iter().filter(|t| t.object == st.object).count();
                assert!(got >= SOLVE_FLOOR.min(st.population), "{objects} objects, {:?}: {got} rows", st.object);
            }
            if 2 * SOLVE_FLOOR * strata <= solve_pixels {
                assert_eq!(joint, emission, "{objects} objects");
            }
        }
    }
}
