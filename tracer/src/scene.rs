//! The geometry the tracer renders: one Embree triangle geometry plus per-triangle data (area, geometric
//! normal, optional vertex normals, and the indices into the material and emission tables of [`crate::Params`]).
//!
//! Orientation: the geometric normal of triangle (v0, v1, v2) is `(v1 − v0) × (v2 − v0)` normalised
//! (counter-clockwise front face, as in Mitsuba, pbrt and OBJ). It decides the emitting side (emission is
//! one-sided: only the front face emits) and is used for ray offsets and visibility. Reflection is two-sided:
//! the shading frame is flipped to the side the light arrives from / the viewer is on.

use crate::embree::TriangleScene;
use crate::error::TracerError;
use crate::numerics::normalize_or;
use glam::Vec3;

/// What the caller hands in. `material_of_tri[t]` / `emitter_of_tri[t]` index `Params::materials` /
/// `Params::emission` (per-object tables: many triangles share an index; per-triangle tables: identity).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneInput {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex shading normals (need not be unit length); `None` = flat shading.
    pub normals: Option<Vec<Vec3>>,
    pub material_of_tri: Vec<u32>,
    pub emitter_of_tri: Vec<u32>,
}

/// A surface point found by a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    pub p: Vec3,
    /// Unit geometric normal, front-face orientation (not flipped towards the ray).
    pub ng: Vec3,
    /// Unit shading normal on the same side as `ng`.
    pub ns: Vec3,
    pub tri: u32,
}

/// Everything a hit needs about its triangle, in one 64-byte cache line.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
struct TriData {
    corners: [Vec3; 3],
    /// Unit geometric normal.
    ng: Vec3,
    area: f32,
    material: u32,
    emitter: u32,
}

/// An immutable, committed scene; safe to share between threads.
#[derive(Debug)]
pub struct Scene {
    embree: TriangleScene,
    triangles: Vec<[u32; 3]>,
    tri_data: Vec<TriData>,
    normals: Option<Vec<Vec3>>,
    emitter_of_tri: Vec<u32>,
    material_slots: usize,
    emitter_slots: usize,
    /// Triangles of each emitter slot: `slot_cdf[slot_start[e]..slot_start[e + 1]]`, in index order, each with
    /// the slot's cdf of area there.
    slot_start: Vec<usize>,
    slot_cdf: Vec<CdfEntry>,
    /// A guide table per slot (the cutpoint method): for a slot of n triangles, the n + 1 entries from
    /// `slot_start[e] + e`, entry g the first index of the slot's cdf above g / n, so that a draw u in
    /// [g / n, (g + 1) / n) searches only between entries g and g + 1 (about one triangle) instead of the whole
    /// cdf: a cache line or two instead of log₂ n dependent misses, which dominated a house's basis renders
    /// (a draw per emitter slot per vertex).
    slot_guide: Vec<u32>,
    /// Total area of each emitter slot.
    slot_area: Vec<f64>,
}

impl Scene {
    /// Validates the input and builds the Embree scene.
    pub fn new(input: SceneInput) -> Result<Scene, TracerError> {
        let SceneInput { positions, triangles, normals, material_of_tri, emitter_of_tri } = input;
        let n = triangles.len();
        for (what, got) in [("material_of_tri", material_of_tri.len()), ("emitter_of_tri", emitter_of_tri.len())] {
            if got != n {
                return Err(TracerError::LengthMismatch { what, expected: n, got });
            }
        }
        if let Some(ns) = &normals {
            if ns.len() != positions.len() {
                return Err(TracerError::LengthMismatch { what: "normals", expected: positions.len(), got: ns.len() });
            }
            if let Some((vertex, &value)) = ns.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(TracerError::NonFinite { what: "normal", vertex, value });
            }
        }
        if let Some((vertex, &value)) = positions.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(TracerError::NonFinite { what: "position", vertex, value });
        }
        let embree = TriangleScene::new(&positions, &triangles)?;
        let mut tri_data = Vec::with_capacity(n);
        for (i, t) in triangles.iter().enumerate() {
            let corners = t.map(|i| positions[i as usize]);
            let [a, b, c] = corners;
            let cr = (b - a).cross(c - a);
            tri_data.push(TriData {
                corners,
                area: 0.5 * cr.length(),
                // Degenerate triangles have no normal; Embree never reports hits on them and their zero area
                // gives them zero light-selection probability, so any unit vector will do.
                ng: normalize_or(cr, Vec3::Z),
                material: material_of_tri[i],
                emitter: emitter_of_tri[i],
            });
        }
        let material_slots = material_of_tri.iter().max().map_or(0, |&m| m as usize + 1);
        let emitter_slots = emitter_of_tri.iter().max().map_or(0, |&m| m as usize + 1);
        // Counting sort of triangles by emitter slot (stable: index order within a slot).
        let mut slot_start = vec![0usize; emitter_slots + 1];
        for &e in &emitter_of_tri {
            slot_start[e as usize + 1] += 1;
        }
        for i in 0..emitter_slots {
            slot_start[i + 1] += slot_start[i];
        }
        let mut fill = slot_start.clone();
        let mut slot_cdf = vec![CdfEntry { cdf: 0.0, tri: 0 }; n];
        for (t, &e) in emitter_of_tri.iter().enumerate() {
            slot_cdf[fill[e as usize]].tri = t as u32;
            fill[e as usize] += 1;
        }
        let mut slot_area = vec![0.0f64; emitter_slots];
        for e in 0..emitter_slots {
            let range = slot_start[e]..slot_start[e + 1];
            let mut acc = 0.0;
            for k in range.clone() {
                acc += f64::from(tri_data[slot_cdf[k].tri as usize].area);
                slot_cdf[k].cdf = acc;
            }
            slot_area[e] = acc;
            if acc > 0.0 {
                for k in range {
                    slot_cdf[k].cdf /= acc;
                }
            }
        }
        let mut slot_guide = Vec::with_capacity(n + emitter_slots);
        for e in 0..emitter_slots {
            slot_guide.extend(guide_table(&slot_cdf[slot_start[e]..slot_start[e + 1]], CdfEntry::cdf));
        }
        Ok(Scene {
            embree,
            triangles,
            tri_data,
            normals,
            emitter_of_tri,
            material_slots,
            emitter_slots,
            slot_start,
            slot_cdf,
            slot_guide,
            slot_area,
        })
    }

    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Minimum length of `Params::materials` (largest index used + 1).
    #[must_use]
    pub fn material_slots(&self) -> usize {
        self.material_slots
    }

    /// Minimum length of `Params::emission`.
    #[must_use]
    pub fn emitter_slots(&self) -> usize {
        self.emitter_slots
    }

    #[inline]
    #[must_use]
    pub fn area(&self, tri: u32) -> f32 {
        self.tri_data[tri as usize].area
    }

    /// Unit geometric normal `(v1 − v0) × (v2 − v0)` normalised (front face).
    #[inline]
    #[must_use]
    pub fn geometric_normal(&self, tri: u32) -> Vec3 {
        self.tri_data[tri as usize].ng
    }

    /// Per emitter slot: what a split at the horizon `up` needs of its geometry ([`horizon_geometry`]).
    #[must_use]
    pub fn horizon_geometry(&self, up: Vec3) -> HorizonGeometry {
        let tris = (0..self.tri_data.len() as u32)
            .map(|t| (self.emitter_of(t), f64::from(self.area(t)), self.geometric_normal(t)));
        horizon_geometry(up, self.emitter_slots(), tris)
    }

    #[inline]
    #[must_use]
    pub fn material_of(&self, tri: u32) -> u32 {
        self.tri_data[tri as usize].material
    }

    #[inline]
    #[must_use]
    pub fn emitter_of(&self, tri: u32) -> u32 {
        self.tri_data[tri as usize].emitter
    }

    /// Total surface area of emitter slot `slot`.
    #[inline]
    #[must_use]
    pub fn emitter_area(&self, slot: u32) -> f64 {
        self.slot_area[slot as usize]
    }

    /// A triangle of emitter slot `slot` chosen with probability ∝ its area by `u` in [0, 1), or None when the
    /// slot has no area.
    #[inline]
    #[must_use]
    pub fn sample_emitter_triangle(&self, slot: u32, u: f64) -> Option<u32> {
        let area = self.slot_area[slot as usize];
        let SlotTables { start, n, guide } = self.slot_tables(slot)?;
        if n == 0 || area.is_nan() || area <= 0.0 {
            return None;
        }
        if n == 1 {
            return Some(self.slot_cdf[start].tri);
        }
        let cdf = &self.slot_cdf[start..start + n];
        let guide = &self.slot_guide[guide..][..=n];
        // Zero-area triangles have an empty cdf interval and so are never chosen by the strict comparison.
        let k = guided_partition_point(cdf, CdfEntry::cdf, guide, u).min(cdf.len() - 1);
        Some(cdf[k].tri)
    }

    /// Starts loading what [`Scene::sample_emitter_triangle`]`(slot, u)` reads first — the guide entries of
    /// u's bucket (or the slot's one entry) — without waiting for it. Stage 1 of a batch of picks: a caller
    /// that picks a triangle of each of many slots at one vertex (a basis render's columns) issues stage 1
    /// for all of them, then [`Scene::prefetch_emitter_cdf`] for all, then the picks, so that the picks' two
    /// dependent cache misses overlap across slots instead of following one another. Reads nothing that is
    /// not already in cache (the slot's bounds), and never fails: a slot out of range does nothing.
    #[inline]
    pub fn prefetch_emitter_guide(&self, slot: u32, u: f64) {
        let Some(SlotTables { start, n, guide }) = self.slot_tables(slot) else { return };
        if n == 1 {
            if let Some(e) = self.slot_cdf.get(start) {
                crate::embree::prefetch(e);
            }
        } else if n > 1 {
            if let Some(g) = self.slot_guide.get(guide + guide_bucket(u, n)) {
                crate::embree::prefetch(g);
            }
        }
    }

    /// Stage 2 of a batch of picks ([`Scene::prefetch_emitter_guide`]): reads the guide entries of u's bucket
    /// and starts loading the cdf entries that bracket it (the first and last that
    /// [`Scene::sample_emitter_triangle`] compares), without waiting for them. Never fails.
    #[inline]
    pub fn prefetch_emitter_cdf(&self, slot: u32, u: f64) {
        let Some(SlotTables { start, n, guide }) = self.slot_tables(slot) else { return };
        if n <= 1 {
            return;
        }
        let at = guide + guide_bucket(u, n);
        let (Some(&lo), Some(&hi)) = (self.slot_guide.get(at), self.slot_guide.get(at + 1)) else { return };
        for i in [(lo as usize).saturating_sub(1), (hi as usize).min(n - 1)] {
            if let Some(e) = self.slot_cdf.get(start + i) {
                crate::embree::prefetch(e);
            }
        }
    }

    /// Where the pick tables of emitter slot `slot` live ([`SlotTables`]), read by `get` so that the
    /// prefetches stay infallible: None for a slot out of range.
    #[inline]
    fn slot_tables(&self, slot: u32) -> Option<SlotTables> {
        let start = *self.slot_start.get(slot as usize)?;
        let end = *self.slot_start.get(slot as usize + 1)?;
        // Each slot's guide has one entry more than its cdf, so slot s's guide starts s entries after its cdf.
        Some(SlotTables { start, n: end.saturating_sub(start), guide: start + slot as usize })
    }

    #[must_use]
    pub fn emitter_of_tri(&self) -> &[u32] {
        &self.emitter_of_tri
    }

    #[inline]
    #[must_use]
    pub fn embree(&self) -> &TriangleScene {
        &self.embree
    }

    /// Closest surface along `org + t·dir`, t in [0, tfar].
    #[inline]
    #[must_use]
    pub fn intersect(&self, org: Vec3, dir: Vec3, tfar: f32) -> Option<(SurfacePoint, f32)> {
        let h = self.embree.intersect(org, dir, 0.0, tfar)?;
        Some((self.surface(h.prim_id, h.u, h.v), h.t))
    }

    /// True when something blocks the segment `org + t·dir`, t in [0, tfar].
    #[inline]
    #[must_use]
    pub fn occluded(&self, org: Vec3, dir: Vec3, tfar: f32) -> bool {
        self.embree.occluded(org, dir, 0.0, tfar)
    }

    /// The position with barycentrics (u, v) of vertices 1 and 2 on triangle `tri` (no normals).
    #[inline]
    #[must_use]
    pub fn position(&self, tri: u32, u: f32, v: f32) -> Vec3 {
        let [a, b, c] = self.tri_data[tri as usize].corners;
        a * (1.0 - u - v) + b * u + c * v
    }

    /// The surface point with barycentrics (u, v) of vertices 1 and 2 on triangle `tri`. The position is
    /// interpolated from the vertices (more accurate than `org + t·dir`, see `offset_ray_origin`).
    #[inline]
    #[must_use]
    pub fn surface(&self, tri: u32, u: f32, v: f32) -> SurfacePoint {
        self.surface_and_slots(tri, u, v).0
    }

    /// Starts loading the record of triangle `tri` (the line `surface_and_slots` reads) into the cache, without
    /// waiting for it.
    #[inline]
    pub fn prefetch_triangle(&self, tri: u32) {
        if let Some(d) = self.tri_data.get(tri as usize) {
            crate::embree::prefetch(d);
        }
    }

    /// [`Scene::surface`] together with the triangle's material and emitter slots, all read from the one
    /// cache line of the triangle's record (the integrator's per-hit lookup).
    #[inline]
    #[must_use]
    pub fn surface_and_slots(&self, tri: u32, u: f32, v: f32) -> (SurfacePoint, u32, u32) {
        let d = &self.tri_data[tri as usize];
        let [a, b, c] = d.corners;
        let w = 1.0 - u - v;
        let p = a * w + b * u + c * v;
        let ng = d.ng;
        let ns = match &self.normals {
            Some(n) => {
                let [na, nb, nc] = self.triangles[tri as usize].map(|i| n[i as usize]);
                let s = normalize_or(na * w + nb * u + nc * v, ng);
                // Vertex normals that disagree with the winding are taken to mean the other side.
                if s.dot(ng) < 0.0 { -s } else { s }
            }
            None => ng,
        };
        (SurfacePoint { p, ng, ns, tri }, d.material, d.emitter)
    }
}

/// A triangle of an emitter slot and the slot's cdf of area up to and including it, side by side: the search
/// that ends on an entry has its triangle in the same cache line.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CdfEntry {
    cdf: f64,
    tri: u32,
}

impl CdfEntry {
    fn cdf(&self) -> f64 {
        self.cdf
    }
}

/// The guide table of a cdf of n entries (`cdf(entry)` non-decreasing): n + 1 entries, entry g the first
/// index whose cdf is above g / n.
fn guide_table<T>(entries: &[T], cdf: impl Fn(&T) -> f64) -> Vec<u32> {
    let n = entries.len();
    (0..=n)
        .map(|g| {
            let at = g as f64 / n as f64;
            entries.partition_point(|e| cdf(e) <= at) as u32
        })
        .collect()
}

/// One emitter slot's pick tables: its cdf entries `slot_cdf[start..start + n]` and its guide entries
/// `slot_guide[guide..=guide + n]` ([`guide_table`]).
#[derive(Debug, Clone, Copy)]
struct SlotTables {
    start: usize,
    n: usize,
    guide: usize,
}

/// The guide-table bucket of a draw u over a cdf of n entries: ⌊u·n⌋ within 0..n. `as usize` saturates, so a
/// negative or NaN u gives bucket 0, which [`guided_partition_point`] then rejects or confirms.
#[inline]
fn guide_bucket(u: f64, n: usize) -> usize {
    ((u * n as f64) as usize).min(n.saturating_sub(1))
}

/// `entries.partition_point(|e| cdf(e) <= u)`, exactly, searched only between the two entries of `guide`
/// ([`guide_table`]) that bracket u. Where they do not (u rounded onto a bucket's edge, or u outside [0, 1)),
/// all entries are searched.
#[inline]
fn guided_partition_point<T>(entries: &[T], cdf: impl Fn(&T) -> f64, guide: &[u32], u: f64) -> usize {
    let n = entries.len();
    let g = guide_bucket(u, n);
    let (lo, hi) = (guide[g] as usize, (guide[g + 1] as usize).min(n));
    // The cdf does not decrease: every entry before the answer is ≤ u and every entry from it on is > u, so
    // these checks put the answer in lo..=hi.
    let bracketed = lo <= hi && (lo == 0 || cdf(&entries[lo - 1]) <= u) && (hi == n || cdf(&entries[hi]) > u);
    if bracketed {
        lo + entries[lo..hi].partition_point(|e| cdf(e) <= u)
    } else {
        entries.partition_point(|e| cdf(e) <= u)
    }
}

/// Per emitter slot, what a split at the horizon needs of its geometry ([`horizon_geometry`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HorizonGeometry {
    /// The share of its cosine-weighted emission that leaves upward (what splitting it at the horizon
    /// divides): the area-weighted mean of (1 + n·up)/2 over its triangles (the share of a cosine-weighted
    /// hemisphere on the far side of a plane through its centre is (1 + cos θ)/2, θ between the normal and the
    /// plane's normal); 0 for a slot without area.
    pub upward: Vec<f64>,
    /// The mean of s = −ω·up, the sine of the elevation of the sky that a direction ω leaving it downward
    /// carries, over its downward cosine-weighted emission (what makes a graded sky flat at the same flux):
    /// 4/(3π) ≈ 0.424 for a vertical emitter, 2/3 for one facing down, 0 for a slot that sends nothing down. A
    /// triangle at c = n·up sends ∫ (−ω·up)₊ (ω·n)₊ dω = (2/3)((π − γ)·cos γ + sin γ) with cos γ = −c (the
    /// integral of two clamped cosines whose axes are γ apart), out of the π·(1 − c)/2 of its downward
    /// cosine-weighted emission.
    pub sky: Vec<f64>,
}

/// [`HorizonGeometry`] of `slots` emitter slots, in one pass over their triangles given as (slot, area,
/// front-face normal); triangles of other slots are skipped.
#[must_use]
pub fn horizon_geometry(up: Vec3, slots: usize, triangles: impl Iterator<Item = (u32, f64, Vec3)>) -> HorizonGeometry {
    let (mut area, mut upward) = (vec![0.0f64; slots], vec![0.0f64; slots]);
    let (mut moment, mut down) = (vec![0.0f64; slots], vec![0.0f64; slots]);
    for (slot, a, n) in triangles {
        let s = slot as usize;
        if s >= slots {
            continue;
        }
        let c = f64::from(n.dot(up));
        area[s] += a;
        upward[s] += a * (1.0 + c) / 2.0;
        let cos_g = (-c).clamp(-1.0, 1.0);
        let g = cos_g.acos();
        moment[s] += a * (2.0 / 3.0) * ((std::f64::consts::PI - g) * cos_g + g.sin());
        down[s] += a * std::f64::consts::PI * (1.0 + cos_g) / 2.0;
    }
    HorizonGeometry {
        upward: area.iter().zip(&upward).map(|(&a, &u)| if a > 0.0 { (u / a).clamp(0.0, 1.0) } else { 0.0 }).collect(),
        // 1e-12 of π per unit area: a slot whose downward half is that small sends no sky worth a mean.
        sky: moment.iter().zip(&down).map(|(&m, &d)| if d > 1e-12 { (m / d).clamp(0.0, 1.0) } else { 0.0 }).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form against a Monte Carlo estimate of the mean elevation sine over the downward
    /// cosine-weighted directions, for normals from facing down to facing up.
    #[test]
    fn sky_elevation_means_match_a_monte_carlo_estimate() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for &c in &[-1.0f64, -0.7, -0.2, 0.0, 0.3, 0.8] {
            let n = glam::DVec3::new((1.0 - c * c).sqrt(), 0.0, c);
            let (mut sum, mut count) = (0.0, 0u32);
            for _ in 0..400_000 {
                // Cosine-weighted direction about n.
                let (r, phi) = (next().sqrt(), 2.0 * std::f64::consts::PI * next());
                let (t1, t2) = {
                    let t1 = glam::DVec3::Y.cross(n).normalize();
                    (t1, n.cross(t1))
                };
                let w = (r * phi.cos()) * t1 + (r * phi.sin()) * t2 + (1.0 - r * r).max(0.0).sqrt() * n;
                if w.z < 0.0 {
                    sum += -w.z;
                    count += 1;
                }
            }
            let want = sum / f64::from(count);
            let got = horizon_geometry(Vec3::Z, 1, std::iter::once((0, 2.0, n.as_vec3()))).sky[0];
            // 400 k draws: the estimate's standard error is below 1e-3.
            assert!((got - want).abs() < 4e-3, "c = {c}: {got} against {want}");
        }
        let vertical = horizon_geometry(Vec3::Z, 1, std::iter::once((0, 1.0, Vec3::X))).sky[0];
        assert!((vertical - 4.0 / (3.0 * std::f64::consts::PI)).abs() < 1e-6);
    }

    /// The guided search returns the plain binary search's index for every draw, on cdfs with zero-area
    /// triangles (flat runs), one dominant triangle, and u on and beside every bucket edge.
    #[test]
    fn the_guided_search_finds_what_the_binary_search_finds() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..200 {
            let n = 1 + case % 37;
            let areas: Vec<f64> = (0..n)
                .map(|i| match (case + i) % 5 {
                    0 => 0.0,
                    1 if case % 3 == 0 => 1e6,
                    _ => next(),
                })
                .collect();
            let total: f64 = areas.iter().sum();
            if total <= 0.0 {
                continue;
            }
            let mut acc = 0.0;
            let cdf: Vec<f64> = areas
                .iter()
                .map(|a| {
                    acc += a;
                    acc / total
                })
                .collect();
            let guide = guide_table(&cdf, |&c| c);
            let mut draws: Vec<f64> = (0..200).map(|_| next()).collect();
            for g in 0..=n {
                let edge = g as f64 / n as f64;
                draws.extend([edge, edge.next_down(), edge.next_up()]);
            }
            draws.extend(cdf.iter().flat_map(|&c| [c, c.next_down(), c.next_up()]));
            draws.extend([0.0, -1.0, 2.0, f64::NAN]);
            for u in draws {
                assert_eq!(
                    guided_partition_point(&cdf, |&c| c, &guide, u),
                    cdf.partition_point(|&c| c <= u),
                    "case {case}, u = {u}"
                );
            }
        }
    }
}
