//! Light selection for next-event estimation: a triangle is chosen with probability ∝ (mean RGB emission
//! scale, over both halves of a slot split at the horizon) × area, i.e. ∝ its emitted power under either
//! profile (the profile integral over the hemisphere, π or 2π/3, is the same constant for all triangles). Built per parameter set, so an object becomes a light
//! as soon as the optimiser gives it emission; triangles emitting nothing are never selected (their
//! contribution is still found by BSDF sampling, with MIS weight 1).

use crate::params::Params;
use crate::scene::Scene;
use glam::{Vec2, Vec3};

/// Two-level distribution: an emitter slot with probability ∝ mean emission × slot area, then a triangle of
/// the slot ∝ its area (precomputed in the [`Scene`]), so a triangle's probability is ∝ its emitted power and
/// building the sampler costs O(emitter slots), not O(triangles).
#[derive(Debug, Clone, PartialEq)]
pub struct LightSampler {
    /// Emitting slots, in index order.
    slots: Vec<u32>,
    /// Inclusive prefix sums of their weights, normalised so the last is 1.
    cdf: Vec<f64>,
    /// Selection probability of every slot divided by its area (0 for non-emitting slots): the probability
    /// of a triangle is this times its area.
    prob_per_area: Vec<f64>,
}

/// A point sampled on an emitter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    pub tri: u32,
    pub p: Vec3,
    /// Probability density per unit area (selection probability / triangle area).
    pub pdf_area: f32,
}

impl LightSampler {
    /// `params` must cover the scene (see `Params::check`).
    #[must_use]
    pub fn new(scene: &Scene, params: &Params) -> Self {
        let n = scene.emitter_slots();
        let mut slots = Vec::new();
        let mut weights = Vec::new();
        for e in 0..n as u32 {
            // A slot split at the horizon: the mean of its halves (each sends its radiance into one of the two
            // halves of a vertical emitter's directions, so the mean is its power up to the constant above),
            // its sky half the mean of its horizon and zenith when it has a gradient (an estimate of its flux
            // that only steers sampling).
            let em = match params.horizon.ground_of(e) {
                Some(g) => {
                    let sky = params.flat_sky(e, 0.5);
                    (sky + params.emission[g as usize].as_dvec3()) / 2.0
                }
                None => params.emission[e as usize].as_dvec3(),
            };
            // Negative or NaN emission (possible transiently inside an optimiser step) is not sampled.
            // Summed in f64: an f32 sum of three channels near f32::MAX would overflow and drop the light.
            let w = em.element_sum() / 3.0 * scene.emitter_area(e);
            if w > 0.0 && w.is_finite() {
                slots.push(e);
                weights.push(w);
            }
        }
        let total: f64 = weights.iter().sum();
        let mut prob_per_area = vec![0.0f64; n];
        let mut cdf = Vec::with_capacity(weights.len());
        let mut acc = 0.0;
        for (&e, &w) in slots.iter().zip(&weights) {
            acc += w;
            cdf.push(acc / total);
            prob_per_area[e as usize] = w / total / scene.emitter_area(e);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        LightSampler { slots, cdf, prob_per_area }
    }

    /// True when nothing emits: next-event estimation is skipped.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Density per unit area with which `sample` picks points on triangle `tri`.
    #[inline]
    #[must_use]
    pub fn pdf_area(&self, scene: &Scene, tri: u32) -> f32 {
        self.pdf_area_of_slot(scene.emitter_of(tri))
    }

    /// Density per unit area with which `sample` picks points on any triangle of emitter slot `slot`.
    #[inline]
    #[must_use]
    pub fn pdf_area_of_slot(&self, slot: u32) -> f32 {
        self.prob_per_area[slot as usize] as f32
    }

    /// Picks an emitting slot with `u_slot`, one of its triangles with `u_tri` and a uniform point on the
    /// triangle with `u_point` (separate numbers: rescaling one would leave too few bits for large slots).
    #[inline]
    #[must_use]
    pub fn sample(&self, scene: &Scene, u_slot: f32, u_tri: f32, u_point: Vec2) -> Option<LightSample> {
        self.pick(scene, u_slot, u_tri).map(|pick| pick.point(scene, u_point))
    }

    /// The first half of [`LightSampler::sample`]: the triangle, chosen from the sampler's and the scene's
    /// distributions without reading the triangle's own record. A caller drawing many samples at a vertex (one
    /// per emission column) picks them all first and prefetches their records ([`Scene::prefetch_triangle`]),
    /// so that the records' cache misses overlap instead of following one another.
    #[inline]
    #[must_use]
    pub fn pick(&self, scene: &Scene, u_slot: f32, u_tri: f32) -> Option<LightPick> {
        let slot = self.slot(u_slot)?;
        let tri = scene.sample_emitter_triangle(slot, f64::from(u_tri))?;
        Some(LightPick { tri, pdf_area: self.prob_per_area[slot as usize] as f32 })
    }

    /// The emitter slot that [`LightSampler::pick`] draws with `u_slot` (None when nothing emits): read from
    /// the sampler's own table, not the scene's, so a caller can prefetch the scene's tables for the pick
    /// ([`Scene::prefetch_emitter_guide`]) before making it.
    #[inline]
    #[must_use]
    pub fn slot(&self, u_slot: f32) -> Option<u32> {
        if self.slots.is_empty() {
            return None;
        }
        let u = f64::from(u_slot);
        let i = self.cdf.partition_point(|&c| c <= u).min(self.slots.len() - 1);
        Some(self.slots[i])
    }
}

/// A triangle picked by [`LightSampler::pick`], before its point is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightPick {
    pub tri: u32,
    /// Probability density per unit area of the points drawn on it.
    pub pdf_area: f32,
}

impl LightPick {
    /// The uniform point on the triangle drawn with `u_point`: the second half of [`LightSampler::sample`].
    #[inline]
    #[must_use]
    pub fn point(self, scene: &Scene, u_point: Vec2) -> LightSample {
        // Uniform barycentrics by the square-root warp (pbrt-v4 SampleUniformTriangle's classic variant).
        let r = u_point.x.sqrt();
        let (b1, b2) = (1.0 - r, u_point.y * r);
        LightSample { tri: self.tri, p: scene.position(self.tri, b1, b2), pdf_area: self.pdf_area }
    }
}
