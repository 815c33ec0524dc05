//! The one home of numerically safe helpers. Every threshold carries the reason for its value.

use glam::Vec3;

/// `sqrt(max(0, x))`: arguments that are negative only by round-off (e.g. `1 - cos²θ`) give 0, not NaN.
#[inline]
#[must_use]
pub fn safe_sqrt(x: f32) -> f32 {
    debug_assert!(x > -1e-3 || x.is_nan(), "safe_sqrt of clearly negative {x}");
    x.max(0.0).sqrt()
}

/// `acos(clamp(x, -1, 1))`: dot products of unit vectors can leave [-1, 1] by an ulp.
#[inline]
#[must_use]
pub fn safe_acos(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).acos()
}

/// `v / |v|`, or `None` when `|v|` is zero, subnormal or not finite (glam's `try_normalize` semantics).
#[inline]
#[must_use]
pub fn try_normalize(v: Vec3) -> Option<Vec3> {
    v.try_normalize()
}

/// `v / |v|`, or `fallback` when `v` cannot be normalised (degenerate triangle normals, zero directions).
#[inline]
#[must_use]
pub fn normalize_or(v: Vec3, fallback: Vec3) -> Vec3 {
    v.try_normalize().unwrap_or(fallback)
}

/// An orthonormal frame whose `n` is a unit normal; local coordinates have z along `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Branchless construction of Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017).
    /// `n` must be unit length; the result is continuous everywhere except across n.z = 0 sign flips.
    #[inline]
    #[must_use]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// World → local (z = normal).
    #[inline]
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local → world.
    #[inline]
    #[must_use]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Relative size of the floating-point error of a surface point computed by barycentric interpolation of its
/// triangle's vertices. pbrt-v4 (§6.8.6) bounds that error by γ₇·Σ|bᵢpᵢ| ≈ 4.2e-7·|p|; we use 2⁻¹⁸ ≈ 3.8e-6,
/// about 9× the bound, to also cover the error of the normal and of the vertex transforms done by callers.
const SPAWN_RELATIVE_ERROR: f32 = 1.0 / 262_144.0;

/// Absolute floor of the spawn offset: points at (or very near) the world origin have a tiny relative error
/// bound but Embree's own watertight test still has an absolute error; 1e-7 scene units (0.1 µm for scenes in
/// metres) is far below any geometric feature.
const SPAWN_ABSOLUTE_ERROR: f32 = 1e-7;

/// Moves a point `p` on a surface with unit geometric normal `ng` off the surface, to the
/// side `dir` points to, by more than the floating-point error of `p`, so that a ray spawned there with
/// `tnear = 0` cannot re-hit the surface it starts on (pbrt's `OffsetRayOrigin`). The only place in the
/// tracer that decides ray epsilons.
#[inline]
#[must_use]
pub fn offset_ray_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    // 1e-3: unit vectors normalised in f32 are within a few ulp of length 1; anything further is a caller bug.
    debug_assert!((ng.length_squared() - 1.0).abs() < 1e-3, "offset_ray_origin needs a unit normal, got {ng}");
    // The error box of p is |p|·SPAWN_RELATIVE_ERROR (+ floor) per component; its support along n is the
    // offset. That is ≥ 2⁻¹⁸·|p| ≈ 32 ulp of p's largest component, so rounding the sum below (≤ ½ ulp per
    // component) cannot undo it; no next-float stepping is needed.
    let err = p.abs() * SPAWN_RELATIVE_ERROR + Vec3::splat(SPAWN_ABSOLUTE_ERROR);
    let d = ng.abs().dot(err);
    let d = if dir.dot(ng) < 0.0 { -d } else { d };
    p + ng * d
}

/// Power heuristic (β = 2) weight of a strategy with pdf `a` against one with pdf `b` (Veach 1997).
/// An infinite `a` (a delta-like strategy) gets weight 1; two zero pdfs give 0.
#[inline]
#[must_use]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    if a.is_infinite() {
        return 1.0;
    }
    if a.is_nan() || a <= 0.0 {
        return 0.0;
    }
    // Written as 1 / (1 + (b/a)²) so that tiny pdfs do not underflow when squared.
    let r = b / a;
    1.0 / (1.0 + r * r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal_for_many_normals() {
        for i in 0..1000 {
            let z = -1.0 + 2.0 * (i as f32 + 0.5) / 1000.0;
            let phi = i as f32 * 2.399_963;
            let r = safe_sqrt(1.0 - z * z);
            let n = Vec3::new(r * phi.cos(), r * phi.sin(), z).normalize();
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            assert!((f.s.cross(f.t) - n).length() < 1e-4, "right-handed");
            let v = Vec3::new(0.3, -0.2, 0.9);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn offset_moves_to_the_requested_side_and_scales_with_p() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        for p in [Vec3::ZERO, Vec3::new(1000.0, -1000.0, 1000.0), Vec3::new(0.1, 0.2, 0.3)] {
            let up = offset_ray_origin(p, n, Vec3::new(0.1, 0.0, 1.0));
            let down = offset_ray_origin(p, n, Vec3::new(0.1, 0.0, -1.0));
            assert!(up.z > p.z && down.z < p.z, "{p} {up} {down}");
            assert!((up.z - p.z) >= p.abs().max_element() * SPAWN_RELATIVE_ERROR);
            assert_eq!(up.x, p.x);
        }
    }

    #[test]
    fn power_heuristic_is_a_partition_of_unity() {
        for (a, b) in [(1.0, 2.0), (0.0, 3.0), (1e-30, 1e-30), (5.0, 0.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
    }
}
