//! Disney-style BRDF with the parameters the paper optimises. All directions are in the local shading frame
//! (z = shading normal), `wo` towards the viewer/previous vertex, `wi` towards the light/next vertex, both
//! unit length. `eval` returns f_r without the cosine factor.
//!
//! PLACEHOLDER API (Lambert only) — the BSDF work replaces the bodies, keeping these signatures.

use glam::{Vec2, Vec3};

/// Material parameters of one object or triangle.
///
/// | name | range | meaning |
/// |---|---|---|
/// | base_color | [0,1]³ | diffuse albedo (dielectric) / F0 tint (metal) |
/// | roughness | [0,1] | perceptual roughness, α = max(ε, roughness²) |
/// | metallic | [0,1] | blend dielectric → conductor |
/// | specular | [0,1] | dielectric F0 = 0.08·specular |
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

impl Material {
    /// f_r(wo, wi), zero when either direction is below the surface.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.base_color * (1.0 - self.metallic) * std::f32::consts::FRAC_1_PI
    }

    /// f_r and its derivatives with respect to every parameter.
    #[must_use]
    pub fn eval_grad(&self, wo: Vec3, wi: Vec3) -> (Vec3, MaterialGrad) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, MaterialGrad::default());
        }
        let k = std::f32::consts::FRAC_1_PI;
        let f = self.base_color * (1.0 - self.metallic) * k;
        let g = MaterialGrad {
            d_base_color: Vec3::splat((1.0 - self.metallic) * k),
            d_metallic: -self.base_color * k,
            ..Default::default()
        };
        (f, g)
    }

    /// Solid-angle pdf of `sample` producing `wi`.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 { 0.0 } else { wi.z * std::f32::consts::FRAC_1_PI }
    }

    /// Samples wi given two uniform numbers for the direction and one for the lobe choice.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: Vec2, _u_lobe: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let r = u.x.sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        let wi = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt());
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample { wi, f: self.eval(wo, wi), pdf })
    }

    /// True when the material is pure Lambert (metallic = specular = 0): the integrator's fast path.
    #[must_use]
    pub fn is_lambert(&self) -> bool {
        self.metallic == 0.0 && self.specular == 0.0
    }
}
