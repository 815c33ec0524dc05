//! The pixels of the per-triangle fit: every valid pixel whose centre ray hits the mesh, with the triangle
//! and would-be child it hits, and whether its whole footprint lies on that triangle.

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

/// All valid pixels (mask ≠ 0, finite RGB) of all views that see the mesh, in (view, row, column) order.
#[must_use]
pub fn collect(
    scene: &tracer::Scene,
    cameras: &[tracer::Camera],
    images: &[ingest::photo::LinearImage],
) -> Vec<TriSample> {
    let per_view: Vec<Vec<TriSample>> = cameras
        .par_iter()
        .zip(images.par_iter())
        .enumerate()
        .map(|(view, (cam, img))| {
            let mut out = Vec::new();
            for (x, y, t) in crate::fit::pixels::valid_pixels(cam, img) {
                let hit_at = |dx: f32, dy: f32| {
                    let (o, d) = cam.ray(Vec2::new(x as f32 + dx, y as f32 + dy));
                    scene.embree().intersect(o, d, 0.0, f32::INFINITY)
                };
                let Some(h) = hit_at(0.0, 0.0) else { continue };
                // The pixel's footprint is the box ±½ around its centre (the tracer's box filter).
                let interior = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
                    .iter()
                    .all(|&(dx, dy)| hit_at(dx, dy).is_some_and(|c| c.prim_id == h.prim_id));
                out.push(TriSample {
                    pixel: PixelRef { view: view as u32, x, y },
                    target: t,
                    tri: h.prim_id,
                    child: child_of(h.u, h.v),
                    interior,
                });
            }
            out
        })
        .collect();
    per_view.into_iter().flatten().collect()
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
