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

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9; relative error < 1e-13).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(s, x) (Numerical Recipes §6.2: series below s + 1, Lentz continued
/// fraction above; both iterate to 1e-15 relative).
fn gamma_q(s: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_pre = -x + s * x.ln() - ln_gamma(s);
    if x < s + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / s, 1.0 / s, s);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * ln_pre.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - s;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - s);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        ln_pre.exp() * h
    }
}

/// P(χ²_dof ≥ stat).
pub(super) fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    gamma_q(0.5 * dof as f64, 0.5 * stat)
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
