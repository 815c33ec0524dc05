//! Physics tests of the BRDF: reciprocity, white furnace, sampling consistency and χ², derivatives against
//! finite differences of an f64 instantiation of the same formulas. All random numbers come from fixed seeds.

mod derivatives;
mod furnace;
mod reciprocity;
mod sampling;

use glam::{DVec3, Vec3};

use super::Material;

/// SplitMix64 (Steele, Lea & Flood 2014): tiny, seedable, good enough for test sampling.
#[derive(Debug, Clone)]
pub(super) struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1) with 24 random bits (every value exactly representable, never 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}

/// Unit direction with the given cosθ and φ (computed in f64, rounded once).
pub(super) fn dir(cos_theta: f64, phi: f64) -> Vec3 {
    let s = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    DVec3::new(s * phi.cos(), s * phi.sin(), cos_theta).as_vec3()
}

pub(super) fn material(base: f32, roughness: f32, metallic: f32, specular: f32) -> Material {
    Material { base_color: Vec3::splat(base), roughness, metallic, specular }
}

/// P(χ²_dof ≥ stat) (statrs).
pub(super) fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(dof as f64).expect("dof ≥ 1").sf(stat)
}

#[test]
fn chi2_p_value_matches_tables() {
    // Textbook critical values: P(χ²_1 ≥ 3.841) = 0.05, P(χ²_10 ≥ 23.209) = 0.01, P(χ²_100 ≥ 135.807) = 0.01;
    // and the closed form P(χ²_2 ≥ x) = exp(−x/2).
    assert!((chi2_p_value(3.841_458_820_694_124, 1) - 0.05).abs() < 1e-9);
    assert!((chi2_p_value(23.209_251_158_954_36, 10) - 0.01).abs() < 1e-9);
    assert!((chi2_p_value(135.806_723_3, 100) - 0.01).abs() < 1e-8);
    for x in [0.1, 1.0, 7.0, 40.0] {
        assert!((chi2_p_value(x, 2) - (-0.5 * x).exp()).abs() < 1e-12);
    }
}
