//! Settings of the per-object fit (`[object]` in the pipeline config). Every default is the value measured
//! on the default scene (data-fixtures/demo) to reach albedo mean L1 ≤ 0.01 and the light within 5 %
//! (tests/fit_demo.rs) inside the demo's time budget; see the module docs of [`crate::fit`]
//! for the method and `docs/optim/design-measurements.md` for the measurements.

use serde::{Deserialize, Serialize};

/// The per-pixel loss whose gradient Adam follows.
///
/// `l1` is the paper's: weight sign(I − I_target)/B. With a finite number of value paths that weight is
/// biased, because a Monte Carlo estimate's distribution is skewed (median below mean): measured at the truth
/// of the small room with 128 value paths, 64 seeds, every base-colour gradient component came out negative,
/// mean t = −2.6 (t ≈ −80 at 4 paths). `huber` is L1 beyond
/// `huber_delta · I_target` and L2 inside it: weight clamp((I − I_target)/(δ·I_target), −1, 1)/B, which keeps
/// L1's robustness to outliers far from the solution and is unbiased near it, where the Monte Carlo error is
/// inside the corner (tests/fit_gradient.rs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AdamLoss {
    L1,
    Huber,
}

/// Per-object fit settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectFitSettings {
    /// Adam iterations on the materials (paper §4.5), before the Gauss–Newton refinement.
    pub iterations: u32,
    /// Pixels per Adam batch, drawn uniformly over all valid pixels of all images.
    pub batch_pixels: u32,
    /// Adam learning rate at the start (parameters live in [0, 1]).
    pub lr: f64,
    /// The learning rate decays geometrically to `lr · lr_final_fraction` at the last Adam iteration.
    pub lr_final_fraction: f64,
    /// Paths per pixel of the value estimate I in the loss (paper: many, 2^7–2^10).
    pub n_value: u32,
    /// Paths per pixel of the gradient estimate ∂I/∂θ (paper: 1), drawn independently of the value paths.
    pub n_grad: u32,
    /// Loss of the Adam phase: `huber` (default) or `l1` (paper Eq. 3). See [`AdamLoss`].
    pub loss: AdamLoss,
    /// Corner of the Huber loss, relative to the target radiance of each pixel and channel.
    pub huber_delta: f64,
    /// Emission L1 weight, relative: an object's emission e_k costs `emission_l1 · s_k · e_k`, with s_k the
    /// mean |∂I/∂e_k| over the solve pixels — i.e. how strongly that emission moves the loss (a hidden light's s_k
    /// is ~1e-4 of a visible wall's), so one weight treats a visible wall and a hidden light alike. It applies in
    /// the Adam phase's emission-only solves, which choose the emitters; the re-fit with the lobes and the joint
    /// Gauss–Newton steps keep the emitters they start from, unpenalised.
    pub emission_l1: f64,
    pub seed: u64,
    /// A checkpoint is handed out every this many iterations (Adam iterations and refinement steps).
    pub checkpoint_every: u32,
    /// The emission is re-solved in closed form every this many Adam iterations (0 = only at the start).
    pub emission_solve_every: u32,
    /// Pixels in the closed-form emission solve and the Gauss–Newton refinement: 32 per object (and for the
    /// pixels that see no object), the rest in proportion to the objects' training pixels, each weighted by its
    /// object's share of the training pixels (`fit::pixels::draw_stratified`); with more than
    /// `solve_pixels / 32` objects a solve draws 32 per object, more than `solve_pixels`. A joint step on
    /// emission and base colour draws at least 64 per object on average (`fit::solve::joint_samples`).
    pub solve_pixels: u32,
    /// Paths per pixel of each Jacobian column / value in the solves; a solve that draws more than
    /// `solve_pixels` rows (32 per object) renders its emission columns with `solve_spp · solve_pixels` paths
    /// in all, fewer per row, so that their cost grows linearly with the objects
    /// ([`crate::fit::emission_solve::basis_spp`]).
    pub solve_spp: u32,
    /// Paths per pixel of the Adam phase's emission solves that a later one replaces (every one but the last; the
    /// solve before the first iteration too). They only set the emission that Adam's next iterations work
    /// against, and the last solve, at `solve_spp`, chooses the emitters the refinement starts from. Capped at
    /// `solve_spp`. On the 1280×1024 house the Adam phase is these solves, whose basis renders of every
    /// object's column cost about 20 s each at 128 paths (docs/scale/README.md, "Interim emission solves at
    /// half the paths").
    pub interim_solve_spp: u32,
    /// Paths per pixel of the check every Gauss–Newton step passes before it is taken (the refinement's and the
    /// model selection's re-fits, [`crate::fit::step_check`]); capped at `solve_spp`. The check compares the
    /// step's start and candidate rendered with the same random numbers, so most of their noise cancels in
    /// the paired differences it tests: at 64 paths it passes the small room's steps towards the truth and cuts
    /// back the harmful ones (lab/tests/fit_step_check.rs), and on the 1280×1024 house (held-out renders at 64
    /// paths in both runs) the refinement and the re-fit after a dropped emission took 115 s and 94 s instead of
    /// 127 s and 151 s (docs/scale/README.md, "Step checks and held-out renders at 64 paths").
    pub check_spp: u32,
    /// Gauss–Newton refinement steps on base colour and emission after the Adam phase.
    pub refine_steps: u32,
    /// Fraction of the valid pixels held out from every fit, used only to decide each object's model.
    pub holdout_fraction: f64,
    /// Largest number of held-out pixels per object, of pixels in an object's lobe test and of test pixels in
    /// an emitter's emission and horizon tests: the decisions need a sample of fixed size, not a fraction of
    /// the photos.
    pub holdout_pixels: u32,
    /// Largest number of training pixels kept per object (and of those that see no object), a uniform sample
    /// of its pixels; every draw over the training pixels still draws over all of them, each kept pixel
    /// standing for its object's pixel count over its kept count (`fit::pixels`), and memory stops growing
    /// with the photos (32 bytes per kept pixel). The default, 2²⁰, pools no object of any scene measured so
    /// far: a pool of 16 384 moved the hidden uplight of the corpus's `room-textured` from 5 % to ×2.3–4.4 in
    /// one run (docs/optim/design-measurements.md, "Costs at house scale"), and whether that is the pool or
    /// the draw's luck on a near-degenerate direction is not measured yet.
    pub train_pool: u32,
    /// Paths per pixel of the held-out renders that decide each object's model: the decision compares the
    /// residuals of two renders pixel by pixel with the same random numbers, so most of their noise cancels,
    /// and the sequential tests look at more pixels where what is left hides the effect. 128 decides as 512
    /// did: on the 1280×1024 house it keeps a lobe on 22 of the 41 glossy or metal objects (512: 23) and on 11
    /// of the 137 diffuse ones (512: 12), finds every light, and its albedo and light errors stay within the
    /// spread between runs, in 74 % of the object stage's time; the fixtures decide alike down to 64
    /// (docs/scale/README.md, "Held-out renders at 128 paths"; docs/tradeoff/). At 64 the 320×256 house's metal
    /// sphere `sphere-0-0` was held dielectric in 4 of 4 runs (at 128: 1 of 6), and the house's albedo L1 after
    /// the per-triangle stage was 0.0229 against 0.0190 (docs/scale/README.md, "Step checks and held-out renders
    /// at 64 paths").
    pub holdout_spp: u32,
    /// Try a specular lobe per object and keep it when the held-out residual improves significantly.
    pub try_specular: bool,
    /// Gauss–Newton steps on emission and base colour after specular lobes were kept (lobes fixed; averaged
    /// over the second half); 0 = only the emission is re-solved (materials fixed). The lobe itself comes from a
    /// roughness search ([`crate::fit::roughness`]). Default 0: the joint steps fit the light against the lobe's
    /// specular strength, whose search noise (glossy floor 0.68–0.78 for a true 0.8) they turned into light
    /// errors of up to 10 % (docs/optim/design-measurements.md, "Solve pixels per object and the checker
    /// light").
    pub specular_trial_steps: u32,
}

impl Default for ObjectFitSettings {
    fn default() -> Self {
        ObjectFitSettings {
            iterations: 100,
            batch_pixels: 64,
            lr: 0.02,
            lr_final_fraction: 0.1,
            n_value: 128,
            n_grad: 1,
            loss: AdamLoss::Huber,
            huber_delta: 0.5,
            emission_l1: 0.05,
            seed: 0,
            checkpoint_every: 50,
            emission_solve_every: 25,
            solve_pixels: 1024,
            solve_spp: 128,
            interim_solve_spp: 64,
            check_spp: 64,
            refine_steps: 8,
            holdout_fraction: 0.1,
            holdout_pixels: 2048,
            train_pool: 1 << 20,
            holdout_spp: 128,
            try_specular: true,
            specular_trial_steps: 0,
        }
    }
}
