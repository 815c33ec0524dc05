//! Unidirectional path tracing with next-event estimation and MIS (power heuristic), and the exact path
//! derivative of the same estimator (paper §3.3, Eq. 5–6) in adjoint form.
//!
//! Notation: vertex k is the k-th surface hit (k = 0 is seen by the camera), `β_k` the throughput of the
//! prefix up to vertex k (product of f·|cos|/pdf/q of earlier scatterings; β_0 = 1), and the estimate is
//!
//!   L = Σ_k β_k ⊙ ( Le_k·m_k  +  f_nee,k ⊙ Le_nee,k · |cos_nee,k| / p_nee,k · m_nee,k ),
//!
//! with m the MIS weights. The derivative with respect to material or emission parameters holds every pdf,
//! MIS weight and Russian-roulette probability fixed (they are functions of θ, but the estimator stays unbiased
//! for ∂E[L]/∂θ because the weights of all strategies still sum to one for every path). With the radiance
//! arriving at vertex k from its own emission and everything after it,
//!
//!   r_k = Le_k·m_k + f_nee,k ⊙ Le_nee,k·g_k + f_k·(|cos_k|/(p_k q_k)) ⊙ r_{k+1},
//!
//! L = r_0 and ∂L/∂θ_mat(k) = β_k ⊙ (∂f_nee,k ⊙ Le_nee,k·g_k + ∂f_k ⊙ r_{k+1}·|cos_k|/(p_k q_k)). This form needs
//! no division by f, so it stays exact at zero albedo. Emission derivatives are β_k·m_k·∂Le/∂e at every hit
//! (including surfaces that emit nothing now: that is how a hidden light is found) and
//! β_k ⊙ f_nee,k·g_k·∂Le/∂e at every NEE connection.

use crate::bsdf::{BsdfSample, Material, MaterialAt, MaterialGrad};
use crate::embree::RayHit;
use crate::lights::{LightPick, LightSample, LightSampler};
use crate::numerics::{Frame, offset_ray_origin, power_heuristic};
use crate::params::{EmissionProfile, Grads, MaterialGradSum, Params, TracerSettings};
use crate::rng::PathSampler;
use crate::scene::Scene;
use glam::{DVec3, Vec2, Vec3};

/// Fraction of the segment length a shadow ray stops short of its (already offset) target, so that rounding
/// in Embree's t computation cannot report the light itself as the occluder (pbrt's ShadowEpsilon).
const SHADOW_EPSILON: f32 = 1e-4;

/// Highest Russian-roulette survival probability: even a path with throughput ≥ 1 (white closed room) is
/// ended with 5 % probability per bounce, bounding the expected path length.
const RR_MAX_SURVIVAL: f32 = 0.95;

/// Lowest survival probability of gradient paths: their prefix throughput may be zero (black surfaces) while
/// the radiance they carry back is still needed for ∂f (see module doc); keeping ≥ 25 % of them alive costs
/// at most 4× in the variance of those terms and avoids an estimator that is blind at albedo 0.
const RR_MIN_SURVIVAL_GRADIENT: f32 = 0.25;

/// Random-number dimensions: 0–1 pixel jitter, then `DIMS_PER_VERTEX` per vertex.
pub(crate) const DIM_JITTER: u32 = 0;
const DIM_FIRST_VERTEX: u32 = 2;
/// Per vertex: 0 light slot, 1 light triangle, 2–3 light point, 4 lobe, 5–6 direction, 7 roulette.
const DIMS_PER_VERTEX: u32 = 8;
/// The choice between the horizon and zenith entries of a sky with a gradient (`Params::emission_entry`), two
/// per vertex (the emission its ray hits, then its next-event connection), numbered from here: far past any
/// path's per-vertex dimensions, so that scenes without such a sky draw exactly the numbers they drew before.
const DIM_SKY_PICK: u32 = 1 << 30;

/// The random number of a vertex's sky pick (`nee`: its next-event connection; else the emission it hits).
#[inline]
fn sky_pick(rng: &PathSampler, depth: u32, nee: bool) -> f32 {
    rng.get(DIM_SKY_PICK + 2 * depth + u32::from(nee))
}

/// Everything a path needs to read, shared by all paths of one batch.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Context<'a> {
    pub scene: &'a Scene,
    pub params: &'a Params,
    pub lights: &'a LightSampler,
    pub settings: &'a TracerSettings,
}

/// Next-event connection recorded at a vertex (gradient mode).
#[derive(Debug, Clone, Copy)]
struct NeeRecord {
    d_f: MaterialGrad,
    f: Vec3,
    /// Le at the light point towards the vertex (no MIS weight).
    le: Vec3,
    /// |cos| / p_light(solid angle) · MIS weight.
    g: f32,
    emitter: u32,
    /// ∂Le/∂e at the light point.
    le_factor: f32,
}

/// BSDF-sampled continuation recorded at a vertex (gradient mode).
#[derive(Debug, Clone, Copy)]
struct ScatterRecord {
    d_f: MaterialGrad,
    f: Vec3,
    /// |cos| / (pdf · q).
    weight: f32,
}

/// One vertex of a recorded path.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Vertex {
    beta: Vec3,
    material: u32,
    emitter: u32,
    /// Emitted radiance towards the previous vertex, times its MIS weight.
    le: Vec3,
    /// ∂(Le·m)/∂e.
    le_factor: f32,
    nee: Option<NeeRecord>,
    scatter: Option<ScatterRecord>,
}

/// Whether to record the path for differentiation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mode {
    Value,
    Gradient,
}

/// Traces one path from `org` along unit `dir`, returns its radiance estimate; in gradient mode the vertices
/// are appended to `record` (cleared first). `rays` counts the Embree queries made: [closest hit, shadow].
#[inline]
pub(crate) fn trace(
    ctx: &Context<'_>,
    org: Vec3,
    dir: Vec3,
    rng: &PathSampler,
    mode: Mode,
    record: &mut Vec<Vertex>,
    rays: &mut [u64; 2],
) -> Vec3 {
    record.clear();
    // One monomorphised loop per mode: value paths carry no derivative records at all.
    match mode {
        Mode::Value => trace_mode::<false>(ctx, org, dir, rng, record, rays),
        Mode::Gradient => trace_mode::<true>(ctx, org, dir, rng, record, rays),
    }
}

/// A next-event connection whose shadow ray has not been traced yet. Its BSDF terms are evaluated only once the
/// light is known to be visible: in gradient mode that skips the derivative evaluation for every occluded
/// connection (value mode evaluates f before tracing, to skip the shadow ray where f = 0).
#[derive(Debug, Clone, Copy)]
struct PendingShadow {
    from: Vec3,
    /// Unnormalised: `to − from`, traced for t in [0, 1 − SHADOW_EPSILON].
    dir: Vec3,
    /// Direction to the light in the shading frame.
    wi_l: Vec3,
    /// Solid-angle pdf of sampling the light point.
    pdf_l: f32,
    /// Le at the light point towards the vertex (no MIS weight), its ∂Le/∂e and emission entry.
    le: Vec3,
    le_factor: f32,
    emitter: u32,
    /// Value mode: (f, BSDF pdf) already evaluated.
    eval: Option<(Vec3, f32)>,
}

/// Traces a pending shadow ray of vertex `v` (throughput `beta`, BSDF `bsdf`); when it is unoccluded,
/// evaluates the connection (with ∂f in gradient mode), adds its contribution to `l` and records it in `v`.
#[inline]
fn finish_shadow<const GRAD: bool>(
    scene: &Scene,
    bsdf: &MaterialAt<'_>,
    shadow: Option<PendingShadow>,
    beta: Vec3,
    l: &mut Vec3,
    v: &mut Vertex,
    rays: &mut [u64; 2],
) {
    let Some(s) = shadow else { return };
    rays[1] += 1;
    if scene.occluded(s.from, s.dir, 1.0 - SHADOW_EPSILON) {
        return;
    }
    let (f, d_f, pdf_b) = match s.eval {
        Some((f, pdf_b)) if !GRAD => (f, MaterialGrad::default(), pdf_b),
        _ => bsdf.eval_grad_pdf(s.wi_l),
    };
    let mis = power_heuristic(s.pdf_l, pdf_b);
    let g = s.wi_l.z.abs() / s.pdf_l * mis;
    *l += beta * f * s.le * g;
    v.nee = Some(NeeRecord { d_f, f, le: s.le, g, emitter: s.emitter, le_factor: s.le_factor });
}

/// MIS weight of emission reached by a BSDF-sampled ray (`prev_bsdf_pdf`; None for the camera ray: weight 1)
/// at distance `t` and cosine `cos_o` on a triangle of emitter slot `emitter`, against `lights`' density of
/// sampling that point.
#[inline]
fn hit_mis(lights: &LightSampler, emitter: u32, prev_bsdf_pdf: Option<f32>, t: f32, cos_o: f32) -> f32 {
    match prev_bsdf_pdf {
        None => 1.0,
        Some(pdf_b) => {
            let pdf_area = lights.pdf_area_of_slot(emitter);
            if pdf_area > 0.0 {
                let pdf_l = pdf_area * t * t / cos_o;
                power_heuristic(pdf_b, pdf_l)
            } else {
                1.0
            }
        }
    }
}

/// The next-event connection from the shading point `p` (geometric normal `ng` on the viewer's side, shading
/// `frame`, BSDF `bsdf`) to the light sample `ls`, up to its shadow ray; None where it cannot contribute: the
/// light faces away, the point lies behind the surface, or (value mode) the BSDF is 0 there, so that its
/// shadow ray is not traced. Gradient mode still needs ∂f, evaluated after the shadow ray (`finish_shadow`).
/// `emission(slot, wo)` is the emission entry and radiance scale of the light's slot towards `wo` (unit, from
/// the light point to `p`). Value mode returns None where that radiance is 0 as well (nothing to add).
#[inline]
#[allow(clippy::too_many_arguments)]
fn connect<const GRAD: bool>(
    scene: &Scene,
    profile: EmissionProfile,
    bsdf: &MaterialAt<'_>,
    frame: &Frame,
    p: Vec3,
    ng: Vec3,
    ls: LightSample,
    emission: impl Fn(u32, Vec3) -> (u32, Vec3),
) -> Option<PendingShadow> {
    let to_light = ls.p - p;
    let dist2 = to_light.length_squared();
    let wi = to_light / dist2.sqrt();
    let ng_l = scene.geometric_normal(ls.tri);
    let cos_l = -wi.dot(ng_l);
    let le_factor = profile.factor(cos_l);
    if !(le_factor > 0.0 && wi.dot(ng) > 0.0 && dist2 > 0.0) {
        return None;
    }
    let wi_l = frame.to_local(wi);
    let eval = (!GRAD).then(|| bsdf.eval_pdf(wi_l));
    if eval.is_some_and(|(f, _)| f == Vec3::ZERO) {
        return None;
    }
    let from = offset_ray_origin(p, ng, wi);
    let to = offset_ray_origin(ls.p, ng_l, -wi);
    let pdf_l = ls.pdf_area * dist2 / cos_l;
    let (entry, e) = emission(scene.emitter_of(ls.tri), -wi);
    if !GRAD && e == Vec3::ZERO {
        return None;
    }
    let le = e * le_factor;
    Some(PendingShadow { from, dir: to - from, wi_l, pdf_l, le, le_factor, emitter: entry, eval })
}

/// The continuation sampled at a vertex (`wi_l`, `f`, `pdf` of the BSDF sample, in the shading `frame`; `ng`
/// the geometric normal on the viewer's side; `beta` the throughput so far): its world direction and its
/// weight |cos|/(pdf·q) after Russian roulette with survival probability q ≥ `rr_floor`, the roulette's number
/// drawn from dimension `dim_rr`; None where the path ends there (an invalid pdf, a direction below the
/// surface, or the roulette).
#[inline]
#[allow(clippy::too_many_arguments)]
fn continuation(
    frame: &Frame,
    ng: Vec3,
    BsdfSample { wi: wi_l, f, pdf }: BsdfSample,
    beta: Vec3,
    depth: u32,
    settings: &TracerSettings,
    rr_floor: f32,
    rng: &PathSampler,
    dim_rr: u32,
) -> Option<(Vec3, f32)> {
    let wi = frame.to_world(wi_l);
    if pdf.is_nan() || pdf <= 0.0 || wi.dot(ng) <= 0.0 {
        return None;
    }
    let mut weight = wi_l.z.abs() / pdf;
    let beta_next = beta * f * weight;
    if depth + 1 > settings.rr_depth {
        let q = beta_next.max_element().clamp(rr_floor, RR_MAX_SURVIVAL);
        if rng.get(dim_rr) >= q {
            return None;
        }
        weight /= q;
    }
    Some((wi, weight))
}

/// The closest hit of the continuation from `p` along `wi` (the origin offset off the surface with geometric
/// normal `ng`), counted in `rays`, with the hit triangle's record prefetched: the caller traces its pending
/// shadow ray while the record loads.
#[inline]
fn next_hit(scene: &Scene, p: Vec3, ng: Vec3, wi: Vec3, rays: &mut [u64; 2]) -> Option<RayHit> {
    rays[0] += 1;
    let hit = scene.embree().intersect(offset_ray_origin(p, ng, wi), wi, 0.0, f32::INFINITY);
    if let Some(h) = &hit {
        scene.prefetch_triangle(h.prim_id);
    }
    hit
}

/// The path loop of [`trace`]; `GRAD` = gradient mode.
///
/// Order of the Embree queries: a vertex's shadow ray is traced after the closest-hit query of the next ray
/// (both are independent of each other), with the next hit's triangle record prefetched in between, so that
/// the record (one cache line per triangle, usually a miss) arrives while Embree traces the shadow ray.
/// Radiance is accumulated in the same order as without the reordering.
fn trace_mode<const GRAD: bool>(
    ctx: &Context<'_>,
    org: Vec3,
    dir: Vec3,
    rng: &PathSampler,
    record: &mut Vec<Vertex>,
    rays: &mut [u64; 2],
) -> Vec3 {
    let Context { scene, params, lights, settings } = *ctx;
    let profile = settings.emission_profile;
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut d = dir;
    // Solid-angle pdf of the BSDF sample that produced the current ray; None for the camera ray (no MIS).
    let mut prev_bsdf_pdf: Option<f32> = None;
    rays[0] += 1;
    let mut next_hit = scene.embree().intersect(org, dir, 0.0, f32::INFINITY);
    for depth in 0..=settings.max_depth {
        let Some(hit) = next_hit else { break };
        let dim = DIM_FIRST_VERTEX + depth * DIMS_PER_VERTEX;
        let last = depth == settings.max_depth;
        let light = if last || lights.is_empty() {
            None
        } else {
            let u_point = Vec2::new(rng.get(dim + 2), rng.get(dim + 3));
            lights.sample(scene, rng.get(dim), rng.get(dim + 1), u_point)
        };
        let (sp, material_idx, emitter) = scene.surface_and_slots(hit.prim_id, hit.u, hit.v);
        let t = hit.t;
        let wo = -d;
        let mut v =
            Vertex { beta, material: material_idx, emitter, le: Vec3::ZERO, le_factor: 0.0, nee: None, scatter: None };

        // Emission seen along the ray (one-sided: front face only).
        let cos_o = sp.ng.dot(wo);
        let factor = profile.factor(cos_o);
        if factor > 0.0 {
            let mis = hit_mis(lights, emitter, prev_bsdf_pdf, t, cos_o);
            v.le_factor = factor * mis;
            v.emitter = params.emission_entry(emitter, wo, || sky_pick(rng, depth, false));
            v.le = params.emission[v.emitter as usize] * v.le_factor;
            l += beta * v.le;
        }
        if last {
            record_if::<GRAD>(record, v);
            break;
        }

        // Two-sided shading: both normals flipped to the viewer's side.
        let (ng, ns) = if cos_o < 0.0 { (-sp.ng, -sp.ns) } else { (sp.ng, sp.ns) };
        let frame = Frame::from_normal(ns);
        let wo_l = frame.to_local(wo);
        let material: &Material = &params.materials[material_idx as usize];
        // The BSDF terms that depend only on wo (Fresnel at wo, lobe-selection probability), computed once for
        // the next-event evaluation and the sampled continuation.
        let bsdf = material.at(wo_l);

        // Next-event estimation, up to its shadow ray (traced below).
        let shadow = light.and_then(|ls| {
            connect::<GRAD>(scene, profile, &bsdf, &frame, sp.p, ng, ls, |slot, wo| {
                let entry = params.emission_entry(slot, wo, || sky_pick(rng, depth, true));
                (entry, params.emission[entry as usize])
            })
        });

        // BSDF sampling of the continuation. Gradient mode evaluates f once, with its derivatives.
        let u_dir = Vec2::new(rng.get(dim + 5), rng.get(dim + 6));
        let u_lobe = rng.get(dim + 4);
        let sampled = if GRAD {
            bsdf.sample_grad(u_dir, u_lobe)
        } else {
            bsdf.sample(u_dir, u_lobe).map(|s| (s, MaterialGrad::default()))
        };
        let rr_floor = if GRAD { RR_MIN_SURVIVAL_GRADIENT } else { 0.0 };
        let continued = sampled.and_then(|(sample, d_f)| {
            let (wi, weight) = continuation(&frame, ng, sample, beta, depth, settings, rr_floor, rng, dim + 7)?;
            Some((wi, weight, sample.f, sample.pdf, d_f))
        });
        let Some((wi, weight, f, pdf, d_f)) = continued else {
            finish_shadow::<GRAD>(scene, &bsdf, shadow, beta, &mut l, &mut v, rays);
            record_if::<GRAD>(record, v);
            break;
        };
        // The next ray's closest hit first, then this vertex's shadow ray while the hit's record loads.
        next_hit = self::next_hit(scene, sp.p, ng, wi, rays);
        finish_shadow::<GRAD>(scene, &bsdf, shadow, beta, &mut l, &mut v, rays);
        v.scatter = Some(ScatterRecord { d_f, f, weight });
        record_if::<GRAD>(record, v);
        beta *= f * weight;
        prev_bsdf_pdf = Some(pdf);
        d = wi;
    }
    l
}

/// The emitters of [`trace_columns`]: one light sampler per column, each built for its slot alone at unit
/// emission, and the emission entry of each column (a slot, or the ground half of a split slot).
#[derive(Debug, Clone)]
pub(crate) struct Columns {
    /// `samplers[i]` samples column i's slot only (empty if the slot has no area).
    pub samplers: Vec<LightSampler>,
    /// The emission entry of each column.
    pub entries: Vec<u32>,
}

/// What [`trace_columns`] writes and reuses from path to path (one per thread, not one per path): the
/// estimate per column, and each column's pending shadow ray at the current vertex.
#[derive(Debug, Default)]
pub(crate) struct ColumnScratch {
    /// The last path's estimate per column.
    pub out: Vec<Vec3>,
    shadows: Vec<Option<PendingShadow>>,
    /// Each column's light triangle at the current vertex, picked before any is connected.
    picks: Vec<Option<LightPick>>,
}

/// One path's estimate for every column of `cols` at once: entry i of `scratch.out` is exactly
/// what [`trace`] in value mode returns with `Params::emission` = 1 at `cols.entries[i]` and 0 elsewhere (the
/// basis image of that emission entry), bit for bit. The columns share everything that does not depend on which
/// object emits — the camera ray, every BSDF-sampled continuation and its Russian roulette (the throughput
/// does not depend on emission) — and differ only in their next-event connections, each drawn with the same
/// random numbers as that column's own path would draw them, and in their MIS weights. A basis render of K
/// emitters then traces each continuation ray once instead of K times; the shadow rays stay one per column
/// and vertex. The loop follows `trace_mode::<false>` step for step (each column's sums are formed in the
/// same order); the test `columns_match_separate_basis_renders` holds them to the same bits.
pub(crate) fn trace_columns(
    ctx: &Context<'_>,
    cols: &Columns,
    org: Vec3,
    dir: Vec3,
    rng: &PathSampler,
    scratch: &mut ColumnScratch,
    rays: &mut [u64; 2],
) {
    let Context { scene, params, settings, .. } = *ctx;
    let profile = settings.emission_profile;
    let n = cols.entries.len();
    let ColumnScratch { out, shadows, picks } = scratch;
    out.clear();
    out.resize(n, Vec3::ZERO);
    shadows.clear();
    shadows.resize(n, None);
    let mut beta = Vec3::ONE;
    let mut d = dir;
    let mut prev_bsdf_pdf: Option<f32> = None;
    // What `finish_shadow` records its connection into (unused in value mode).
    let mut vertex = Vertex { beta, material: 0, emitter: 0, le: Vec3::ZERO, le_factor: 0.0, nee: None, scatter: None };
    rays[0] += 1;
    let mut next_hit = scene.embree().intersect(org, dir, 0.0, f32::INFINITY);
    for depth in 0..=settings.max_depth {
        let Some(hit) = next_hit else { break };
        let dim = DIM_FIRST_VERTEX + depth * DIMS_PER_VERTEX;
        let last = depth == settings.max_depth;
        let (sp, material_idx, emitter) = scene.surface_and_slots(hit.prim_id, hit.u, hit.v);
        let t = hit.t;
        let wo = -d;

        // Emission seen along the ray: non-zero in the hit emitter's own column only (every other column's
        // emission is 0 here, and adds 0·β).
        let cos_o = sp.ng.dot(wo);
        let factor = profile.factor(cos_o);
        if factor > 0.0 {
            let hit_entry = params.emission_entry(emitter, wo, || sky_pick(rng, depth, false));
            for (i, (sampler, &entry)) in cols.samplers.iter().zip(&cols.entries).enumerate() {
                let mis = hit_mis(sampler, emitter, prev_bsdf_pdf, t, cos_o);
                let e = if entry == hit_entry { Vec3::ONE } else { Vec3::ZERO };
                out[i] += beta * (e * (factor * mis));
            }
        }
        if last {
            break;
        }

        let (ng, ns) = if cos_o < 0.0 { (-sp.ng, -sp.ns) } else { (sp.ng, sp.ns) };
        let frame = Frame::from_normal(ns);
        let wo_l = frame.to_local(wo);
        let material: &Material = &params.materials[material_idx as usize];
        let bsdf = material.at(wo_l);

        // Each column's next-event connection, up to its shadow ray. Every column's light triangle is picked
        // first and its record prefetched, then the points are drawn and connected: with hundreds of columns
        // the records are scattered over the scene's memory, and read one after another each waited for its
        // own cache miss (most of a house's basis render: docs/optim/design-measurements.md, "Basis renders
        // that wait on memory, and solves on one core"). The picks' own reads (a slot's guide entries, then
        // the cdf entries they bracket) are prefetched the same way, one pass over the columns per level: a
        // pick read them as two dependent misses, column after column, half of a house's emission solves
        // (docs/optim/design-measurements.md, "Light picks that wait on their tables").
        let (u_slot, u_tri) = (rng.get(dim), rng.get(dim + 1));
        let u_point = Vec2::new(rng.get(dim + 2), rng.get(dim + 3));
        let slots = || cols.samplers.iter().filter_map(|sampler| sampler.slot(u_slot));
        slots().for_each(|slot| scene.prefetch_emitter_guide(slot, f64::from(u_tri)));
        slots().for_each(|slot| scene.prefetch_emitter_cdf(slot, f64::from(u_tri)));
        picks.clear();
        picks.extend(cols.samplers.iter().map(|sampler| {
            let pick = sampler.pick(scene, u_slot, u_tri);
            if let Some(pick) = pick {
                scene.prefetch_triangle(pick.tri);
            }
            pick
        }));
        for ((shadow, pick), &entry) in shadows.iter_mut().zip(picks.iter()).zip(&cols.entries) {
            *shadow = pick.and_then(|pick| {
                connect::<false>(scene, profile, &bsdf, &frame, sp.p, ng, pick.point(scene, u_point), |slot, wo| {
                    let e = params.emission_entry(slot, wo, || sky_pick(rng, depth, true));
                    (e, if e == entry { Vec3::ONE } else { Vec3::ZERO })
                })
            });
        }
        let finish =
            |shadows: &mut [Option<PendingShadow>], out: &mut [Vec3], vertex: &mut Vertex, rays: &mut [u64; 2]| {
                for (shadow, l) in shadows.iter_mut().zip(out.iter_mut()) {
                    finish_shadow::<false>(scene, &bsdf, shadow.take(), beta, l, vertex, rays);
                }
            };

        let u_dir = Vec2::new(rng.get(dim + 5), rng.get(dim + 6));
        let u_lobe = rng.get(dim + 4);
        let continued = bsdf.sample(u_dir, u_lobe).and_then(|sample| {
            let (wi, weight) = continuation(&frame, ng, sample, beta, depth, settings, 0.0, rng, dim + 7)?;
            Some((wi, weight, sample.f, sample.pdf))
        });
        let Some((wi, weight, f, pdf)) = continued else {
            finish(shadows, out, &mut vertex, rays);
            break;
        };
        next_hit = self::next_hit(scene, sp.p, ng, wi, rays);
        finish(shadows, out, &mut vertex, rays);
        beta *= f * weight;
        prev_bsdf_pdf = Some(pdf);
        d = wi;
    }
}

#[inline]
fn record_if<const GRAD: bool>(record: &mut Vec<Vertex>, v: Vertex) {
    if GRAD {
        record.push(v);
    }
}

/// A sparse gradient contribution of one path.
#[derive(Debug, Clone, Copy)]
pub(crate) enum GradEntry {
    Material(u32, MaterialGradSum),
    Emission(u32, DVec3),
}

impl GradEntry {
    /// The parameter the entry is for: (kind, slot), materials (0) before emissions (1).
    pub(crate) fn param(&self) -> (u8, u32) {
        match *self {
            GradEntry::Material(i, _) => (0, i),
            GradEntry::Emission(i, _) => (1, i),
        }
    }
}

/// The backward pass over a recorded path: adds `∂(w·L)/∂θ` for every parameter it touched to `out`
/// (merged with a recent entry of the same parameter, else appended).
pub(crate) fn backward(path: &[Vertex], w: Vec3, out: &mut Vec<GradEntry>) {
    let mut r_next = Vec3::ZERO;
    for v in path.iter().rev() {
        let wb = w * v.beta;
        let mut r = v.le;
        if v.le_factor > 0.0 {
            add_emission(out, v.emitter, (wb * v.le_factor).as_dvec3());
        }
        let mut m = MaterialGradSum::default();
        let mut touched = false;
        if let Some(n) = &v.nee {
            let a = n.le * n.g;
            r += n.f * a;
            m.add_chain(&n.d_f, wb * a);
            add_emission(out, n.emitter, (wb * n.f * (n.g * n.le_factor)).as_dvec3());
            touched = true;
        }
        if let Some(s) = &v.scatter {
            let b = r_next * s.weight;
            r += s.f * b;
            m.add_chain(&s.d_f, wb * b);
            touched = true;
        }
        if touched {
            add_material(out, v.material, &m);
        }
        r_next = r;
    }
}

/// Number of most recent entries searched for the same parameter before appending a new one: a pixel's
/// paths touch few objects, so this merges nearly all duplicates while bounding the search cost when
/// parameters are per triangle (then entries are merely longer, results identical up to rounding order,
/// which is itself fixed).
const MERGE_WINDOW: usize = 32;

fn add_emission(out: &mut Vec<GradEntry>, idx: u32, d: DVec3) {
    let start = out.len().saturating_sub(MERGE_WINDOW);
    for e in out[start..].iter_mut().rev() {
        if let GradEntry::Emission(i, acc) = e
            && *i == idx
        {
            *acc += d;
            return;
        }
    }
    out.push(GradEntry::Emission(idx, d));
}

fn add_material(out: &mut Vec<GradEntry>, idx: u32, m: &MaterialGradSum) {
    let start = out.len().saturating_sub(MERGE_WINDOW);
    for e in out[start..].iter_mut().rev() {
        if let GradEntry::Material(i, acc) = e
            && *i == idx
        {
            acc.add(m);
            return;
        }
    }
    out.push(GradEntry::Material(idx, *m));
}

/// Where the most recent entry of each parameter lies in one pixel's entry list: [`merge`]'s lookup, an
/// open-addressing table keyed by the parameter (kind and index), so that merging a path's entry costs one
/// lookup instead of a scan of the list's last [`MERGE_WINDOW`] entries (56 bytes each). On a 213-object house
/// the scan was 8 % of the object stage's lobe search (`docs/scale/README.md`, "Per-pixel gradients at house
/// scale"). Cleared for every pixel's list ([`EntryIndex::clear`]).
#[derive(Debug, Default, Clone)]
pub(crate) struct EntryIndex {
    /// Per bucket: the key ([`EntryIndex::EMPTY`] when free); a power-of-two length, at most half full.
    keys: Vec<u64>,
    /// Per bucket: the position of the key's most recent entry in the list.
    at: Vec<u32>,
    /// Occupied buckets.
    used: usize,
}

impl EntryIndex {
    const EMPTY: u64 = u64::MAX;
    /// Buckets of a table's first allocation: a pixel's paths touch tens of parameters on a house.
    const FIRST: usize = 64;

    /// Forgets every entry (the next pixel's list starts empty).
    pub(crate) fn clear(&mut self) {
        if self.used > 0 {
            self.keys.fill(Self::EMPTY);
            self.used = 0;
        }
    }

    fn key(e: &GradEntry) -> u64 {
        let (kind, slot) = e.param();
        (u64::from(slot) << 1) | u64::from(kind)
    }

    /// The bucket holding `key`, or the free one where it goes (linear probing from a Fibonacci hash).
    fn bucket(&self, key: u64) -> usize {
        let mask = self.keys.len() - 1;
        let mut b = (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize & mask;
        loop {
            let k = self.keys[b];
            if k == key || k == Self::EMPTY {
                return b;
            }
            b = (b + 1) & mask;
        }
    }

    /// Makes room for one more key at a load of at most one half.
    fn reserve_one(&mut self) {
        if 2 * (self.used + 1) <= self.keys.len() {
            return;
        }
        let cap = (2 * self.keys.len()).max(Self::FIRST);
        let keys = std::mem::replace(&mut self.keys, vec![Self::EMPTY; cap]);
        let at = std::mem::replace(&mut self.at, vec![0; cap]);
        for (k, a) in keys.into_iter().zip(at) {
            if k != Self::EMPTY {
                let b = self.bucket(k);
                self.keys[b] = k;
                self.at[b] = a;
            }
        }
    }
}

/// Adds one path's entries (from [`backward`] into an empty vector) to a pixel's entries `out`, merged like
/// [`backward`] merges them: into the parameter's most recent entry when it is among the last
/// [`MERGE_WINDOW`], else appended. `index` holds the positions of `out`'s entries (empty with `out`).
pub(crate) fn merge(out: &mut Vec<GradEntry>, path: &[GradEntry], index: &mut EntryIndex) {
    for e in path {
        index.reserve_one();
        let key = EntryIndex::key(e);
        let b = index.bucket(key);
        let start = out.len().saturating_sub(MERGE_WINDOW);
        if index.keys[b] == key && index.at[b] as usize >= start {
            match (&mut out[index.at[b] as usize], e) {
                (GradEntry::Material(_, acc), GradEntry::Material(_, m)) => acc.add(m),
                (GradEntry::Emission(_, acc), GradEntry::Emission(_, d)) => *acc += *d,
                // The key holds the kind, so the entry found under it is of the same kind.
                _ => unreachable!("entry index: kinds differ under one key"),
            }
        } else {
            if index.keys[b] == EntryIndex::EMPTY {
                index.keys[b] = key;
                index.used += 1;
            }
            index.at[b] = out.len() as u32;
            out.push(*e);
        }
    }
}

/// Adds entries into a dense table, in order.
pub(crate) fn accumulate(grads: &mut Grads, entries: &[GradEntry]) {
    for e in entries {
        match *e {
            GradEntry::Material(i, ref m) => grads.materials[i as usize].add(m),
            GradEntry::Emission(i, ref d) => grads.emission[i as usize] += *d,
        }
    }
}

/// Lambda for `r_0`: the radiance implied by a recorded path; equals `trace`'s return value (used in tests).
#[cfg(test)]
pub(crate) fn replay_radiance(path: &[Vertex]) -> Vec3 {
    let mut r_next = Vec3::ZERO;
    for v in path.iter().rev() {
        let mut r = v.le;
        if let Some(n) = &v.nee {
            r += n.f * n.le * n.g;
        }
        if let Some(s) = &v.scatter {
            r += s.f * r_next * s.weight;
        }
        r_next = r;
    }
    r_next
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{PixelKey, Stream};
    use crate::scene::SceneInput;

    /// The merge as a scan of the last [`MERGE_WINDOW`] entries (what [`backward`] does within a path).
    fn merge_by_scan(out: &mut Vec<GradEntry>, path: &[GradEntry]) {
        for e in path {
            match *e {
                GradEntry::Material(i, ref m) => add_material(out, i, m),
                GradEntry::Emission(i, d) => add_emission(out, i, d),
            }
        }
    }

    /// The indexed merge gives the scan's entries, in its order, with its sums bit for bit: over pixels whose
    /// paths touch a few parameters (all merged) and pixels whose paths touch thousands (per-triangle slots,
    /// where older entries leave the window and a parameter gets a second entry), one index reused across
    /// pixels as the renderer reuses it.
    #[test]
    fn the_indexed_merge_is_the_scan() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut index = EntryIndex::default();
        let mut second_entries = 0;
        for (pixel, params) in [8u64, 40, 3000, 12, 100_000, 5].into_iter().enumerate() {
            index.clear();
            let (mut scanned, mut indexed) = (Vec::new(), Vec::new());
            for _ in 0..64 {
                let path: Vec<GradEntry> = (0..1 + next() % 12)
                    .map(|_| {
                        let i = (next() % params) as u32;
                        let v = (next() % 1000) as f64 / 7.0 - 50.0;
                        if next() % 3 == 0 {
                            GradEntry::Emission(i, DVec3::new(v, -v, 0.5 * v))
                        } else {
                            let m = MaterialGradSum {
                                base_color: DVec3::new(v, 0.25 * v, -v),
                                roughness: v,
                                metallic: 0.0,
                                specular: -0.5 * v,
                            };
                            GradEntry::Material(i, m)
                        }
                    })
                    .collect();
                merge_by_scan(&mut scanned, &path);
                merge(&mut indexed, &path, &mut index);
            }
            assert_eq!(scanned.len(), indexed.len(), "pixel {pixel}");
            for (a, b) in scanned.iter().zip(&indexed) {
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "pixel {pixel}");
            }
            let mut keys: Vec<u64> = indexed.iter().map(EntryIndex::key).collect();
            keys.sort_unstable();
            keys.dedup();
            second_entries += indexed.len() - keys.len();
        }
        // The window was exercised: some parameter got a second entry.
        assert!(second_entries > 0);
    }

    /// A closed unit cube (inward faces, emitter slot 0 off) with a glossy floor and an emitting ceiling
    /// (emitter slot 1), and the floor on its own emitter slot 2.
    fn room() -> (Scene, Params) {
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let quads = [
            ([v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)], 0, 2), // floor, +y
            ([v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)], 1, 1), // ceiling, −y (light)
            ([v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)], 1, 0),
            ([v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)], 1, 0),
            ([v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)], 1, 0),
            ([v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)], 1, 0),
        ];
        let mut input = SceneInput::default();
        for (q, m, e) in quads {
            let b = input.positions.len() as u32;
            input.positions.extend(q);
            input.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
            input.material_of_tri.extend([m, m]);
            input.emitter_of_tri.extend([e, e]);
        }
        let params = Params {
            materials: vec![
                Material { base_color: Vec3::new(0.8, 0.5, 0.3), roughness: 0.3, metallic: 0.5, specular: 0.5 },
                Material { base_color: Vec3::splat(0.6), roughness: 1.0, metallic: 0.0, specular: 0.0 },
            ],
            emission: vec![Vec3::ZERO, Vec3::new(3.0, 2.0, 1.0), Vec3::new(0.2, 0.1, 0.0)],
            horizon: Default::default(),
        };
        (Scene::new(input).expect("scene"), params)
    }

    #[test]
    fn recorded_path_replays_its_radiance_and_is_homogeneous_in_emission() {
        let (scene, params) = room();
        let lights = LightSampler::new(&scene, &params);
        let settings = TracerSettings { max_depth: 6, rr_depth: 2, ..Default::default() };
        let ctx = Context { scene: &scene, params: &params, lights: &lights, settings: &settings };
        let no_rr = TracerSettings { rr_depth: settings.max_depth, ..settings };
        let ctx_no_rr = Context { settings: &no_rr, ..ctx };
        let w = Vec3::new(1.0, -0.5, 2.0);
        let mut record = Vec::new();
        let mut rays = [0; 2];
        for i in 0..500u32 {
            let rng = PathSampler::new(4, Stream::Gradient, 0, PixelKey { view: 0, x: i, y: 0 }, 0);
            let dir = Vec3::new(rng.get(0) - 0.5, rng.get(1) - 0.5, -1.0).normalize();
            let l = trace(&ctx, Vec3::new(0.5, 0.5, 0.9), dir, &rng, Mode::Gradient, &mut record, &mut rays);
            let replay = replay_radiance(&record);
            // 1e-4 relative: the same f32 products summed in a different order.
            assert!((l - replay).abs().max_element() <= 1e-4 * (1.0 + l.max_element()), "{l} vs {replay}");
            // The estimate is linear in the emission table: Σ_i e_i·∂(w·L)/∂e_i = w·L (Euler's theorem).
            let mut entries = Vec::new();
            backward(&record, w, &mut entries);
            let mut grads = Grads::zeros_like(&params);
            accumulate(&mut grads, &entries);
            let euler: f64 = grads.emission.iter().zip(&params.emission).map(|(g, e)| g.dot(e.as_dvec3())).sum();
            let wl = f64::from(w.dot(l));
            assert!((euler - wl).abs() <= 1e-4 * (1.0 + wl.abs()), "path {i}: {euler} vs {wl}");
            // Without roulette (whose gradient-mode floor differs), value mode draws the same numbers and follows
            // the same path to the same value.
            let (mut rec, mut rays2) = (Vec::new(), [0; 2]);
            let o = Vec3::new(0.5, 0.5, 0.9);
            let lg = trace(&ctx_no_rr, o, dir, &rng, Mode::Gradient, &mut rec, &mut rays2);
            let lv = trace(&ctx_no_rr, o, dir, &rng, Mode::Value, &mut rec, &mut rays2);
            assert!((lv - lg).abs().max_element() <= 1e-4 * (1.0 + lg.max_element()), "{lv} vs {lg}");
        }
        assert!(rays[0] > 500 && rays[1] > 0);
    }
}
