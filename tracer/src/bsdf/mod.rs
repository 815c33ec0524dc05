//! Disney-style BRDF with the parameters the paper optimises (base colour, roughness, metallic, specular):
//! a Fresnel-coupled Lambert lobe plus a GGX microfacet lobe. All directions are in the local shading frame
//! (z = shading normal), `wo` towards the viewer/previous vertex, `wi` towards the light/next vertex, both
//! unit length. `eval` returns f_r without the cosine factor; both directions must be above the surface
//! (z > 0), otherwise f_r = 0 and the pdf is 0.
//!
//! # Model
//!
//! Per colour channel k, with c = base_color, m = metallic, s = specular, r = roughness:
//!
//! ```text
//! f_k(wo, wi) = (1 − m)·c_k/π · (1 − F_k(cosθo))·(1 − F_k(cosθi))      diffuse   (lambert.rs, fresnel.rs)
//!             + D(h)·G2(wo, wi)·F_k(wo·h) / (4 cosθo cosθi)            specular  (ggx.rs)
//! F0_k = (1 − m)·0.08·s + m·c_k,   F_k(x) = F0_k + (min(1, 50·F0_k) − F0_k)·(1 − x)⁵     (fresnel.rs)
//! α = max(1e-4, r²),  D = GGX,  G2 = height-correlated Smith                              (ggx.rs)
//! ```
//!
//! Two deliberate departures from the purely additive `(1 − m)·c/π + D·G2·F/(4 cos cos)`:
//! - The diffuse lobe is weighted by (1 − F(cosθo))(1 − F(cosθi)) (symmetric, so reciprocity holds): light
//!   reflected by the specular interface is not also diffused. Without it a white (c = 1) dielectric reflects
//!   1 + F0 + … > 1 of the incident energy (≥ 8 % too much for specular = 1), failing the white-furnace test.
//!   The price: F at the macro-normal overestimates what a rough specular lobe reflects at grazing angles, so
//!   rough white dielectrics lose energy there (albedo 0.53 at cosθo = 0.1 and 0.23 at 1e-4 for roughness 0.5,
//!   specular 0.5; 0.91 at normal incidence), where Kelemen-style albedo tables would conserve it.
//! - F90 = min(1, 50·F0) instead of 1 (see fresnel.rs), so that metallic = specular = 0 ⇒ F ≡ 0 ⇒ f is
//!   exactly Lambert c/π (the [`Material::is_lambert`] fast path computes the same bits).
//!
//! # Sampling
//!
//! One-sample mixture of the two lobes: the specular lobe (VNDF, ggx.rs) is chosen with probability
//! P_s = lum(F(cosθo)) / (lum(F(cosθo)) + lum((1 − m)·c·(1 − F(cosθo)))) (an estimate of the lobes' albedos;
//! lum = Rec. 709 luminance), the cosine-weighted diffuse lobe otherwise, and `pdf` returns the mixture
//! P_s·p_s + (1 − P_s)·cosθi/π, so MIS weights computed from `pdf` are correct. P_s > 0 wherever the
//! specular lobe is non-zero and P_s < 1 wherever the diffuse lobe is non-zero.
//!
//! # Derivatives
//!
//! `eval_grad` differentiates the formulas above analytically (chain rule through F0, F90, α, D and V; the
//! terms are written out in `eval_generic`). ∂/∂roughness is 0 where α is clamped (roughness < 0.01). At the
//! kink of F90 (F0 = 0.02 exactly) the derivative of the F90 = 1 side is returned (the right derivative).
//! The formulas are generic over the float type (real.rs): the renderer runs them in f32, the tests also in
//! f64 as the finite-difference and round-off reference.

mod fresnel;
mod ggx;
mod lambert;
mod real;

#[cfg(test)]
mod tests;

use glam::{Vec2, Vec3};

pub use ggx::{ALPHA_MIN, SPECULAR_MIN_COS};
use real::Real;

/// Material parameters of one object or triangle. All four are differentiable (see [`MaterialGrad`]).
///
/// | name | range | meaning | flags |
/// |---|---|---|---|
/// | base_color | \[0, 1\]³ | diffuse albedo (dielectric) / F0 tint (metal) | differentiable |
/// | roughness | \[0, 1\] | perceptual roughness, α = max(1e-4, roughness²) | differentiable, ∂ = 0 below 0.01 |
/// | metallic | \[0, 1\] | blend dielectric → conductor | differentiable |
/// | specular | \[0, 1\] | dielectric F0 = 0.08·specular | differentiable, kink where F0 = 0.02 |
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    pub base_color: Vec3,
    pub roughness: f32,
    pub metallic: f32,
    pub specular: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material { base_color: Vec3::splat(0.5), roughness: 0.5, metallic: 0.0, specular: 0.0 }
    }
}

/// ∂f_r/∂θ for one (wo, wi). f_r is RGB and each colour channel of f_r depends only on the same channel of
/// base_color, so `d_base_color` is the diagonal of the Jacobian; the scalar parameters have one RGB column.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MaterialGrad {
    pub d_base_color: Vec3,
    pub d_roughness: Vec3,
    pub d_metallic: Vec3,
    pub d_specular: Vec3,
}

/// A direction sampled from the BRDF: `f` = f_r(wo, wi) (no cosine), `pdf` in solid angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
}

/// Rec. 709 luminance weights, used only to estimate the lobes' relative albedo for lobe selection.
const LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

impl Material {
    /// f_r(wo, wi), zero when either direction is below the surface.
    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return Vec3::ZERO;
        }
        if self.is_lambert() {
            // Bit-identical to the general formula at m = s = 0 (F ≡ 0 there, factors of exactly 1).
            return self.base_color * std::f32::consts::FRAC_1_PI;
        }
        Vec3::from_array(eval_generic::<f32, false>(&self.params(), wo.to_array(), wi.to_array()).0)
    }

    /// f_r and its derivatives with respect to every parameter. The value equals `eval`'s bit for bit.
    #[must_use]
    pub fn eval_grad(&self, wo: Vec3, wi: Vec3) -> (Vec3, MaterialGrad) {
        let (f, g) = eval_generic::<f32, true>(&self.params(), wo.to_array(), wi.to_array());
        (Vec3::from_array(f), material_grad(&g))
    }

    /// Solid-angle pdf of `sample` producing `wi`: P_s·p_s(wi) + (1 − P_s)·cosθi/π.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return 0.0;
        }
        self.at(wo).pdf(wi)
    }

    /// Samples wi given two uniform numbers for the direction and one for the lobe choice. None when the
    /// sampled direction is below the surface (mass the specular lobe loses at grazing angles) or wo is.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        if wo.z.is_nan() || wo.z <= 0.0 {
            return None;
        }
        self.at(wo).sample(u, u_lobe)
    }

    /// The material seen from a fixed `wo`: the terms that depend only on wo (per-channel F0 and F(cosθo),
    /// the lobe-selection probability) are computed once and shared by every evaluation, pdf and sample at
    /// that vertex. Every result is bit-identical to the corresponding [`Material`] method.
    #[inline]
    #[must_use]
    pub fn at(&self, wo: Vec3) -> MaterialAt<'_> {
        let params = self.params();
        // Pure Lambert skips the Fresnel terms (F ≡ 0); they are computed on demand for derivatives.
        let outgoing = (wo.z > 0.0 && !self.is_lambert()).then(|| outgoing_terms(&params, wo.z));
        let p_spec = match &outgoing {
            Some(o) => specular_probability_from(&params, o),
            None => 0.0,
        };
        MaterialAt { material: self, params, wo, outgoing, p_spec }
    }

    /// True when the material is pure Lambert (metallic = specular = 0): the integrator's fast path.
    #[inline]
    #[must_use]
    pub fn is_lambert(&self) -> bool {
        self.metallic == 0.0 && self.specular == 0.0
    }

    /// P_s, the probability `sample` picks the specular lobe for this wo (wo.z > 0): the Fresnel-weighted
    /// specular albedo estimate over the sum of both lobes' estimates (see the module doc).
    #[must_use]
    pub fn specular_probability(&self, wo: Vec3) -> f32 {
        let params = self.params();
        specular_probability_from(&params, &outgoing_terms(&params, wo.z))
    }

    #[inline]
    fn params(&self) -> Params<f32> {
        Params {
            base: self.base_color.to_array(),
            roughness: self.roughness,
            metallic: self.metallic,
            specular: self.specular,
        }
    }
}

/// P_s from the outgoing terms (see [`Material::specular_probability`]).
#[inline]
fn specular_probability_from(p: &Params<f32>, o: &OutgoingTerms<f32>) -> f32 {
    let mut spec = Vec3::ZERO;
    let mut diffuse = Vec3::ZERO;
    for k in 0..3 {
        let fr = o.fr_o[k];
        spec[k] = fr.f.max(0.0);
        diffuse[k] = ((1.0 - p.metallic) * p.base[k] * fr.one_minus_f).max(0.0);
    }
    let (ws, wd) = (spec.dot(LUMINANCE), diffuse.dot(LUMINANCE));
    if ws > 0.0 { ws / (ws + wd) } else { 0.0 }
}

#[inline]
fn material_grad(g: &Grad<f32>) -> MaterialGrad {
    MaterialGrad {
        d_base_color: Vec3::from_array(g.d_base),
        d_roughness: Vec3::from_array(g.d_roughness),
        d_metallic: Vec3::from_array(g.d_metallic),
        d_specular: Vec3::from_array(g.d_specular),
    }
}

/// A [`Material`] at a fixed outgoing direction wo (see [`Material::at`]).
#[derive(Debug, Clone, Copy)]
pub struct MaterialAt<'a> {
    material: &'a Material,
    params: Params<f32>,
    wo: Vec3,
    /// Present when wo.z > 0 and the material is not pure Lambert.
    outgoing: Option<OutgoingTerms<f32>>,
    p_spec: f32,
}

impl MaterialAt<'_> {
    /// P_s, the probability of sampling the specular lobe (0 for pure Lambert or wo below the surface).
    #[inline]
    #[must_use]
    pub fn specular_probability(&self) -> f32 {
        self.p_spec
    }

    /// [`Material::eval`].
    #[inline]
    #[must_use]
    pub fn eval(&self, wi: Vec3) -> Vec3 {
        self.eval_pdf(wi).0
    }

    /// [`Material::pdf`].
    #[inline]
    #[must_use]
    pub fn pdf(&self, wi: Vec3) -> f32 {
        let wo = self.wo;
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return 0.0;
        }
        let p_diffuse = lambert::pdf_cosine(wi);
        if self.p_spec > 0.0 {
            let (alpha, _) = ggx::alpha(self.material.roughness);
            self.p_spec * ggx::pdf_reflect(alpha, wo, wi) + (1.0 - self.p_spec) * p_diffuse
        } else {
            p_diffuse
        }
    }

    /// ([`Material::eval`], [`Material::pdf`]) sharing the GGX half-vector, D and S(wo) between the two.
    #[inline]
    #[must_use]
    pub fn eval_pdf(&self, wi: Vec3) -> (Vec3, f32) {
        let wo = self.wo;
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return (Vec3::ZERO, 0.0);
        }
        let p_diffuse = lambert::pdf_cosine(wi);
        let Some(o) = &self.outgoing else {
            // Pure Lambert: as in `Material::eval`, and P_s = 0.
            return (self.material.base_color * std::f32::consts::FRAC_1_PI, p_diffuse);
        };
        let (f, _, terms) = eval_terms::<f32, false>(&self.params, o, wo.to_array(), wi.to_array());
        (Vec3::from_array(f), self.mixture_pdf(terms, wi, p_diffuse))
    }

    /// ([`Material::eval_grad`], [`Material::pdf`]) sharing the GGX terms like [`MaterialAt::eval_pdf`].
    #[inline]
    #[must_use]
    pub fn eval_grad_pdf(&self, wi: Vec3) -> (Vec3, MaterialGrad, f32) {
        let wo = self.wo;
        if !(wo.z > 0.0 && wi.z > 0.0) {
            // eval_generic's zeros below the surface.
            return (Vec3::ZERO, MaterialGrad::default(), 0.0);
        }
        let o = match &self.outgoing {
            Some(o) => *o,
            None => outgoing_terms(&self.params, wo.z),
        };
        let (f, g, terms) = eval_terms::<f32, true>(&self.params, &o, wo.to_array(), wi.to_array());
        (Vec3::from_array(f), material_grad(&g), self.mixture_pdf(terms, wi, lambert::pdf_cosine(wi)))
    }

    /// P_s·p_s + (1 − P_s)·p_d for wo, wi above the surface, p_s from the terms of an evaluation when it
    /// computed them (bit-identical to `ggx::pdf_reflect`).
    #[inline]
    fn mixture_pdf(&self, terms: Option<SpecularTerms<f32>>, wi: Vec3, p_diffuse: f32) -> f32 {
        if self.p_spec > 0.0 {
            let p_s = match terms {
                Some(t) => ggx::pdf_reflect_from(t.d, self.wo.z, t.s_o),
                None => ggx::pdf_reflect(ggx::alpha(self.material.roughness).0, self.wo, wi),
            };
            self.p_spec * p_s + (1.0 - self.p_spec) * p_diffuse
        } else {
            p_diffuse
        }
    }

    /// [`Material::sample`].
    #[inline]
    #[must_use]
    pub fn sample(&self, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        let wi = self.sample_wi(u, u_lobe)?;
        let (f, pdf) = self.eval_pdf(wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BsdfSample { wi, f, pdf })
    }

    /// [`Material::sample`] with f evaluated together with its derivatives: (sample, ∂f).
    #[inline]
    #[must_use]
    pub fn sample_grad(&self, u: Vec2, u_lobe: f32) -> Option<(BsdfSample, MaterialGrad)> {
        let wi = self.sample_wi(u, u_lobe)?;
        let (f, grad, pdf) = self.eval_grad_pdf(wi);
        (pdf > 0.0 && pdf.is_finite()).then_some((BsdfSample { wi, f, pdf }, grad))
    }

    /// The sampled direction (before its pdf is checked): VNDF reflection with probability P_s, else
    /// cosine-weighted.
    #[inline]
    fn sample_wi(&self, u: Vec2, u_lobe: f32) -> Option<Vec3> {
        let wo = self.wo;
        if wo.z.is_nan() || wo.z <= 0.0 {
            return None;
        }
        if !self.material.is_lambert() && u_lobe < self.p_spec {
            let (alpha, _) = ggx::alpha(self.material.roughness);
            let h = ggx::sample_vndf(alpha, wo, u)?;
            Some((2.0 * wo.dot(h) * h - wo).normalize_or_zero())
        } else {
            Some(lambert::sample_cosine(u))
        }
    }
}

/// Material parameters over a generic real: the renderer's f32 or the tests' f64 reference.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Params<T> {
    pub base: [T; 3],
    pub roughness: T,
    pub metallic: T,
    pub specular: T,
}

/// [`MaterialGrad`] over a generic real.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grad<T> {
    pub d_base: [T; 3],
    pub d_roughness: [T; 3],
    pub d_metallic: [T; 3],
    pub d_specular: [T; 3],
}

/// f_r (module doc formula) and, when `GRAD`, its derivatives (zeros otherwise). Per channel, with
/// k_d = (1 − m)c/π, E_o = 1 − F(cosθo), E_i = 1 − F(cosθi) (computed without cancellation, see
/// fresnel::schlick), F_h = F(wo·h), DV = D·V:
///
/// ```text
/// f          = k_d E_o E_i + DV F_h
/// ∂f/∂F0     = −k_d (F_o' E_i + E_o F_i') + DV F_h'              (F' = ∂F/∂F0 from fresnel::schlick)
/// ∂f/∂c      = (1 − m)/π E_o E_i + ∂f/∂F0 · m
/// ∂f/∂m      = −c/π E_o E_i      + ∂f/∂F0 · (c − 0.08 s)
/// ∂f/∂s      =                     ∂f/∂F0 · 0.08 (1 − m)
/// ∂f/∂r      = (∂D/∂a V + D ∂V/∂a) F_h · ∂a/∂r,   ∂a/∂r = 2α ∂α/∂r   (0 when α is clamped)
/// ```
#[must_use]
pub(crate) fn eval_generic<T: Real, const GRAD: bool>(p: &Params<T>, wo: [T; 3], wi: [T; 3]) -> ([T; 3], Grad<T>) {
    let (f, g, _) = eval_terms::<T, GRAD>(p, &outgoing_terms(p, wo[2]), wo, wi);
    (f, g)
}

/// The per-channel terms of f_r that depend only on the material and cosθo: F0 with its partials
/// (∂/∂base, ∂/∂metallic, ∂/∂specular) and Schlick's F(cosθo).
#[derive(Debug, Clone, Copy)]
pub(crate) struct OutgoingTerms<T> {
    pub f0: [T; 3],
    pub df0: [[T; 3]; 3],
    pub fr_o: [fresnel::Fresnel<T>; 3],
}

#[inline]
#[must_use]
pub(crate) fn outgoing_terms<T: Real>(p: &Params<T>, cos_o: T) -> OutgoingTerms<T> {
    let w_o = fresnel::schlick_weight(cos_o);
    let f0 = [0, 1, 2].map(|k| fresnel::f0(p.base[k], p.metallic, p.specular));
    OutgoingTerms { f0: f0.map(|x| x.0), df0: f0.map(|x| x.1), fr_o: f0.map(|x| fresnel::schlick(x.0, w_o)) }
}

/// The GGX terms of one evaluation that the sampling pdf shares: D(h) and S(wo) (see ggx.rs).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SpecularTerms<T> {
    pub d: T,
    pub s_o: T,
}

/// [`eval_generic`] given the [`outgoing_terms`] of (p, wo), also returning the D and S(wo) it computed
/// (None where the specular lobe is off: either direction below the surface or below [`SPECULAR_MIN_COS`]).
#[inline]
#[must_use]
pub(crate) fn eval_terms<T: Real, const GRAD: bool>(
    p: &Params<T>,
    o: &OutgoingTerms<T>,
    wo: [T; 3],
    wi: [T; 3],
) -> ([T; 3], Grad<T>, Option<SpecularTerms<T>>) {
    let zero = T::lit(0.0);
    let one = T::lit(1.0);
    let mut f = [zero; 3];
    let mut g = Grad { d_base: [zero; 3], d_roughness: [zero; 3], d_metallic: [zero; 3], d_specular: [zero; 3] };
    let (cos_o, cos_i) = (wo[2], wi[2]);
    if !(cos_o > zero && cos_i > zero) {
        return (f, g, None);
    }
    let inv_pi = T::lit(std::f64::consts::FRAC_1_PI);
    let w_i = fresnel::schlick_weight(cos_i);

    // Specular geometry, shared by the channels: DV = D·V, its a-derivative, the Schlick weight at wo·h.
    let min_cos = T::lit(f64::from(SPECULAR_MIN_COS));
    let mut terms = None;
    let (dv, d_dv_da, w_h, da_dr) = if cos_o >= min_cos && cos_i >= min_cos {
        let (alpha, dalpha_dr) = ggx::alpha(p.roughness);
        let a = alpha * alpha;
        let h = ggx::half_angles(wo, wi);
        let (d, dd_da) = ggx::ndf(a, &h);
        let (v, dv_da, s_o) = ggx::smith_v(a, wo, wi);
        terms = Some(SpecularTerms { d, s_o });
        (d * v, dd_da * v + d * dv_da, fresnel::schlick_weight(h.cos_d), T::lit(2.0) * alpha * dalpha_dr)
    } else {
        (zero, zero, fresnel::schlick_weight(one), zero)
    };

    for k in 0..3 {
        let c = p.base[k];
        let (f0, df0, fr_o) = (o.f0[k], o.df0[k], o.fr_o[k]);
        let (fr_i, fr_h) = (fresnel::schlick(f0, w_i), fresnel::schlick(f0, w_h));
        let kd = (one - p.metallic) * c * inv_pi;
        let (e_o, e_i) = (fr_o.one_minus_f, fr_i.one_minus_f);
        let f_h = fr_h.f;
        f[k] = kd * e_o * e_i + dv * f_h;
        if GRAD {
            let df_df0 = dv * fr_h.df_df0 - kd * (fr_o.df_df0 * e_i + e_o * fr_i.df_df0);
            g.d_base[k] = (one - p.metallic) * inv_pi * e_o * e_i + df_df0 * df0[0];
            g.d_metallic[k] = -c * inv_pi * e_o * e_i + df_df0 * df0[1];
            g.d_specular[k] = df_df0 * df0[2];
            // Skip (rather than multiply by 0) when α is clamped, so no huge ∂(DV)/∂a meets a zero.
            g.d_roughness[k] = if da_dr == zero { zero } else { d_dv_da * f_h * da_dr };
        }
    }
    (f, g, terms)
}
