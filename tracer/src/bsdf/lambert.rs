//! Lambert diffuse lobe and its cosine-weighted sampling (Malley's method).
//!
//! ```text
//! f_d = ρ/π,   p_d(wi) = cosθi/π
//! ```

use glam::{Vec2, Vec3};

use crate::numerics::safe_sqrt;

/// Cosine-weighted direction on the upper hemisphere from u ∈ [0,1)²: a uniform disk point lifted to the
/// hemisphere. wi.z = √(1 − u.x) > 0 for u.x < 1.
#[inline]
#[must_use]
pub(crate) fn sample_cosine(u: Vec2) -> Vec3 {
    let r = safe_sqrt(u.x);
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), safe_sqrt(1.0 - u.x))
}

/// Solid-angle density of [`sample_cosine`]: cosθi/π above the surface, 0 below.
#[inline]
#[must_use]
pub(crate) fn pdf_cosine(wi: Vec3) -> f32 {
    if wi.z > 0.0 { wi.z * std::f32::consts::FRAC_1_PI } else { 0.0 }
}
