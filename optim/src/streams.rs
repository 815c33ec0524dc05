//! Every random-number stream the optimiser draws from, in one registry. A result is reproducible only if
//! every random number is a pure function of its key (the architecture's reproducibility invariant: thread
//! count never changes a result, a resumed run ends where the uninterrupted run ends), and two uses that
//! shared a key would share their numbers; so each use takes its stream or key space from here, and the
//! values are fixed (changing one changes every result that draws from it).
//!
//! Two kinds of random numbers:
//! - the optimiser's own draws ([`uniform`], keyed by (seed, stream, a, b)): which pixels are held out, which
//!   pixels a batch or a solve uses — one [`draw`] stream per use;
//! - the tracer's path samples, keyed by (seed, iteration, pixel, sample, dimension): the `iteration`
//!   argument of every tracer call comes from a [`key`] space, disjoint between uses.

use tracer::PixelRef;

/// SplitMix64 (Steele et al. 2014): the optimiser's counter-based random numbers; a value depends only on its
/// key.
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform number in [0, 1) keyed by (seed, stream, a, b); `stream` is one of [`draw`].
#[must_use]
pub fn uniform(seed: u64, stream: u64, a: u64, b: u64) -> f64 {
    let h = mix64(mix64(mix64(seed ^ mix64(stream)) ^ a) ^ b);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A pixel's key for [`uniform`]: view, row and column packed (20 bits each for rows and columns).
#[must_use]
pub fn pixel_key(p: PixelRef) -> u64 {
    (u64::from(p.view) << 40) | (u64::from(p.y) << 20) | u64::from(p.x)
}

/// Streams of [`uniform`], one per use, so different uses never share numbers.
pub mod draw {
    /// Per-object fit: whether a pixel is held out (keyed by the pixel).
    pub const HOLDOUT: u64 = 1;
    /// Per-object fit: the pixels of an Adam batch (keyed by the iteration).
    pub const BATCH: u64 = 2;
    /// Per-object fit: the pixels of a closed-form solve (keyed by the solve's [`super::key`], and by the
    /// object stratum and index within it, `crate::fit::pixels::draw_stratified`), and of an object's roughness
    /// search (keyed by the solve's [`super::key`]).
    pub const SOLVE_PIXELS: u64 = 3;
    /// Model selection: whether a training pixel chooses its object's lobe or joins the lobe test (keyed by the
    /// pixel).
    pub const PROFILE: u64 = 4;
    /// Photometric calibration (the `preprocess` stage): the surface points whose photos are compared (keyed by
    /// the point's index and the coordinate drawn).
    pub const CALIBRATION_POINTS: u64 = 5;
    /// Per-object fit: which training pixels an object's pool keeps when it has more than the budget (keyed by
    /// the pixel; `crate::fit::pixels::collect`).
    pub const TRAIN_POOL: u64 = 6;
    /// Model selection: the order in which the emission tests draw the test pixels an emitter's light reaches
    /// (keyed by the pixel; one order for all emitters, so that their tests share pixels).
    pub const EMISSION_TEST: u64 = 7;
    /// Model selection: the order in which the lobe test looks at an object's pixels (keyed by the pixel).
    pub const LOBE_TEST_ORDER: u64 = 8;
    /// Model selection: which of the test pixels an emitter's light reaches its horizon test uses (keyed by
    /// the pixel; `crate::fit::horizon`).
    pub const HORIZON_TEST_ORDER: u64 = 9;
    /// Per-triangle fit: the pixels of a light solve, per object as the object stage's solves draw them (keyed
    /// by its [`super::key::triangle`] key and the object, `crate::fit::pixels::draw_strata_rows`).
    pub const TRIANGLE_EMISSION_PIXELS: u64 = 0x7265;
    /// Per-triangle fit: the pixels of an Adam batch (keyed by its [`super::key::triangle`] key).
    pub const TRIANGLE_BATCH: u64 = 0x7269;
    /// Per-triangle fit: the pixels of the check after a light re-solve (keyed by the pixel and the round).
    pub const TRIANGLE_LIGHT_CHECK: u64 = 0x7271;
    /// Per-triangle fit: which pixels a triangle keeps when it has more than its budget (keyed by the pixel;
    /// `crate::triangle::pixels::collect`).
    pub const TRIANGLE_PIXELS: u64 = 0x7270;
    /// Per-triangle fit: the order in which the lobe family look takes an object's pixels (keyed by the pixel
    /// and the round; `crate::triangle::family`).
    pub const TRIANGLE_FAMILY: u64 = 0x7266;
}

/// Key spaces of the tracer's `iteration` argument. The per-object fit's keys lie below 4·2^32, the
/// per-triangle fit's at 16·2^32 and above.
pub mod key {
    /// Per-object fit: emission solve number n (0 = the initial solve, else the Adam iteration it follows)
    /// at `SOLVE + n`.
    pub const SOLVE: u64 = 1 << 32;
    /// Per-object fit: Gauss–Newton refinement step at `REFINE + step`.
    pub const REFINE: u64 = 2 << 32;
    /// Per-object fit: the renders that check refinement step n ([`crate::fit::step_check`]) at
    /// `REFINE_CHECK + n`, start and candidates with the same key (common random numbers). 2^24 above the
    /// steps' own keys, below their second estimates' (XOR [`SECOND_ESTIMATE`]).
    pub const REFINE_CHECK: u64 = REFINE + (1 << 24);
    /// Model selection: the base of its fields below (2^20 apart); object k's profile pixels at `SELECT + k`.
    pub const SELECT: u64 = 3 << 32;
    /// Model selection: the renders with and without the specular lobes (common random numbers).
    pub const SELECT_LOBE_TEST: u64 = SELECT + (1 << 20);
    /// Model selection: the averaged steps after the lobes were kept.
    pub const SELECT_SPECULAR_STEPS: u64 = SELECT + (2 << 20);
    /// Model selection: the emission test's pilot columns (where each emitter's light arrives).
    pub const SELECT_EMISSION_COLUMNS: u64 = SELECT + (3 << 20);
    /// Model selection: object k's roughness search at `SELECT_ROUGHNESS + k`.
    pub const SELECT_ROUGHNESS: u64 = SELECT + (4 << 20);
    /// Model selection: object k's base-colour column in its emission refit at `SELECT_PIXEL_ROWS + k`.
    pub const SELECT_PIXEL_ROWS: u64 = SELECT + (5 << 20);
    /// Model selection: the averaged steps of the emission refit.
    pub const SELECT_EMISSION_REFIT: u64 = SELECT + (6 << 20);
    /// Tone-curve exponent check after a fit ([`crate::photometric`]): its first render at `EXPONENT`, the
    /// second, independent one at `EXPONENT` XOR [`SECOND_ESTIMATE`]; every trial of the search shares them.
    pub const EXPONENT: u64 = SELECT + (7 << 20);
    /// Model selection: the emission tests' renders, of the fitted model and of the models without an
    /// emission or with a lobe instead (common random numbers, the same for every emitter: the model's render
    /// at a pixel serves every test; object k's base-colour column at `SELECT_PIXEL_ROWS + k`).
    pub const SELECT_EMISSION_TEST: u64 = SELECT + (8 << 20);
    /// After model selection: the render and the two Jacobian estimates (XOR [`PROFILE_JACOBIAN`], and with
    /// [`SECOND_ESTIMATE`]) behind the standard errors of the unseen objects' base colours
    /// ([`crate::fit::prior`]), and the draw of their pixels.
    pub const UNSEEN_PRIOR: u64 = SELECT + (9 << 20);
    /// Model selection: object k's lobe without emission, the alternative its emission test weighs it against
    /// (`SELECT_EMISSION_LOBE + 2k` dielectric, `+ 2k + 1` metal roughness search; the render of its arm at
    /// `SELECT_EMISSION_TEST`, with the other arms).
    pub const SELECT_EMISSION_LOBE: u64 = SELECT + (10 << 20);
    /// Model selection: object k's columns of its two halves at the horizon in its emission test, when the test
    /// weighs its emission split (`SELECT_SPLIT_COLUMNS + k`; the split arm's render at `SELECT_EMISSION_TEST`).
    pub const SELECT_SPLIT_COLUMNS: u64 = SELECT + (11 << 20);
    /// Model selection: the horizon test's renders of the model with every candidate split and with one
    /// joined again (common random numbers, the same for every candidate; `crate::fit::horizon`).
    pub const SELECT_HORIZON_TEST: u64 = SELECT + (12 << 20);
    /// Model selection: object k's metal probes and metal roughness search in the second look at its lobe
    /// family, or, for an object the first look made metal, the search of its dielectric lobe that the second
    /// look weighs the metal against, at `SELECT_METAL + k` (`crate::fit::family`).
    pub const SELECT_METAL: u64 = SELECT + (13 << 20);
    /// Model selection: the renders of the second look's tests, with and without the metal lobes (common random
    /// numbers), and of its recheck of the first look's metals against their dielectric lobes.
    pub const SELECT_METAL_TEST: u64 = SELECT + (14 << 20);
    /// Model selection: object k's Lambert solve that the second look weighs its dielectric lobe against, at
    /// `SELECT_LAMBERT + k`, and (at `SELECT_LAMBERT_TEST`) the renders of that test (`crate::fit::family`).
    pub const SELECT_LAMBERT: u64 = SELECT + (15 << 20);
    pub const SELECT_LAMBERT_TEST: u64 = SELECT + (16 << 20);
    /// Model selection: the sky-gradient test's renders of the model with every kept split's sky graded and
    /// with one made flat again (common random numbers; `crate::fit::horizon`).
    pub const SELECT_SKY_TEST: u64 = SELECT + (17 << 20);
    /// Model selection: added to an averaged re-fit step's key for its step check (the steps' keys lie
    /// below it, the next field 2^20 above).
    pub const SELECT_STEP_CHECK: u64 = 1 << 19;
    /// XORed into a solve's key for its second, independent Jacobian estimate (instrumental variables).
    pub const SECOND_ESTIMATE: u64 = 1 << 31;
    /// XORed into a roughness-profile point's key for its Jacobian (the value and its slope must not share
    /// noise).
    pub const PROFILE_JACOBIAN: u64 = 1 << 30;
    /// XORed into a metal search's key for the renders of its start ([`crate::fit::roughness::ratio_start`]).
    pub const RATIO_START: u64 = 1 << 29;

    /// Per-triangle fit: the key for (round, step), distinct for every render of the stage and disjoint from
    /// the per-object fit's keys (< 4·2^32). Steps: ratio step k of pass p at `p·fit_steps + k` (< 2^16),
    /// Adam iteration i at [`TRIANGLE_ADAM`]` | i`, light solve of pass p at [`TRIANGLE_EMISSION`]` | p`.
    #[must_use]
    pub fn triangle(round: u32, step: u32) -> u64 {
        (16u64 << 32) | (u64::from(round) << 20) | u64::from(step)
    }
    /// Step field of [`triangle`] for the Adam iterations: above every ratio step (< 2^16 steps).
    pub const TRIANGLE_ADAM: u32 = 1 << 16;
    /// Step field of [`triangle`] for the light solve of pass p (`TRIANGLE_EMISSION | p`): above every ratio
    /// step and Adam key (< 2^17 iterations), below the 2^20 of the round field.
    pub const TRIANGLE_EMISSION: u32 = 1 << 17;
    /// Step field of [`triangle`] for the check of a round's light re-solve: above the light solves' keys
    /// (`TRIANGLE_EMISSION | p`, `| TRIANGLE_EMISSION_SECOND`), below the round field.
    pub const TRIANGLE_LIGHT_CHECK: u32 = 1 << 19;
    /// ORed into a light solve's key for its second, independent Jacobian estimate.
    pub const TRIANGLE_EMISSION_SECOND: u64 = 1 << 18;
    /// The render of the final per-triangle model behind the sub-triangle albedo detail
    /// ([`crate::triangle::detail`]): above every [`triangle`] key (< 17·2^32).
    pub const TRIANGLE_DETAIL: u64 = 17 << 32;
    /// The lobe family look ([`crate::triangle::family`]): the key of step `step` of alternative `alternative`
    /// of object `object` ([`TRIANGLE_FAMILY_TEST`] for the test's renders), above every [`triangle`] key and
    /// [`TRIANGLE_DETAIL`] (< 19·2^32): 20 bits of object, 4 of alternative, 8 of step.
    #[must_use]
    pub fn triangle_family(object: u32, alternative: u32, step: u32) -> u64 {
        (18u64 << 32)
            | (u64::from(object & 0xf_ffff) << 12)
            | (u64::from(alternative & 0xf) << 8)
            | u64::from(step & 0xff)
    }
    /// The alternative field of [`triangle_family`] for the renders of the look's test (steps 0 and 1: its two
    /// half-path renders).
    pub const TRIANGLE_FAMILY_TEST: u32 = 0xf;
    /// The alternative field of [`triangle_family`] for the ratio steps of the switched objects after the look
    /// (with the object field [`TRIANGLE_FAMILY_ALL`]; step k for the k-th step).
    pub const TRIANGLE_FAMILY_PASS: u32 = 0xd;
    /// The object field of [`triangle_family`] for keys that belong to no one object (the largest of 20 bits).
    pub const TRIANGLE_FAMILY_ALL: u32 = 0xf_ffff;
}

#[cfg(test)]
mod tests {
    use super::key::triangle;

    #[test]
    fn render_keys_are_distinct_per_round_and_step() {
        let mut keys: Vec<u64> = (0..4).flat_map(|r| (0..8).map(move |s| triangle(r, s))).collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), 32);
        assert!(triangle(0, 0) > 4 << 32);
    }
}
