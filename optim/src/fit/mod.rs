//! Per-object material and emission fit (paper §3–4): every object has one base colour, roughness, metallic,
//! specular and RGB emission; the photos are matched by path-traced estimates.
//!
//! # Method (see `object.rs` for the loop)
//! 1. **Emission solve** (closed form, [`emission_solve`]): with materials fixed, radiance is linear in
//!    emission; J from basis renders, e ≥ 0 by IRLS with a relative penalty. Every solve draws its pixels per
//!    object (32 each, the rest in proportion to the objects' pixels, weighted back to the full data:
//!    [`pixels::draw_stratified`]), and its data term is Huber's loss with one corner per object, the
//!    interquartile range of that object's residuals ([`linear::DataLoss::GroupHuber`]): L1-like beyond it,
//!    so outliers weigh little, and the mean of the object's pixels within it — where L1's minimum on an
//!    object whose pixels have two colours (a textured floor fitted with one albedo) is flat between them, and
//!    the hidden light's colour, fixed only by interreflection, followed the solves' pixel draw (measured:
//!    docs/optim/design-measurements.md, "Solve pixels per object and the checker light").
//! 2. **Adam** (paper §4.5) on every base colour: batches of `batch_pixels` pixels uniform over all valid training
//!    pixels, L1 loss with `n_value` value paths and `n_grad` independent gradient paths per pixel
//!    (weights sign(I − I_target)/B), geometric learning-rate decay, clamping to [0, 1]; emission re-solved
//!    every `emission_solve_every` iterations (variable projection: the emission always optimal for the
//!    current materials).
//! 3. **Gauss–Newton refinement** of base colour and emission jointly (`refine_steps` steps, same pixel draw and
//!    data term as 1; the parameters returned are averaged over the second half of the steps).
//! 4. **Model selection** ([`select`]): each object starts diffuse with no emission; a specular lobe is tried
//!    per object — roughness by a 1-D search on the profile loss with base colour and specular solved for each
//!    roughness ([`roughness`]), on half of the object's training pixels, common random numbers; when the
//!    dielectric's specular strength is at its bound, also the metal family and metallic between the two
//!    ([`roughness::search_lobe`]) — and kept only
//!    when it lowers the residual on the other half plus the held-out pixels significantly (paired t > 3 and a
//!    gain > 0.5 % of the mean radiance; a lobe that lowers the searched half's residual below the best Lambert
//!    surface's by less than that at every roughness searched is not tested); with lobes kept, the emission of
//!    the emitters the refinement left is re-solved, unpenalised (or, with `specular_trial_steps` > 0,
//!    Gauss–Newton steps re-fit emission and base colour). An emission term is kept
//!    only when it lowers the held-out residual significantly, against the model without it and, for an
//!    object the photos see, against its best dielectric or metal lobe without emission (an object that
//!    mirrors a lamp is a metal, not a light). Objects seen in fewer than 16 training pixels are
//!    reported unconstrained (no lobe trial). A kept emitter that faces sideways, a window pane, is split at
//!    the horizon when the held-out pixels its light reaches pay for a second radiance ([`horizon`]).
//! 5. **Objects no photo sees** ([`prior`]): steps 2–3 estimate their base colours too, through the light
//!    they reflect onto the objects the photos see; each is then weighed against a stated prior (the
//!    area-weighted distribution of the observed objects of its category, or of all) by its standard error.
//!
//! A comparison fit ([`FitMode::Comparison`]) runs steps 1–3 only, with emission on a given set of objects.
//!
//! The decision, its reason and `constrained` are in [`ObjectModel`] and go to `materials.json` (`model`,
//! `why`, `constrained`).
//!
//! All randomness is keyed by (seed, iteration), so a run resumed from a [`FitState`] checkpoint gives the
//! same result as an uninterrupted run (tests/fit_resume.rs).
//!
//! # Measurements
//!
//! The measurements that chose the method and its defaults (accuracy and time on the bundled scenes, what
//! did not work) are in `docs/optim/design-measurements.md`.
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
pub(crate) mod family;
pub mod horizon;
pub mod jacobian;
pub mod layout;
pub mod linear;
pub mod object;
pub(crate) mod paired;
pub mod pixels;
pub mod prior;
pub mod roughness;
pub mod samples;
pub mod select;
pub mod settings;
pub mod solve;
pub mod step_check;

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
    /// The whole fit, or a comparison fit (see [`FitMode`]).
    pub mode: FitMode<'a>,
}

/// What a fit estimates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FitMode<'a> {
    /// Steps 1–5 above: every object the photos see may emit, and model selection decides.
    #[default]
    Full,
    /// Steps 1–3 only, with emission allowed only on the objects with `emitters[k]` (others held at 0): a fit
    /// that compares how well different inputs (photos raised to different exponents) are explained by one
    /// fixed set of lights, with no faint emissions free to absorb what the inputs get wrong and no model
    /// decision that can flip between two inputs. Its result is the averaged refinement, every object diffuse.
    Comparison { emitters: &'a [bool] },
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
    /// Fraction of a refinement step taken after its check ([`step_check`]): 1, a halving, or 0 when the
    /// step was refused; 1 for Adam iterations (and in histories written before the check existed).
    #[serde(default = "one")]
    pub step_fraction: f64,
}

fn one() -> f64 {
    1.0
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
    /// False when the photos do not see the object in enough pixels to constrain its material directly (its
    /// base colour then comes from interreflection and a prior, `why` says how).
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
    /// Training and held-out pixels (after the held-out budget): what the decisions were made on.
    pub train_pixels: usize,
    pub holdout_pixels: usize,
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
    #[error("fit: interrupted after step {iteration}; its checkpoint is written")]
    Interrupted { iteration: u32 },
    /// Stopped on request within model selection, which keeps no checkpoint of its own: a rerun resumes from
    /// the checkpoint of the fit's last step.
    #[error("fit: stopped during model selection; a rerun resumes from the checkpoint of the last fit step")]
    Stopped(#[from] crate::progress::Stopped),
    #[error("fit: non-finite {what} at step {iteration}")]
    NonFinite { what: &'static str, iteration: u32 },
    #[error(
        "fit: the tracer discarded {discarded} of {paths} path samples as non-finite (f32 overflow), more than \
         the accepted fraction of {bound:e}; check for extreme emission values or degenerate geometry",
        bound = samples::MAX_DISCARDED_FRACTION
    )]
    TooManyDiscarded { discarded: u64, paths: u64 },
}
