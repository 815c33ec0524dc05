//! The unknowns (material and emission tables), render settings, and the gradient table shaped like them.

use crate::bsdf::{Material, MaterialGrad};
use crate::error::TracerError;
use crate::scene::Scene;
use glam::{DVec3, Vec3};

/// Parameter tables, indexed by `SceneInput::material_of_tri` and `SceneInput::emitter_of_tri`.
/// `emission[i]` is the RGB radiance scale `e` of emitter slot i (see [`EmissionProfile`]); 0 = not a light.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params {
    pub materials: Vec<Material>,
    pub emission: Vec<Vec3>,
}

impl Params {
    /// Checks that the tables cover every index the scene uses.
    pub fn check(&self, scene: &Scene) -> Result<(), TracerError> {
        if self.materials.len() < scene.material_slots() {
            return Err(TracerError::LengthMismatch {
                what: "Params::materials",
                expected: scene.material_slots(),
                got: self.materials.len(),
            });
        }
        if self.emission.len() < scene.emitter_slots() {
            return Err(TracerError::LengthMismatch {
                what: "Params::emission",
                expected: scene.emitter_slots(),
                got: self.emission.len(),
            });
        }
        Ok(())
    }
}

/// Directional profile of emitted radiance at a front-facing direction with cosine `cos` to the geometric
/// normal; both are zero on the back face (one-sided emitters).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EmissionProfile {
    /// L_e = e: Lambertian emitter, what Mitsuba, Tungsten and pbrt call an area light.
    #[default]
    Uniform,
    /// L_e = e·(i·n)₊, the paper's profile (§4.3).
    Cosine,
}

impl EmissionProfile {
    /// ∂L_e/∂e (the same for every colour channel): L_e = e · factor(cos).
    #[inline]
    #[must_use]
    pub fn factor(self, cos: f32) -> f32 {
        if cos <= 0.0 {
            return 0.0;
        }
        match self {
            EmissionProfile::Uniform => 1.0,
            EmissionProfile::Cosine => cos,
        }
    }
}

/// Path-tracing settings.
///
/// Depth convention (pbrt's): `max_depth` is the largest number of scattering events on a path;
/// 0 = emitters seen directly only, 1 = plus direct illumination, … (Mitsuba's `max_depth` is ours + 1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TracerSettings {
    pub max_depth: u32,
    /// Russian roulette is applied to the scattering at vertices with depth ≥ `rr_depth`.
    pub rr_depth: u32,
    pub emission_profile: EmissionProfile,
}

impl Default for TracerSettings {
    fn default() -> Self {
        TracerSettings { max_depth: 8, rr_depth: 3, emission_profile: EmissionProfile::Uniform }
    }
}

/// Accumulated derivative of Σ_pixels w·I with respect to one material's parameters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MaterialGradSum {
    pub base_color: DVec3,
    pub roughness: f64,
    pub metallic: f64,
    pub specular: f64,
}

impl MaterialGradSum {
    /// Adds `c ⊙ ∂f` for a per-channel chain factor `c` (weight ⊙ throughput ⊙ incoming radiance …):
    /// base colour is per channel (diagonal Jacobian), scalar parameters sum over channels.
    #[inline]
    pub fn add_chain(&mut self, d: &MaterialGrad, c: Vec3) {
        self.base_color += (d.d_base_color * c).as_dvec3();
        self.roughness += f64::from((d.d_roughness * c).element_sum());
        self.metallic += f64::from((d.d_metallic * c).element_sum());
        self.specular += f64::from((d.d_specular * c).element_sum());
    }

    pub fn add(&mut self, o: &MaterialGradSum) {
        self.base_color += o.base_color;
        self.roughness += o.roughness;
        self.metallic += o.metallic;
        self.specular += o.specular;
    }
}

/// Gradient table indexed like [`Params`]: `∂(Σ_j w_j · I_j)/∂θ` for the weights the caller passed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Grads {
    pub materials: Vec<MaterialGradSum>,
    pub emission: Vec<DVec3>,
}

impl Grads {
    #[must_use]
    pub fn zeros_like(params: &Params) -> Self {
        Grads {
            materials: vec![MaterialGradSum::default(); params.materials.len()],
            emission: vec![DVec3::ZERO; params.emission.len()],
        }
    }
}
