//! GGX (Trowbridge–Reitz) microfacet lobe: distribution D, height-correlated Smith masking-shadowing G2, and
//! visible-normal (VNDF) sampling (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)).
//!
//! Isotropic, local frame (z = normal), `wo` and `wi` above the surface (cos θo = wo.z > 0, cos θi = wi.z > 0),
//! h = (wo + wi)/|wo + wi|, α = max(ε, roughness²) (see [`ALPHA_MIN`]), a = α². The specular lobe is
//!
//! ```text
//! f_s = D(h)·G2(wo, wi)·F(wo·h) / (4 cosθo cosθi) = D(h)·V(wo, wi)·F(wo·h)
//! D(h)  = a / (π (a cos²θh + sin²θh)²)                         (= 1/(π α² cos⁴θh (1 + tan²θh/α²)²))
//! Λ(w)  = (√(1 + a tan²θ) − 1)/2 = (S(w) − cosθ)/(2 cosθ),     S(w) = √(cos²θ + a sin²θ)
//! G1(w) = 1/(1 + Λ(w)) = 2 cosθ / (cosθ + S(w))
//! G2    = 1/(1 + Λ(wo) + Λ(wi))                                 (height-correlated Smith, Heitz 2014 eq. 99)
//! V     = G2/(4 cosθo cosθi) = 1 / (2 (cosθi·S(wo) + cosθo·S(wi)))
//! ```
//!
//! Every quantity is formed without dividing by a cosine and without `1 − cos²` cancellation (sin²θ is taken
//! from the x, y components), so D and V stay accurate for α = ε and cosθ → 0. VNDF sampling draws h with
//! density D_wo(h) = G1(wo)·(wo·h)⁺·D(h)/cosθo and reflects wo about it; with dωi/dh = 1/(4 wo·h) the
//! solid-angle density of wi is
//!
//! ```text
//! p_s(wi | wo) = G1(wo)·D(h) / (4 cosθo) = D(h) / (2 (cosθo + S(wo)))
//! ```
//!
//! Reflections that land below the horizon are lost (`sample` fails), so ∫ p_s dωi ≤ 1.

use glam::{Vec2, Vec3};

use super::real::Real;

/// ε in α = max(ε, roughness²). pbrt-v4 uses the same 1e-4 (below it the anisotropic `e` term of D blows up).
/// Here D is written as a/(π k²) with k = a cos²θh + sin²θh ≥ a, so at α = ε: D ≤ 1/(π ε²) ≈ 3.2e7,
/// ∂D/∂a ≤ 1/(π a²) ≈ 3.2e15 and k³ ≥ 1e-24, all normal f32 numbers; the f32 sampler still resolves a lobe
/// of angular width 1e-4 rad (direction ulp ≈ 6e-8). A smaller ε would push ∂D/∂a past 1e23 (α = 1e-6) and
/// make the f32 tests of the gradient meaningless; roughness < 0.01 all map to this mirror-like lobe, with
/// ∂α/∂roughness = 0 there (the clamp is active, so the derivative is exactly zero, not 2·roughness).
pub const ALPHA_MIN: f32 = 1e-4;

/// Cosines below this (of wo or wi) switch the specular lobe off. The lobe is bounded by
/// f_s ≤ D_max·V_max ≤ 1/(π ε²) · 1/(4 ε cosθ) ≈ 8e10/cosθ and its a-derivative by ≈ 8e18/cosθ (before the
/// chain factor ∂a/∂roughness); with cosθ ≥ 1e-12 both stay below 1e31, finite in f32 even after a few
/// products in the integrator. The lost solid angle (a band of width 1e-12 rad at the horizon) is negligible.
pub const SPECULAR_MIN_COS: f32 = 1e-12;

/// α = max(ε, roughness²) and ∂α/∂roughness (0 where the clamp is active, i.e. roughness² ≤ ε).
#[inline]
#[must_use]
pub(crate) fn alpha<T: Real>(roughness: T) -> (T, T) {
    let eps = T::lit(f64::from(ALPHA_MIN));
    let r2 = roughness * roughness;
    if r2 > eps { (r2, T::lit(2.0) * roughness) } else { (eps, T::lit(0.0)) }
}

/// The half vector's angles, from wo + wi without normalising it first.
#[derive(Debug, Clone, Copy)]
pub(crate) struct HalfAngles<T> {
    /// cos²θh
    pub cos2: T,
    /// sin²θh, from the tangential components (no 1 − cos² cancellation near the normal)
    pub sin2: T,
    /// wo·h = wi·h = |wo + wi|/2 for unit wo, wi, clamped to ≤ 1
    pub cos_d: T,
}

/// Half-vector angles for wo, wi both above the surface (then wo + wi has z > 0, never the zero vector).
#[inline]
#[must_use]
pub(crate) fn half_angles<T: Real>(wo: [T; 3], wi: [T; 3]) -> HalfAngles<T> {
    let h = [wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]];
    let t2 = h[0] * h[0] + h[1] * h[1];
    let z2 = h[2] * h[2];
    let l2 = t2 + z2;
    HalfAngles { cos2: z2 / l2, sin2: t2 / l2, cos_d: (T::lit(0.5) * l2.safe_sqrt()).min_r(T::lit(1.0)) }
}

/// D(h) = a / (π (a cos²θh + sin²θh)²) and ∂D/∂a = (sin²θh − a cos²θh) / (π k³), k = a cos²θh + sin²θh.
#[inline]
#[must_use]
pub(crate) fn ndf<T: Real>(a: T, h: &HalfAngles<T>) -> (T, T) {
    let inv_pi = T::lit(std::f64::consts::FRAC_1_PI);
    let k = a * h.cos2 + h.sin2;
    let pk2 = k * k;
    (a * inv_pi / pk2, (h.sin2 - a * h.cos2) * inv_pi / (pk2 * k))
}

/// S(w) = √(cos²θ + a sin²θ), with sin²θ = x² + y².
#[inline]
#[must_use]
pub(crate) fn smith_s<T: Real>(a: T, w: [T; 3]) -> T {
    (w[2] * w[2] + a * (w[0] * w[0] + w[1] * w[1])).safe_sqrt()
}

/// V = G2/(4 cosθo cosθi) = 1/(2 (cosθi S(wo) + cosθo S(wi))) and ∂V/∂a, for wo, wi above the surface,
/// and S(wo) (which the sampling pdf shares). ∂S/∂a = sin²θ/(2S), so
/// ∂V/∂a = −V² (cosθi sin²θo / S(wo) + cosθo sin²θi / S(wi)).
#[inline]
#[must_use]
pub(crate) fn smith_v<T: Real>(a: T, wo: [T; 3], wi: [T; 3]) -> (T, T, T) {
    let (so, si) = (smith_s(a, wo), smith_s(a, wi));
    let v = T::lit(0.5) / (wi[2] * so + wo[2] * si);
    let so_t2 = wo[0] * wo[0] + wo[1] * wo[1];
    let si_t2 = wi[0] * wi[0] + wi[1] * wi[1];
    (v, -v * v * (wi[2] * so_t2 / so + wo[2] * si_t2 / si), so)
}

/// p_s from the D(h) and S(wo) of the same (α, wo, wi): bit-identical to [`pdf_reflect`], for callers that
/// already evaluated both.
#[inline]
#[must_use]
pub(crate) fn pdf_reflect_from(d: f32, wo_z: f32, s_o: f32) -> f32 {
    d / (2.0 * (wo_z + s_o))
}

/// Solid-angle density of a VNDF-sampled reflection: p_s(wi | wo) = D(h) / (2 (cosθo + S(wo))).
#[inline]
#[must_use]
pub(crate) fn pdf_reflect(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    let a = alpha * alpha;
    let (wo, wi) = (wo.to_array(), wi.to_array());
    let (d, _) = ndf(a, &half_angles(wo, wi));
    pdf_reflect_from(d, wo[2], smith_s(a, wo))
}

/// Draws a microfacet normal from the distribution of normals visible from `wo` (wo.z > 0), Heitz 2018
/// listing 1 with α_x = α_y = α. None only if the result degenerates to the zero vector.
#[must_use]
pub(crate) fn sample_vndf(alpha: f32, wo: Vec3, u: Vec2) -> Option<Vec3> {
    // Section 3.2: stretch the view vector to the hemisphere configuration (α = 1).
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize_or_zero();
    if vh == Vec3::ZERO {
        return None;
    }
    // Section 4.1: orthonormal basis; at normal incidence any tangent will do.
    let t1 = Vec3::new(-vh.y, vh.x, 0.0).normalize_or(Vec3::X);
    let t2 = vh.cross(t1);
    // Section 4.2: parameterise the projected area (a disk, half of it warped towards vh).
    let r = crate::numerics::safe_sqrt(u.x);
    let phi = std::f32::consts::TAU * u.y;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * crate::numerics::safe_sqrt(1.0 - p1 * p1) + s * r * phi.sin();
    // Section 4.3: reproject onto the hemisphere.
    let nh = p1 * t1 + p2 * t2 + crate::numerics::safe_sqrt(1.0 - p1 * p1 - p2 * p2) * vh;
    // Section 3.4: unstretch back to the ellipsoid configuration.
    let ne = Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize_or_zero();
    (ne != Vec3::ZERO).then_some(ne)
}
