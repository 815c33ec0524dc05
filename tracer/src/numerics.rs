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
