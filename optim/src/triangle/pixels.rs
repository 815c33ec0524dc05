//! The pixels of the per-triangle fit: the valid pixels whose centre ray hits the mesh, at most a budget per
//! triangle (`triangle.pixels_per_triangle`), with the triangle and would-be child each hits, and whether its
//! whole footprint lies on that triangle.

use std::collections::BinaryHeap;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use tracer::PixelRef;

/// One pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriSample {
    pub pixel: PixelRef,
    pub target: Vec3,
    /// Triangle hit by the centre ray.
    pub tri: u32,
    /// Which child of a 4-way midpoint split of `tri` holds the centre: 0, 1, 2 = the corner child at
    /// vertex 0, 1, 2; 3 = the middle child.
    pub child: u8,
    /// The centre and the four corners of the pixel all hit `tri`: the pixel's value depends on `tri` alone.
    pub interior: bool,
    /// The centre and the four corners all hit triangles of `tri`'s object (its emitter slot, which is the
    /// object in the per-triangle scene, [`super::TriangleState::scene`]): the pixel sees that object alone, so
    /// its value scales with that object's base colour where the object is uniform. Every interior pixel is one.
    pub on_object: bool,
    /// Barycentric coordinates (u, v) of the centre's hit: the point is (1 − u − v)·p0 + u·p1 + v·p2.
    pub bary: Vec2,
}

/// The child of a 4-way split holding barycentrics (w0, w1, w2) = (1 − u − v, u, v): the corner child at
/// vertex i holds the points with w_i > ½.
#[must_use]
pub fn child_of(u: f32, v: f32) -> u8 {
    let w = 1.0 - u - v;
    if w > 0.5 {
        0
    } else if u > 0.5 {
        1
    } else if v > 0.5 {
        2
    } else {
        3
    }
}

/// The pixels of one round: at most a budget per triangle, and per triangle the pixel centres in its best
/// view (the split's footprint limit), counted before the budget.
#[derive(Debug, Clone, PartialEq)]
pub struct TriPixels {
    /// In (view, row, column) order.
    pub samples: Vec<TriSample>,
    /// Per triangle: the most pixel centres on it in any one view.
    pub best_view: Vec<u32>,
    /// Valid pixels that hit the mesh, before the budget.
    pub seen: u64,
}

/// Views whose pixels are traced at once: bounds the memory of the unbudgeted pixels in flight (a 1280×1024
/// view is 1.3 M pixels of 32 bytes) while keeping every core busy.
const VIEWS_IN_FLIGHT: usize = 8;

/// The valid pixels (mask ≠ 0, finite RGB) of all views that see the mesh, at most `per_triangle` of them per
/// triangle: a uniform sample of its pixels (the smallest ranks of a seeded uniform draw keyed by the pixel),
/// so a round's renders cost at most `per_triangle` × triangles pixels whatever the photos' resolution and
/// number. A triangle with fewer pixels keeps them all; with `per_triangle = usize::MAX` every pixel is kept.
#[must_use]
pub fn collect(
    scene: &tracer::Scene,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
    triangles: usize,
    per_triangle: usize,
    seed: u64,
) -> TriPixels {
    collect_budgets(scene, cameras, images, &vec![per_triangle; triangles], seed)
}

/// [`collect`] with a budget of its own per triangle (`budgets[t]`; the triangle count is `budgets.len()`).
/// A budget of 0 keeps no pixel of that triangle but still counts its best view.
#[must_use]
pub fn collect_budgets(
    scene: &tracer::Scene,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
    budgets: &[usize],
    seed: u64,
) -> TriPixels {
    let triangles = budgets.len();
    let rank = |p: PixelRef| {
        crate::streams::uniform(seed, crate::streams::draw::TRIANGLE_PIXELS, crate::streams::pixel_key(p), 0)
    };
    // Per triangle: a max-heap of its kept samples' ranks (the largest is the bar a new pixel must pass once
    // the triangle is full; ranks lie in [0, 1), where the bit patterns order like the values) with each
    // sample's slot in `kept`, and the running count in the current view.
    let mut heaps: Vec<BinaryHeap<(u64, usize)>> = vec![BinaryHeap::new(); triangles];
    let mut kept: Vec<TriSample> = Vec::new();
    let mut best_view = vec![0u32; triangles];
    let mut current: Vec<(u32, u32)> = vec![(u32::MAX, 0); triangles];
    let mut seen = 0u64;
    let views: Vec<usize> = (0..cameras.len().min(images.len())).collect();
    for chunk in views.chunks(VIEWS_IN_FLIGHT) {
        let per_view: Vec<Vec<TriSample>> =
            chunk.par_iter().map(|&view| view_pixels(scene, &cameras[view], &images[view], view)).collect();
        for s in per_view.into_iter().flatten() {
            let t = s.tri as usize;
            if t >= triangles {
                continue;
            }
            seen += 1;
            let c = &mut current[t];
            if c.0 == s.pixel.view {
                c.1 += 1;
            } else {
                *c = (s.pixel.view, 1);
            }
            best_view[t] = best_view[t].max(c.1);
            let r = rank(s.pixel).to_bits();
            let heap = &mut heaps[t];
            if heap.len() < budgets[t] {
                heap.push((r, kept.len()));
                kept.push(s);
            } else if let Some(mut top) = heap.peek_mut()
                && r < top.0
            {
                let slot = top.1;
                kept[slot] = s;
                *top = (r, slot);
            }
        }
    }
    let mut samples = kept;
    samples.sort_unstable_by_key(|s| (s.pixel.view, s.pixel.y, s.pixel.x));
    TriPixels { samples, best_view, seen }
}

/// One view's valid pixels whose centre ray hits the mesh, in (row, column) order.
fn view_pixels(
    scene: &tracer::Scene,
    cam: &tracer::Camera,
    img: &ingest::photo::LinearImage,
    view: usize,
) -> Vec<TriSample> {
    let mut out = Vec::new();
    for (x, y, t) in crate::fit::pixels::valid_pixels(cam, img) {
        let hit_at = |dx: f32, dy: f32| {
            let (o, d) = cam.ray(Vec2::new(x as f32 + dx, y as f32 + dy));
            scene.embree().intersect(o, d, 0.0, f32::INFINITY)
        };
        let Some(h) = hit_at(0.0, 0.0) else { continue };
        // The pixel's footprint is the box ±½ around its centre (the tracer's box filter). A corner off the
        // object settles both flags (an interior pixel is on the object), so the rest are not traced.
        let object = scene.emitter_of(h.prim_id);
        let (mut interior, mut on_object) = (true, true);
        for (dx, dy) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
            let corner = hit_at(dx, dy).map(|c| c.prim_id);
            interior &= corner == Some(h.prim_id);
            on_object &= corner.is_some_and(|p| scene.emitter_of(p) == object);
            if !on_object {
                break;
            }
        }
        out.push(TriSample {
            pixel: PixelRef { view: view as u32, x, y },
            target: t,
            tri: h.prim_id,
            child: child_of(h.u, h.v),
            interior,
            on_object,
            bary: Vec2::new(h.u, h.v),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn children_partition_the_triangle_like_the_midpoint_split() {
        assert_eq!(child_of(0.1, 0.1), 0);
        assert_eq!(child_of(0.8, 0.1), 1);
        assert_eq!(child_of(0.1, 0.8), 2);
        assert_eq!(child_of(0.3, 0.3), 3);
        assert_eq!(child_of(0.45, 0.45), 3);
    }
}
