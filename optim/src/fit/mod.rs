//! Per-object material and emission fit (paper §3–4): every object has one base colour, roughness, metallic,
//! specular and RGB emission; the photos are matched by path-traced estimates.
//!
//! # Method (see `object.rs` for the loop)
//! 1. **Emission solve** (closed form, [`emission_solve`]): with materials fixed, radiance is linear in
//!    emission; J from basis renders, e ≥ 0 by IRLS-L1 with a relative penalty.
//! 2. **Adam** (paper §4.5) on base colour: batches of `batch_pixels` pixels uniform over all valid training
//!    pixels, L1 loss with `n_value` value paths and `n_grad` independent gradient paths per pixel
//!    (weights sign(I − I_target)/B), geometric learning-rate decay, clamping to [0, 1]; emission re-solved
//!    every `emission_solve_every` iterations (variable projection: the emission always optimal for the
//!    current materials).
//! 3. **Gauss–Newton refinement** of base colour and emission jointly (`refine_steps` steps; the parameters
//!    returned are averaged over the second half of the steps).
//! 4. **Model selection** ([`select`]): each object starts diffuse with no emission; a specular lobe is tried
//!    per object — roughness by a 1-D search on the profile loss with base colour and specular solved for each
//!    roughness ([`roughness`]), on half of the object's training pixels, common random numbers — and kept only
//!    when it lowers the residual on the other half plus the held-out pixels significantly (paired t > 3 and a
//!    gain > 0.5 % of the mean radiance); with lobes kept, `specular_trial_steps` Gauss–Newton steps re-fit
//!    emission and base colour. An emission term is kept only when it lowers the held-out residual
//!    significantly. Objects seen in fewer than 16 training pixels are reported unconstrained. The decision,
//!    its reason and `constrained` are in [`ObjectModel`] and go to `materials.json` (`model`, `why`,
//!    `constrained`).
//!
//! All randomness is keyed by (seed, iteration), so a run resumed from a [`FitState`] checkpoint gives the
//! same result as an uninterrupted run (tests/fit_resume.rs).
//!
//! # Measurements (2 shared cores, debug build with optimised dependencies)
//! - Default scene (data-fixtures/demo: 9 objects, 8 views of 96×72), default settings: albedo mean L1
//!   0.0023 over the 8 non-emitting objects (largest error: the ceiling, seen in ~70 pixels), hidden light
//!   within 0.32 % (max over RGB), no other emitter, every wall and box "diffuse"; 35 s (tests/fit_demo.rs).
//! - Small room (tests/fit_recovery.rs): albedo L1 0.0007, light within 0.36 %, 18 s.
//! - Adam phase: small room with 0 / 100 / 300 Adam iterations before the refinement gave albedo L1
//!   0.0035 / 0.0041 / 0.0028 (earlier estimator version): the refinement does the work, Adam is a cheap
//!   warm start. Its learning-rate schedule, measured alone (emission fixed at the truth, Adam on base
//!   colour from grey, B = 64, 128 value paths): constant lr 0.02 ends at albedo L1 0.0034 (300 iterations)
//!   and 0.0042 (600); geometric decay to 0.1× at 0.0016 / 0.0015, to 0.03× at 0.0014 (300) — the decay
//!   halves the noise floor, hence `lr_final_fraction` = 0.1.
//! - What did not work (small room): Adam + periodic emission solves alone (100–300 iterations, lr 0.02,
//!   B = 64, 128 value paths): walls too bright (clamped at 1), light at 0.5× — albedo L1 0.21, light error
//!   55 %: the first-order steps do not cross the scale valley. Gauss–Newton with plain least squares on
//!   Monte Carlo Jacobians (32 paths): converges to the same wrong point, and even started at the truth
//!   walks away (light 20 → 10.8 in 3 steps): errors-in-variables shrinkage (−4.7 % on the light in the pure
//!   emission solve) plus the emission penalty, both pushing along the valley. Fixed by two independent
//!   Jacobian estimates (instrumental variables, [`linear::Problem::second`]), the relaxed lasso and
//!   128-path Jacobians on 1024 pixels (32 paths with IV: unstable, ±20 % steps). Taking the emission
//!   columns of the joint step from the same gradient paths as the base-colour columns, instead of K basis
//!   renders, then cut the demo fit from 66 s to 28 s and the small-room error from L1 0.0041 / 2.6 % to
//!   0.0007 / 0.4 %.
//! - Gradient bias at the truth (tests/fit_gradient.rs, 64 seeds × 256 pixels, fresh 512-path targets):
//!   plain L1 with 4 value paths t ≈ −16 on the summed gradient, with 128 paths t = −3.9; the shipped Huber
//!   weight with 128 paths |t| < 1.3 on every component and the sum.
//! - Specular lobes (glossy fixture, data-fixtures/scenes/glossy.toml: floor specular 0.8 / roughness 0.4, box
//!   1.0 / 0.25; tests/fit_glossy.rs). Before: 4 coupled Gauss–Newton steps on (emission, base colour,
//!   roughness, specular) from r = 0.5 with a ±0.1 trust region, four eye-height cameras: floor r = 0.20,
//!   box r = 0.33, lobes kept with t = 3.5 / 3.3 (barely). Two causes, each measured: (a) the evidence — the
//!   eye-height cameras never saw the mirror reflection of the ceiling light, so roughness and specular
//!   traded off; three cameras looking down from high corners put the highlights in frame; (b) the estimator —
//!   with those cameras, the profile search gives the floor r = 0.390 and the box r = 0.500 / specular 0 when
//!   its lobe was judged on its ~60 held-out pixels alone (t = 1.9 for a 10.6 % gain: highlight pixels make the
//!   paired differences noisy); judging on half the object's training pixels (not used by the search) plus
//!   the held-out ones: floor r = 0.392 / 0.398 / 0.398, box r = 0.250 / 0.257 / 0.254 for fit seeds 0 / 1 / 2
//!   (truth 0.4 / 0.25), lobes kept with t = 9.3 / 4.4 (seed 0), every wall and the ceiling diffuse (their
//!   best lobe made the held-out residual worse, t between −5 and −33). Seed 1 without the post-lobe
//!   Gauss–Newton steps left the light's blue channel 6.3 % low (the floor's reflection attributed to the
//!   other surfaces' albedo); with them (seed 2) the light is within 2.7 % and every albedo within 0.02.
//!   Cost: the search is ≤ 15 profile evaluations per object (grid of 7, 6 golden steps after the two
//!   bracket points, skipped when the profile is flat), each a 64-path value render and 3 gradient passes:
//!   with 512 pixels per object the glossy fit went from 29 s to 65 s; with 256 (shipped) 36 s, seed 0:
//!   floor r = 0.388 / specular 0.750 (t = 7.4), box r = 0.254 / 0.966 (t = 4.2), light within 1.9 %,
//!   albedo within 0.006; seeds 1 / 2: floor r = 0.392 / 0.388, box r = 0.257 / 0.254, light within
//!   0.7 % / 3.6 %, every wall diffuse (40 s each). On the default scene every object's best lobe made the held-out residual worse
//!   (+1.7 % to +10 %): all stay diffuse, albedo L1 0.0023, light 0.32 % (unchanged).
//! - Emission test: the model without an object's emission gets that object's best base colour (1-variable
//!   L1 refit per channel on the test pixels); when a dropped emission had replaced albedo (the refit moves
//!   it by more than 0.02), emission and base colour are re-fitted under the chosen model with the
//!   non-emitters pinned at 0.
//!   Measured on a room lit by a small lamp 1e4× brighter than the walls (tests/stability_extremes.rs):
//!   before, the ceiling kept an emission of 1.6e-4 of the lamp and an albedo 0.09–0.17 too dark; after,
//!   every albedo is within 0.041 and the lamp within 2.4 %.
//! - Extremes (tests/stability_extremes.rs, 24×18 or 32×24 photos at 256 paths): albedo 0.02 / 0.98
//!   recovered as 0.019–0.020 / 0.994–1.0; a room 10 km from the origin (f32 coordinates quantised to 1 mm)
//!   fits as well as at the origin (albedo within 0.004, light 0.6 %); cameras 2 cm off a wall looking
//!   along it, and 1e-6 m² triangles next to 3.75 m² ones: no non-finite value, the tile reported
//!   unconstrained; roughness 0.01 recovered as 0.16 (the photos' 2.5° pixels cannot tell lobes below
//!   r ≈ 0.17 apart), roughness 1 correctly left diffuse.
//!
//! # Non-finite values
//!
//! A path sample whose estimate overflows (f32) is discarded by the tracer — it contributes nothing — and
//! counted; the fit sums the counts of every tracer call ([`samples`]) into
//! [`FitOutcome::discarded_samples`] of [`FitOutcome::traced_paths`], logs them (a warning when any was
//! discarded), and fails with [`FitError::TooManyDiscarded`] when more than
//! [`samples::MAX_DISCARDED_FRACTION`] (1e-4) of the paths were discarded. A gradient or loss can then only
//! be non-finite through a bug, so a non-finite gradient, loss or parameter still aborts the fit
//! (`FitError::NonFinite`). Every extreme case of tests/stability_extremes.rs discards no sample.

pub mod adam;
pub mod emission_solve;
pub mod jacobian;
pub mod layout;
pub mod linear;
pub mod object;
pub mod pixels;
pub mod roughness;
pub mod samples;
pub mod select;
pub mod settings;
pub mod solve;

pub use object::fit_objects;
pub use settings::{AdamLoss, ObjectFitSettings};

use serde::{Deserialize, Serialize};

/// One object of the scene; object i uses material and emitter slot i of the tracer's tables.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectDesc {
    pub id: i64,
    pub label: String,
    /// Indices of its triangles in the scene.
    pub triangles: Vec<u32>,
}

/// Everything the fit reads.
#[derive(Debug, Clone, Copy)]
pub struct FitInputs<'a> {
    pub scene: &'a tracer::Scene,
    pub cameras: &'a [tracer::Camera],
    /// One per camera, same size, linear radiance with validity mask.
    pub images: &'a [ingest::photo::LinearImage],
    pub objects: &'a [ObjectDesc],
    pub settings: &'a ObjectFitSettings,
    pub tracer: &'a tracer::TracerSettings,
}

/// One step of the fit's trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IterationRecord {
    /// Global step number (Adam iterations, then refinement steps), 1-based.
    pub iteration: u32,
    /// `"adam"` or `"refine"`.
    pub phase: String,
    /// Mean per-channel L1 loss |I − I_target| of the step's pixels, before the step.
    pub loss: f64,
    /// Learning rate used (0 for refinement steps).
    pub lr: f64,
    /// Base colour and emission of every object after the step.
    pub base_color: Vec<[f64; 3]>,
    pub emission: Vec<[f64; 3]>,
}

/// The fit's checkpoint: enough to continue exactly where it stopped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitState {
    /// Steps completed (0 = only the initial emission solve done).
    pub iteration: u32,
    /// Flat parameter vector ([`layout`]).
    pub params: Vec<f64>,
    pub adam: adam::AdamState,
    pub history: Vec<IterationRecord>,
    /// Path samples traced so far ([`FitOutcome::traced_paths`]); 0 in checkpoints written before the count
    /// existed, whose resumed fits then count only the steps after the resume.
    #[serde(default)]
    pub traced_paths: u64,
    /// Of these, the ones the tracer discarded as non-finite ([`FitOutcome::discarded_samples`]).
    #[serde(default)]
    pub discarded_samples: u64,
}

/// The model chosen for one object and the evidence for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectModel {
    /// `diffuse`, `specular`, `diffuse+emission` or `specular+emission`.
    pub model: String,
    pub why: String,
    /// False when the photos cannot constrain the object's material (seen in too few pixels).
    pub constrained: bool,
}

/// The result of a fit.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    pub params: tracer::Params,
    pub history: Vec<IterationRecord>,
    pub per_object: Vec<ObjectModel>,
    /// Path samples traced by the whole fit (every value and gradient path of every tracer call, discarded
    /// ones included; a resumed fit includes the checkpointed part).
    pub traced_paths: u64,
    /// Of `traced_paths`, the samples the tracer discarded because their estimate was not finite; at most
    /// [`samples::MAX_DISCARDED_FRACTION`] of them, else the fit fails ([`FitError::TooManyDiscarded`]).
    pub discarded_samples: u64,
}

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error("fit: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error("fit: {cameras} cameras but {images} images")]
    ImageCount { cameras: usize, images: usize },
    #[error("fit: image {view} is {got_w}x{got_h} but its camera is {want_w}x{want_h}")]
    ImageSize { view: usize, got_w: u32, got_h: u32, want_w: u32, want_h: u32 },
    #[error("fit: the scene uses {slots} material slots but {objects} objects were given")]
    ObjectCount { slots: usize, objects: usize },
    #[error("fit: no valid pixel in any image")]
    NoPixels,
    #[error("fit: bad setting {key}: {message}")]
    Setting { key: &'static str, message: String },
    #[error("fit: checkpoint does not match this scene: {0}")]
    BadCheckpoint(String),
    #[error("fit: writing a checkpoint: {0}")]
    Checkpoint(String),
    #[error("fit: non-finite {what} at step {iteration}")]
    NonFinite { what: &'static str, iteration: u32 },
    #[error(
        "fit: the tracer discarded {discarded} of {paths} path samples as non-finite (f32 overflow), more than \
         the accepted fraction of {bound:e}; check for extreme emission values or degenerate geometry",
        bound = samples::MAX_DISCARDED_FRACTION
    )]
    TooManyDiscarded { discarded: u64, paths: u64 },
}
