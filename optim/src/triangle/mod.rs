//! The per-triangle fit with adaptive subdivision (paper Fig. 7): starting from the per-object result, every
//! triangle gets its own base colour (emission stays per object: `emitter_of_tri` = object), and triangles
//! whose photos show more detail than one colour explains are split 4-way, in rounds `fit → split → fit`; after
//! the final round's fit the light is re-solved with the per-triangle materials when the evidence says the
//! object stage's light is wrong (a significance gate on its change).
//!
//! # Method
//! - **Scene**: material slot = triangle, emitter slot = object; rebuilt with the tracer's one builder
//!   ([`tracer::Scene::new`]) after every split.
//! - **Pixels** ([`pixels`]): the valid pixels of every prepared view whose centre ray hits the mesh, at most
//!   `pixels_per_triangle` per triangle (a uniform sample; the budget that bounds a round's cost by the
//!   triangles, not by the photos' pixels), with the triangle and the would-be child (4-way split) its centre
//!   lies in, whether the whole pixel footprint (centre and 4 corners) lies inside that triangle
//!   ("interior"), and whether it lies on that triangle's object ("on object").
//! - **Fit** ([`ratio`]): a closed-form multiplicative update per triangle. A diffuse triangle's radiance is
//!   linear in its own base colour (a planar triangle does not light itself), so with the current value ρ,
//!   the photo sum T and the rendered sum R over its pixels, ρ·T/R is the value that matches them; repeated
//!   (`fit_steps`) it is a Jacobi iteration whose fixed point is T = R for every triangle, which also settles
//!   pixels that straddle two triangles and the interreflections between objects. R's noise in the update is
//!   set by the paths the triangle gets in all, so a triangle's pixels are rendered at `spp` paths each, or at
//!   fewer (at least 1) where they would take more than `paths_per_triangle`, as long as their object keeps
//!   `paths_per_object` in all ([`ratio::paths_per_pixel`]); where a round's pixels at `spp` each would take
//!   more than `paths_per_step` paths in one render, its passes take fewer per pixel ([`ratio::round_spp`]),
//!   so that a pass's cost stops growing with the photos (the renders of fixed-size samples, the fit check's
//!   and the lobe family look's, keep `spp`). The ratios are combined with
//!   the **smoothness regulariser** by solving `min Σ_t n_t (ρ_t − r_t)² + λ Σ_(t,u) (ρ_t − ρ_u)²` (n_t: the
//!   triangle's pixels, pairs: triangles of one object sharing an edge, λ = `smoothness`) with Gauss–Seidel
//!   sweeps: an unobserved triangle takes the mean of its neighbours, and a region nobody sees takes its
//!   object's current value (`ratio::fill_unobserved`: the value the object's seen pixels give at that step,
//!   not the one the stage started from). Emitting objects keep their per-object materials, and so do
//!   the objects the object stage left unconstrained ([`fitted_triangles`]). Where an object's
//!   steps reverse direction (a bright object lit by its own interreflections, whose value the whole step
//!   overshoots), only a fraction of the step is taken, halved at each reversal (`ratio::relax_objects`).
//! - **Light** ([`light::refine_light`]), once the mesh is final (the last round, or a round whose split
//!   test refined nothing): the object stage fitted the light with one colour per object, so on a textured
//!   object (misspecified) its emission absorbs part of the misfit, and the ratio steps, which set each
//!   triangle's value *given* the light, turn a light off by a factor into albedos off by its inverse (the
//!   albedo/emission scale valley that only interreflection pins down). Re-solving the emission alone with
//!   those albedos returns the same light (measured: light 6.5 % → 5–9 % off per channel, PSNR 33.1 dB); so,
//!   as the object stage's joint step does, the light moves together with every non-emitting object's
//!   albedo *scale* (ρ_t → s_o·ρ_t, texture shape fixed; not an object the object stage left
//!   unconstrained, whose value is its estimate weighed against a prior, [`crate::fit::prior`]):
//!   [`light::LIGHT_CYCLES`] (2) cycles of
//!   Gauss–Newton steps on (e, s), averaged after the first [`light::LIGHT_BURN_IN`] (2), then
//!   `light_fit_steps` ratio steps against the averaged light. Each object's averaged scale is shrunk toward
//!   the scale common to all objects as far as its steps' scatter leaves it unknown
//!   ([`light::shrink_scales`], empirical Bayes): an object seen in a few pixels scatters by tens of percent
//!   per step and follows the light's common move instead of its noise. A cycle takes [`light::LIGHT_MIN_STEPS`] (6)
//!   steps and goes on, up to `light_steps` (18), while some emitter's averaged emission has a relative
//!   standard error above `light_precision` (1 %, [`light::light_relative_se`]): a seen lamp scatters by
//!   under 1 % per step and stops at the minimum, a lamp no photo sees by a quarter of its value and takes
//!   the budget. The second cycle's light is pooled with the first's where they agree within their joint
//!   scatter ([`light::pool_cycles`]: inverse-variance weights, a channel that moved by more than
//!   [`light::POOL_Z`] joint standard errors takes the new cycle's mean), so an unseen lamp known to 6–12 %
//!   by each cycle is not re-drawn by the second but known better by both. Each step is the object stage's
//!   solver on columns from the per-triangle scene
//!   ([`crate::fit::emission_solve::solve_on_columns`]): ∂I/∂e_k and ∂I/∂s_o = Σ_(t ∈ o) ρ_t ∂I/∂ρ_t from the
//!   same gradient paths, two independent estimates (instrumental variables), `object.solve_pixels` pixels
//!   drawn from the round's pixels at `object.solve_spp` paths; objects whose per-object model has no emission
//!   stay at 0 (no new emitter appears), with no lasso (the support is the object stage's decision). Data term
//!   L2, not L1: the ratio steps match sums (means) and an L1 fit matches medians, which differ for skewed
//!   Monte Carlo estimates — alternating the two walked the red light down by ~1 % per cycle; Marquardt
//!   damping 1e-3 (0.1, the object stage's value, is relative to the IRLS-L1 weights; with L2 it held the
//!   scales within 0.3 % of 1 per step and the light stayed 5 % off).
//! - **Light-change gate** ([`light::light_change_p`], [`light::LIGHT_SIGNIFICANCE`] = 1 %): only what the
//!   evidence calls for. After the first cycle's steps, the mean of its averaged steps is tested against the
//!   object stage's light: per emitter and channel a Wald t = (x̄ − x₀)/(s/√n) with the steps' own scatter s
//!   as the Monte Carlo standard error (the steps are uncorrelated once converged: lag-1 autocorrelation
//!   between −0.22 and −0.04 on the default scene, a corpus room and the house; relative variance pooled over
//!   the emitter's 3 channels: 3(n − 1) degrees of freedom), t² ~ F(1, 3(n − 1))
//!   ([`significance::f_survival`]), Bonferroni over the 3K tests. Not
//!   significant: the cycle is undone — the light *and* the albedo scales that moved with it go back to the
//!   round's fit — and the second cycle and both ratio passes are skipped (a uniform scene's per-triangle
//!   model is its per-object model, whose light the object stage already fitted jointly with its albedos).
//!   Calibration (unit test, 4000 seeded trials of 4 and of 16 Gaussian steps with 1.5 % scatter): 44 and 39
//!   rejections under the null (1.1 % and 1.0 %), 4000 of 4000 for a light 6 % off.
//! - **Fit check** (after the light's cycles): the re-solved state and the round's fit are rendered on up to
//!   64 k of the round's pixels with the same random numbers; when the re-solved one fits the photos
//!   significantly worse (paired t of the per-pixel L1 differences > 2), or its mean L1 is more than
//!   [`light::MAX_LOSS_GROWTH`] times the fit's (a change confined to a few pixels is never significant,
//!   however large), the light and the albedos go back to the round's fit. The gate above tests whether the
//!   light moved, not whether it moved the right way.
//! - **Lobe family look** ([`family`], after the light, `family_pixels` > 0): the object stage chose each
//!   object's lobe family with one colour per object for its neighbours, whose misfit a wrong family can
//!   absorb; with the neighbours now resolved by place every non-emitting object is tried in the other family
//!   (a dielectric as a metal, a metal as a Lambert surface): both families fitted with one colour for the
//!   object by ratio steps on up to 512 of its pixels, and the object switched where the rest, up to
//!   `family_pixels`, prefer the other family (the object stage's paired metal test, in sequential looks); a
//!   pass of `light_fit_steps` ratio steps follows the switches. The round's log records every object's look.
//! - **Shrinkage to the object** ([`ratio::shrink_to_object`]), before the smoothness solve at every step: no
//!   per-triangle parameter the evidence does not call for. Per object, its value m is the object-level ratio
//!   update ΣT/Σ(R/ρ) over its pixels that see it alone (footprint on its triangles only, whichever of them;
//!   at least 32), accepted only when it differs from the object's current value significantly (χ²(3) at
//!   99.9 %, variance from those pixels' photo − render scatter), else the current value stays: an object
//!   tessellated finer than the pixels, of whose triangles hardly one has clean evidence, still follows its
//!   photos. Each triangle's ratio r_t (sampling variance v_t
//!   = ρ²·n·s²/R² from that scatter, i.e. from the value paths and the photo noise) becomes
//!   m + τ²/(τ² + v_t)·(r_t − m), with τ² the object's spread beyond noise by the method of moments with weights
//!   1/v_t, τ² = max(0, (Σ (r_t − m)²/v_t − k)/Σ 1/v_t) over its k triangles with clean evidence (empirical
//!   Bayes / James–Stein; unweighted, a few slivers of huge v_t hid a striped cabinet's spread and flattened
//!   it): a uniform object (τ² ≈ 0) keeps its value on every triangle, a textured one keeps its triangles'
//!   own values. Triangles seen in fewer than 4 interior pixels take m. Optionally
//!   (`adam_iterations`, [`adam`]) Adam follows with batches of pixels and the object stage's loss weights,
//!   `n_value`/`n_grad` paths, clamping, on base colour (and roughness/metallic of objects whose model has a
//!   specular lobe).
//! - **Split test** ([`split`], [`significance`]): after a fit the pixel residuals (photo − render, with the
//!   render rescaled by the last update) of a triangle's interior pixels are grouped by would-be child; the
//!   one-way ANOVA F statistic per channel (variance between the children's means over the pooled variance
//!   within them) with its degrees of freedom (k − 1, n − k: k children with pixels, n interior pixels) gives a
//!   p-value, the chance of so much structure from noise alone; the triangle's p is 3 × the smallest over the
//!   channels (Bonferroni). Holm's step-down correction over every triangle tested in the round then keeps the
//!   probability that a round splits any triangle whose children differ only by noise at most
//!   `split_significance` (0.01), whatever the number of triangles and their pixel counts. A significant
//!   triangle is split when its contrast (largest child mean residual against the triangle's, over its mean
//!   radiance) exceeds `split_contrast` and it covers ≥ 4·`min_pixels` pixel centres in its best view (the
//!   footprint limit), smallest p first, within `max_triangles` (a bound on the mesh's size, not its growth;
//!   the significant triangles it leaves unsplit are counted, [`RoundRecord::over_budget`]). Geometry:
//!   [`crate::subdivide`] (red 4-way split, green/blue closure, parameters inherited from the parent).
//! - **Resume**: a checkpoint after every round that ends with a split (mesh, per-triangle materials and the
//!   per-object emission, [`TriangleState`]); all random numbers are keyed by (seed, round, pass, step), so a
//!   resumed run ends where an uninterrupted one ends (tests/triangle_resume.rs, emission included). The light
//!   refinement belongs to the final round, which writes the result rather than a checkpoint;
//!   [`RoundRecord::emission`] logs the emission after every round.
//!
//! - **Detail** ([`detail`]), after the rounds and outside them (the export stage calls it): texels finer
//!   than any triangle, the photos divided by the final model's shading.
//!
//! # Measurements
//!
//! The measurements that chose the shrinkage, the split test, the light refinement and its gate, and the
//! smoothness and Adam defaults are in `docs/optim/design-measurements.md`.

pub mod adam;
pub mod detail;
pub mod family;
pub mod light;
pub mod pixels;
pub mod ratio;
pub mod significance;
pub mod split;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::fit::ObjectFitSettings;

/// Format tag of the stage's result (`triangle/result.json` beside `triangle/mesh.ply`; the layout is the
/// workflow's `artefacts::triangle`).
pub const RESULT_FORMAT: &str = "ipt-triangle/2";

/// A mesh with per-triangle materials and per-object emission: the state of the per-triangle fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriangleState {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub triangles: Vec<[u32; 3]>,
    /// Object index per triangle (index into the ingested object list).
    pub face_object: Vec<u32>,
    /// Per triangle.
    pub materials: Vec<tracer::Material>,
    /// Per object, then the ground half of every emitter split at the horizon (`horizon`).
    pub emission: Vec<Vec3>,
    /// Emitters split at the horizon (`tracer::params::Horizon`; none in results written before splits).
    #[serde(default)]
    pub horizon: tracer::params::Horizon,
    /// Rounds finished (a round = one fit, followed by one split unless it is the last).
    pub rounds_done: u32,
    pub log: Vec<RoundRecord>,
}

/// What one round did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoundRecord {
    pub round: u32,
    /// Triangles during the round's fit.
    pub triangles: usize,
    /// Mean per-channel |photo − render| over the fitted pixels after each fit step.
    pub loss: Vec<f64>,
    /// Triangles marked for splitting, split (red), refused by the limits, cut by closure.
    pub marked: usize,
    pub refined: usize,
    pub refused: usize,
    pub closure_cut: usize,
    /// Triangles the split test found significant but left unsplit: the mesh would have outgrown
    /// `triangle.max_triangles` ([`split::Marks::over_budget`]); 0 in results written before it was counted.
    #[serde(default)]
    pub over_budget: usize,
    pub seconds: f64,
    /// Per object: the emission after the round's fit (re-solved with the per-triangle materials); empty in
    /// results written before the emission was re-solved.
    #[serde(default)]
    pub emission: Vec<Vec3>,
    /// The lobe family look of the final round ([`family`]), one entry per object looked at; empty in other
    /// rounds, with the look off, and in results written before it.
    #[serde(default)]
    pub families: Vec<FamilyRecord>,
    /// Mean per-channel |photo − render| over the switched objects' pixels at each ratio step after the lobe
    /// family look (before its update); empty where nothing switched, and in results written before it.
    #[serde(default)]
    pub family_loss: Vec<f64>,
}

/// One object's lobe family look ([`family::Look`]), as the result records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FamilyRecord {
    /// Index into the ingested object list.
    pub object: usize,
    /// The alternative tested: a metal at this roughness, or (absent) a Lambert surface.
    pub metal_roughness: Option<f32>,
    pub fit_pixels: usize,
    pub test_pixels: usize,
    /// Gain of the alternative on the L1 and on the RMS error, fractions of the test pixels' mean radiance,
    /// with their paired t-statistics.
    pub l1_gain: (f64, f64),
    pub rms_gain: Option<(f64, f64)>,
    pub switched: bool,
}

impl From<&family::Look> for FamilyRecord {
    fn from(l: &family::Look) -> Self {
        Self {
            object: l.object,
            metal_roughness: l.metal_roughness,
            fit_pixels: l.fit_pixels,
            test_pixels: l.test_pixels,
            l1_gain: l.l1,
            rms_gain: l.rms,
            switched: l.kept,
        }
    }
}

/// Why the per-triangle stage failed.
#[derive(Debug, thiserror::Error)]
pub enum TriangleError {
    #[error("triangle fit: {0}")]
    Tracer(#[from] tracer::TracerError),
    #[error("triangle fit: {0}")]
    Subdivide(#[from] crate::subdivide::SubdivideError),
    #[error("triangle fit: bad setting triangle.{key}: {message}")]
    Setting { key: &'static str, message: String },
    #[error("triangle fit: {0}")]
    Input(String),
    #[error("triangle fit: writing a checkpoint: {0}")]
    Checkpoint(String),
    #[error("triangle fit: interrupted after round {rounds_done}; its checkpoint is written")]
    Interrupted { rounds_done: u32 },
    /// Stopped on request within a round: the round's work is dropped, and a rerun resumes from the checkpoint
    /// of the last finished round.
    #[error("triangle fit: stopped within a round; a rerun resumes from the last finished round's checkpoint")]
    Stopped(#[from] crate::progress::Stopped),
    /// More than the object fit's bound ([`crate::fit::samples::MAX_DISCARDED_FRACTION`]) of a round's path
    /// samples were discarded as non-finite.
    #[error(
        "triangle fit: round {round}: the tracer discarded {discarded} of {paths} path samples as non-finite \
         (f32 overflow), more than the accepted fraction of {bound:e}",
        bound = crate::fit::samples::MAX_DISCARDED_FRACTION
    )]
    TooManyDiscarded { round: u32, discarded: u64, paths: u64 },
}

impl From<crate::blocks::BlockError> for TriangleError {
    fn from(e: crate::blocks::BlockError) -> Self {
        match e {
            crate::blocks::BlockError::Tracer(e) => e.into(),
            crate::blocks::BlockError::Stopped(s) => s.into(),
        }
    }
}

/// Settings of the per-triangle fit (the pipeline's `[triangle]` table, where each default is documented).
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleSettings {
    /// Subdivision rounds (fit → split → fit …); 0 = per-triangle fit on the given mesh only.
    pub rounds: u32,
    /// Closed-form (ratio) base-colour updates per fit.
    pub fit_steps: u32,
    /// Paths per pixel of the renders of every fit step and of the split test.
    pub spp: u32,
    /// Budget: pixels per triangle (a uniform sample of its pixels when it has more), so a round's renders
    /// cost at most this × triangles pixels whatever the photos' number and resolution.
    pub pixels_per_triangle: u32,
    /// Budget: paths per triangle of a ratio step's render (its pixels at fewer than `spp` paths each where
    /// they would take more, at least 1 each; [`ratio::paths_per_pixel`]); 0 = every pixel at `spp`.
    pub paths_per_triangle: u32,
    /// … but an object's pixels take at least this many paths in all (up to `spp` each).
    pub paths_per_object: u32,
    /// Budget: paths of each render of a round's passes over all its pixels: where the round's pixels at
    /// `spp` each would take more, its passes take fewer per pixel ([`ratio::round_spp`]); 0 = no bound.
    pub paths_per_step: u64,
    /// Adam iterations per fit after the closed-form steps (batches of `object.batch_pixels` pixels,
    /// `object.n_value`/`object.n_grad` paths, the object stage's loss); 0 = closed form only.
    pub adam_iterations: u32,
    /// Adam learning rate of those iterations.
    pub adam_lr: f64,
    /// Weight of the smoothness regulariser between neighbouring triangles of one object, in pixels of
    /// evidence per shared edge (0 = none).
    pub smoothness: f64,
    /// Family-wise level of the split test: the probability that a round splits any triangle whose pixels
    /// differ only by noise is at most this ([`split`]).
    pub split_significance: f64,
    /// A significant triangle is split only when some would-be child's albedo would change by more than this
    /// fraction (largest mean residual of a child over the triangle's mean radiance).
    pub split_contrast: f64,
    /// Smallest pixel footprint of a triangle a split may create: pixel centres in its parent's best view / 4.
    pub min_pixels: u32,
    /// Budget: the mesh never grows beyond this many triangles.
    pub max_triangles: u32,
    /// Budget: most joint light steps per cycle of the final round's light re-solve ([`light::refine_light`];
    /// at least [`light::LIGHT_MIN_STEPS`] are taken); 0 = no light re-solve.
    pub light_steps: u32,
    /// A light cycle stops before `light_steps` once every emitter's averaged emission has at most this
    /// relative standard error ([`light::light_relative_se`]).
    pub light_precision: f64,
    /// Ratio steps of the pass after each light cycle ([`light::refine_light`]), and of the switched objects
    /// after the lobe family look when it switched some ([`family`]).
    pub light_fit_steps: u32,
    /// Budget: pixels per object of the lobe family look after the final round's light re-solve ([`family`]),
    /// half of them, at most [`family::FIT_PIXELS`], to fit both families and the rest to test; 0 = no look.
    pub family_pixels: u32,
    /// Seed of the stage's renders.
    pub seed: u64,
}

/// Everything the rounds read besides the state.
#[derive(Debug, Clone, Copy)]
pub struct RoundInputs<'a> {
    pub cameras: &'a [tracer::Camera],
    pub images: &'a [ingest::photo::LinearImage],
    pub settings: &'a TriangleSettings,
    /// The object stage's settings (Adam batch, paths, loss) for the optional Adam iterations.
    pub object: &'a ObjectFitSettings,
    pub tracer: &'a tracer::TracerSettings,
    /// Per object: its model has a specular lobe (roughness/metallic are then fitted per triangle by Adam).
    pub specular: &'a [bool],
    /// Per object: the object stage found its material constrained by the photos (`materials.json`'s
    /// `constrained`; an object missing from the slice counts as constrained). An unconstrained object keeps
    /// the object stage's material ([`fitted_triangles`]).
    pub constrained: &'a [bool],
}

/// Per triangle, whether the stage fits its material: its object does not emit now (`emission`, per object)
/// and is `constrained` (an object missing from that slice counts as constrained). Emitting objects keep their
/// per-object materials (emission and materials are entangled there; their emission is re-solved by
/// [`light::refine_light`]). An object the object stage left unconstrained keeps its value, its estimate weighed
/// against a prior ([`crate::fit::prior`]): the few pixels that made it unconstrained are no better evidence
/// here. The ratio steps ([`ratio::fit_round`]) fit these triangles, and the light re-solve scales their objects.
#[must_use]
pub fn fitted_triangles(face_object: &[u32], emission: &[Vec3], constrained: &[bool]) -> Vec<bool> {
    face_object
        .iter()
        .map(|&o| {
            let o = o as usize;
            let emits = emission[o].max_element() > 0.0;
            !emits && constrained.get(o).copied().unwrap_or(true)
        })
        .collect()
}

impl TriangleState {
    /// The per-object result spread over the triangles (round 0, before any per-triangle fit).
    pub fn from_objects(
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        triangles: Vec<[u32; 3]>,
        face_object: Vec<u32>,
        params: &tracer::Params,
    ) -> Result<Self, TriangleError> {
        if face_object.len() != triangles.len() {
            return Err(TriangleError::Input(format!(
                "{} object indices for {} triangles",
                face_object.len(),
                triangles.len()
            )));
        }
        let k = params.materials.len().min(params.emission.len());
        if let Some(t) = face_object.iter().position(|&o| o as usize >= k) {
            return Err(TriangleError::Input(format!("triangle {t}: object {} of {k}", face_object[t])));
        }
        Ok(Self {
            materials: face_object.iter().map(|&o| params.materials[o as usize]).collect(),
            emission: params.emission.clone(),
            horizon: params.horizon.clone(),
            positions,
            normals,
            triangles,
            face_object,
            rounds_done: 0,
            log: Vec::new(),
        })
    }

    /// The tracer scene of the current mesh: material slot = triangle, emitter slot = object.
    pub fn scene(&self) -> Result<tracer::Scene, TriangleError> {
        Ok(tracer::Scene::new(tracer::SceneInput {
            positions: self.positions.clone(),
            triangles: self.triangles.clone(),
            normals: self.normals.clone(),
            material_of_tri: (0..self.triangles.len() as u32).collect(),
            emitter_of_tri: self.face_object.clone(),
        })?)
    }

    /// The tracer's parameter tables for [`TriangleState::scene`].
    #[must_use]
    pub fn params(&self) -> tracer::Params {
        tracer::Params {
            materials: self.materials.clone(),
            emission: self.emission.clone(),
            horizon: self.horizon.clone(),
        }
    }

    /// Per object (`objects` entries): the uniform radiance of the same flux as its emission, the same as
    /// its emission unless it is split at the horizon (`tracer::Params::uniform_emission`).
    #[must_use]
    pub fn uniform_emission(&self, objects: usize) -> Vec<Vec3> {
        self.params().uniform_emission(&tracer::scene::horizon_geometry(self.horizon.up, objects, self.faces()))
    }

    /// Per triangle: its object, its area and its front face's unit normal as the tracer's scene builds it.
    fn faces(&self) -> impl Iterator<Item = (u32, f64, Vec3)> + '_ {
        self.triangles.iter().zip(&self.face_object).map(|(t, &o)| {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let cr = (b - a).cross(c - a);
            (o, 0.5 * f64::from(cr.length()), cr.normalize_or_zero())
        })
    }

    /// Per object (`objects` entries): the area-weighted mean of its triangles' materials — base colour,
    /// roughness, metallic and specular each averaged over the object's surface — or `None` for an object
    /// with no triangle of positive area. This is the per-object summary of the per-triangle result: every
    /// triangle's value rests on the photos that see it (or, unseen, takes its object's value), so the mean
    /// uses all the photos' pixels, where the object stage's estimate rests on its solves' samples.
    #[must_use]
    pub fn object_means(&self, objects: usize) -> Vec<Option<tracer::Material>> {
        // Sums in f64: a house-sized object has 10⁴–10⁵ triangles of very unequal area.
        let mut sums = vec![([0.0f64; 3], 0.0f64, 0.0f64, 0.0f64, 0.0f64); objects];
        for ((o, area, _), m) in self.faces().zip(&self.materials) {
            let Some(s) = sums.get_mut(o as usize) else { continue };
            for (acc, v) in s.0.iter_mut().zip(m.base_color.to_array()) {
                *acc += area * f64::from(v);
            }
            s.1 += area * f64::from(m.roughness);
            s.2 += area * f64::from(m.metallic);
            s.3 += area * f64::from(m.specular);
            s.4 += area;
        }
        sums.into_iter()
            .map(|(rgb, r, mt, sp, area)| {
                // A degenerate object (every triangle of zero area) has no surface to average over.
                (area > 0.0).then(|| tracer::Material {
                    base_color: Vec3::new((rgb[0] / area) as f32, (rgb[1] / area) as f32, (rgb[2] / area) as f32),
                    roughness: (r / area) as f32,
                    metallic: (mt / area) as f32,
                    specular: (sp / area) as f32,
                })
            })
            .collect()
    }

    /// Triangles of each object (`objects` entries).
    #[must_use]
    pub fn triangles_per_object(&self, objects: usize) -> Vec<usize> {
        let mut n = vec![0; objects];
        for &o in &self.face_object {
            if let Some(c) = n.get_mut(o as usize) {
                *c += 1;
            }
        }
        n
    }
}

fn check(config: &TriangleSettings) -> Result<(), TriangleError> {
    let bad = |key: &'static str, message: &str| Err(TriangleError::Setting { key, message: message.into() });
    if config.spp == 0 {
        return bad("spp", "must be ≥ 1");
    }
    if config.pixels_per_triangle < 4 {
        // The split test compares a triangle's four would-be children: fewer pixels cannot show one.
        return bad("pixels_per_triangle", "must be ≥ 4");
    }
    if !(config.smoothness.is_finite() && config.smoothness >= 0.0) {
        return bad("smoothness", "must be finite and ≥ 0");
    }
    if !(config.split_significance > 0.0 && config.split_significance < 1.0) {
        return bad("split_significance", "must lie in (0, 1)");
    }
    if !(config.adam_lr.is_finite() && config.adam_lr > 0.0) {
        return bad("adam_lr", "must be finite and > 0");
    }
    Ok(())
}

/// The round's pixels within the per-triangle budget, with a note of how many the budget left out.
fn collect_pixels(
    inputs: &RoundInputs<'_>,
    scene: &tracer::Scene,
    state: &TriangleState,
    round: u32,
    progress: &dyn crate::Progress,
) -> pixels::TriPixels {
    let cfg = inputs.settings;
    progress.set_message(&format!("round {round}: collecting the pixels of {} triangles", state.triangles.len()));
    let pix = pixels::collect(
        scene,
        inputs.cameras,
        inputs.images,
        state.triangles.len(),
        cfg.pixels_per_triangle as usize,
        cfg.seed,
    );
    tracing::info!(round, kept = pix.samples.len(), seen = pix.seen, "triangle pixels");
    progress.note(&format!(
        "[triangle] round {round}: {} of {} pixels (at most {} per triangle)",
        pix.samples.len(),
        pix.seen,
        cfg.pixels_per_triangle
    ));
    pix
}

/// Says in the log when a round's passes over its `pixels` pixels take fewer than `spp` paths each
/// ([`ratio::round_spp`], which [`ratio::fit_pass`] applies).
fn note_paths_per_step(cfg: &TriangleSettings, pixels: usize, round: u32, progress: &dyn crate::Progress) {
    let spp = ratio::round_spp(cfg.spp, cfg.paths_per_step, pixels);
    if spp < cfg.spp {
        tracing::info!(round, pixels, spp, "paths per pixel lowered by the paths per step");
        progress.note(&format!(
            "[triangle] round {round}: {pixels} pixels at {spp} paths each instead of {} (triangle.paths_per_step \
             = {})",
            cfg.spp, cfg.paths_per_step
        ));
    }
}

/// Runs the remaining rounds of `state` (fit → split → … → fit). `on_round` receives the state after every
/// round that ends with a split (a checkpoint); the returned state holds the final fit.
pub fn run_rounds(
    inputs: &RoundInputs<'_>,
    mut state: TriangleState,
    on_round: &mut dyn FnMut(&TriangleState) -> Result<(), TriangleError>,
    progress: &dyn crate::Progress,
) -> Result<TriangleState, TriangleError> {
    check(inputs.settings)?;
    if inputs.images.len() != inputs.cameras.len() {
        return Err(TriangleError::Input(format!(
            "{} images for {} cameras",
            inputs.images.len(),
            inputs.cameras.len()
        )));
    }
    let cfg = inputs.settings;
    if cfg.rounds > 0 && split::within_budget(cfg.max_triangles as usize, state.triangles.len(), 1) == 0 {
        // The budget bounds the mesh's size, not its growth: a scan already at it keeps its own triangles.
        progress.note(&format!(
            "[triangle] the mesh has {} triangles and triangle.max_triangles is {}: no room for a split, so \
             no triangle will be split",
            state.triangles.len(),
            cfg.max_triangles
        ));
    }
    while state.rounds_done <= cfg.rounds {
        // The rounds' phase, again at every round: a round's ratio and light steps report as phases of their
        // own (each with its ETA), which replace it while they run.
        progress.phase("round", u64::from(cfg.rounds) + 1, u64::from(state.rounds_done));
        let round = state.rounds_done;
        let started = std::time::Instant::now();
        let scene = state.scene()?;
        let pix = collect_pixels(inputs, &scene, &state, round, progress);
        note_paths_per_step(cfg, pix.samples.len(), round, progress);
        let fitted = ratio::fit_round(inputs, &scene, &pix.samples, &mut state, round, progress)?;
        let mut rec = RoundRecord {
            round,
            triangles: state.triangles.len(),
            loss: fitted.loss.clone(),
            marked: 0,
            refined: 0,
            refused: 0,
            closure_cut: 0,
            over_budget: 0,
            seconds: 0.0,
            emission: state.emission.clone(),
            families: Vec::new(),
            family_loss: Vec::new(),
        };
        progress.phase("round", u64::from(cfg.rounds) + 1, u64::from(state.rounds_done));
        progress.set_message(&format!("{} triangles, loss {:.4}", rec.triangles, fitted.loss.last().unwrap_or(&0.0)));
        let last = round == cfg.rounds;
        let mut stop = last;
        let mut applied = false;
        if !last {
            let split::Marks { marks, over_budget } =
                split::choose(inputs, &state, &pix.samples, &pix.best_view, &fitted);
            rec.marked = marks.len();
            rec.over_budget = over_budget;
            if marks.is_empty() {
                stop = true;
            } else {
                let sub = split::apply(&mut state, &marks)?;
                applied = true;
                rec.refined = sub.refined.len();
                rec.refused = sub.refused.len();
                rec.closure_cut = sub.closure_cut.len();
                if sub.refined.is_empty() {
                    stop = true;
                }
            }
        }
        if stop {
            // The final mesh: its textures are now resolved, so the light is re-solved with them (the object
            // stage's light was fitted with one colour per object) and the ratio steps follow it.
            // (A split that refined nothing leaves the mesh as it was; rebuilt anyway, to be safe.)
            let (scene, pix) = if applied {
                let scene = state.scene()?;
                let pix = collect_pixels(inputs, &scene, &state, round, progress);
                note_paths_per_step(cfg, pix.samples.len(), round, progress);
                (scene, pix)
            } else {
                (scene, pix)
            };
            if let Some(again) = light::refine_light(inputs, &scene, &pix.samples, &mut state, round, progress)? {
                rec.loss.extend(again.loss);
            }
            rec.emission.clone_from(&state.emission);
            if cfg.family_pixels > 0 {
                // The lobe families, looked at again with the neighbours resolved by place.
                let (looks, loss) = family::family_look(inputs, &scene, &pix.samples, &mut state, round, progress)?;
                let switched: Vec<String> = looks
                    .iter()
                    .filter(|l| l.kept)
                    .map(|l| match l.metal_roughness {
                        Some(r) => format!("object {} → metal (roughness {r:.2})", l.object),
                        None => format!("object {} → dielectric", l.object),
                    })
                    .collect();
                progress.note(&format!(
                    "[triangle] round {round}: lobe family look at {} objects: {} switched{}",
                    looks.len(),
                    switched.len(),
                    if switched.is_empty() { String::new() } else { format!(" ({})", switched.join(", ")) }
                ));
                tracing::info!(round, looked = looks.len(), switched = switched.len(), "lobe family look");
                rec.families = looks.iter().map(FamilyRecord::from).collect();
                rec.family_loss = loss;
            }
        }
        rec.seconds = started.elapsed().as_secs_f64();
        tracing::info!(round, triangles = rec.triangles, marked = rec.marked, refined = rec.refined, "triangle round");
        let over_budget = if rec.over_budget > 0 {
            format!(
                ", {} more significant but over the budget of {} triangles (triangle.max_triangles)",
                rec.over_budget, cfg.max_triangles
            )
        } else {
            String::new()
        };
        progress.note(&format!(
            "[triangle] round {round}: {} triangles, loss {:.5}, {} marked, {} split, {} refused, {} closure \
             cuts{over_budget} ({:.1} s); emission of the emitters {:?}",
            rec.triangles,
            rec.loss.last().unwrap_or(&0.0),
            rec.marked,
            rec.refined,
            rec.refused,
            rec.closure_cut,
            rec.seconds,
            rec.emission.iter().filter(|e| e.max_element() > 0.0).map(|e| e.to_array()).collect::<Vec<_>>()
        ));
        state.log.push(rec);
        if stop {
            // Nothing changed the mesh after this fit: it is the final result.
            state.rounds_done = cfg.rounds + 1;
            progress.phase("round", u64::from(cfg.rounds) + 1, u64::from(state.rounds_done));
            return Ok(state);
        }
        state.rounds_done += 1;
        on_round(&state)?;
        if progress.stop_requested() {
            return Err(TriangleError::Interrupted { rounds_done: state.rounds_done });
        }
    }
    Ok(state)
}
