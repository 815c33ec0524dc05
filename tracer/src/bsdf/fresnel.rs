//! Schlick's Fresnel approximation with the Disney F0 and a grazing reflectance that vanishes with F0.
//!
//! Per colour channel k:
//!
//! ```text
//! F0_k  = (1 − metallic)·0.08·specular + metallic·base_k      (Disney: lerp(0.08·specular, base, metallic))
//! F90_k = min(1, 50·F0_k)
//! F_k(cos) = F0_k + (F90_k − F0_k)·(1 − cos)⁵
//! ```
//!
//! Schlick's original has F90 = 1. We use F90 = min(1, 50·F0) (Filament / UE4's "specular occlusion" rule,
//! threshold F0 = 0.02 because no real material reflects less than 2 % at normal incidence): identical to
//! Schlick for every physical F0 ≥ 0.02, and F ≡ 0 when F0 = 0, so that specular = metallic = 0 is exactly
//! Lambert (with F90 = 1 a surface of refractive index 1 would still mirror grazing light, which the exact
//! Fresnel equations deny). The min() has a kink at F0 = 0.02; `schlick` returns the derivative of the branch
//! taken (the right derivative at the kink point itself).

use super::real::{Real, pow5};

/// Dielectric F0 per unit `specular` (Disney: specular = 0.5 ↦ F0 = 0.04, the reflectance of n ≈ 1.5).
pub(crate) const DIELECTRIC_F0_SCALE: f64 = 0.08;

/// F90 / F0 below the kink: F90 reaches 1 at F0 = 1/50 = 0.02, the lowest normal-incidence reflectance of
/// real materials (water ≈ 0.02), after Filament.
pub(crate) const F90_PER_F0: f64 = 50.0;

/// F0 = lerp(0.08·specular, base, metallic) for one channel, and its partial derivatives
/// (∂/∂base, ∂/∂metallic, ∂/∂specular).
#[inline]
#[must_use]
pub(crate) fn f0<T: Real>(base: T, metallic: T, specular: T) -> (T, [T; 3]) {
    let k = T::lit(DIELECTRIC_F0_SCALE);
    let one = T::lit(1.0);
    let f0 = (one - metallic) * k * specular + metallic * base;
    (f0, [metallic, base - k * specular, k * (one - metallic)])
}

/// The Schlick weight of a cosine x: w = (1 − x)⁵ and its complement 1 − w = x·(5 − 10x + 10x² − 5x³ + x⁴),
/// the latter by Horner's rule so that it keeps full relative precision at grazing angles (x → 0), where
/// 1 − (1 − x)⁵ ≈ 5x would lose all digits to cancellation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SchlickWeight<T> {
    pub w: T,
    pub one_minus_w: T,
}

#[inline]
#[must_use]
pub(crate) fn schlick_weight<T: Real>(x: T) -> SchlickWeight<T> {
    let l = |c: f64| T::lit(c);
    let poly = l(5.0) + x * (l(-10.0) + x * (l(10.0) + x * (l(-5.0) + x)));
    SchlickWeight { w: pow5(T::lit(1.0) - x), one_minus_w: x * poly }
}

/// Schlick's F for a given F0, its complement 1 − F, and ∂F/∂F0 (= −∂(1 − F)/∂F0).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fresnel<T> {
    pub f: T,
    /// 1 − F, written as (1 − F0)(1 − w) + (1 − F90)·w (non-negative terms, accurate where F → 1) when
    /// F > 1/2, and as 1 − F otherwise (no cancellation there, and exactly 1 when F = 0, which keeps
    /// metallic = specular = 0 exactly Lambert). The two forms agree to a few ulps at the switch.
    pub one_minus_f: T,
    pub df_df0: T,
}

/// F = F0 + (F90 − F0)·w with F90 = min(1, 50·F0), for the weight `sw` of the cosine.
#[inline]
#[must_use]
pub(crate) fn schlick<T: Real>(f0: T, sw: SchlickWeight<T>) -> Fresnel<T> {
    let one = T::lit(1.0);
    let slope = T::lit(F90_PER_F0);
    let (f90, df90) = if f0 * slope < one { (f0 * slope, slope) } else { (one, T::lit(0.0)) };
    let f = f0 + (f90 - f0) * sw.w;
    let one_minus_f = if f > T::lit(0.5) { (one - f0) * sw.one_minus_w + (one - f90) * sw.w } else { one - f };
    Fresnel { f, one_minus_f, df_df0: sw.one_minus_w + df90 * sw.w }
}
