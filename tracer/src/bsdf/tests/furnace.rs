//! White furnace: with base colour 1 the directional albedo ∫ f cosθi dωi never exceeds 1.

use glam::Vec2;

use super::{Rng, dir, material};

/// Importance-sampled estimate of the directional albedo: mean of f·cosθi/pdf (failed samples contribute 0,
/// as in the integrator) over `reps` independent jittered n×n grids of direction numbers, and its standard
/// error from the spread of the `reps` replica means (valid for the stratified estimator).
fn albedo(m: &super::Material, cos_o: f64, n: usize, reps: usize, rng: &mut Rng) -> (f64, f64) {
    let wo = dir(cos_o, 0.7);
    let means: Vec<f64> = (0..reps)
        .map(|_| {
            let mut sum = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + rng.f32()) / n as f32, (j as f32 + rng.f32()) / n as f32);
                    let weight =
                        |u_lobe: f32| m.sample(wo, u, u_lobe).map_or(0.0, |s| f64::from(s.f.x * s.wi.z / s.pdf));
                    // The expectation over the lobe choice, exactly: u_lobe = 0 picks the specular lobe whenever
                    // P_s > 0, u_lobe = 1 − 2⁻²⁴ the diffuse one whenever P_s < 1 − 2⁻²⁴.
                    let p_s = f64::from(m.specular_probability(wo));
                    let x = p_s * weight(0.0) + (1.0 - p_s) * weight(1.0 - f32::EPSILON / 2.0);
                    assert!(x.is_finite() && x >= 0.0, "{m:?} cos_o={cos_o}: weight {x}");
                    sum += x;
                }
            }
            sum / (n * n) as f64
        })
        .collect();
    let r = reps as f64;
    let mean = means.iter().sum::<f64>() / r;
    let var = means.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (r - 1.0);
    (mean, (var / r).sqrt())
}

#[test]
fn white_furnace_never_exceeds_one() {
    // 1e-3: the bound. SE_MAX: the estimate must be precise enough that an excess of 1e-3 would show
    // (4 standard errors).
    const BOUND: f64 = 1.0 + 1e-3;
    const SE_MAX: f64 = 2.5e-4;
    let mut rng = Rng::new(0xF0_2ACE);
    let (mut max_mean, mut max_se) = (0.0f64, 0.0f64);
    let mut min_mean = f64::INFINITY;
    for roughness in [0.0, 1e-4, 0.05, 0.2, 0.5, 1.0] {
        for metallic in [0.0, 0.5, 1.0] {
            for specular in [0.0, 0.5, 1.0] {
                let m = material(1.0, roughness, metallic, specular);
                for cos_o in [1.0, 0.5, 0.1, 1e-2, 1e-4] {
                    let (mean, se) = albedo(&m, cos_o, 64, 16, &mut rng);
                    eprintln!("r={roughness} m={metallic} s={specular} cos_o={cos_o}: albedo {mean:.5} ± {se:.1e}");
                    assert!(mean <= BOUND, "{m:?} cos_o={cos_o}: albedo {mean} ± {se}");
                    assert!(se <= SE_MAX, "{m:?} cos_o={cos_o}: standard error {se} too large to decide");
                    max_mean = max_mean.max(mean);
                    min_mean = min_mean.min(mean);
                    max_se = max_se.max(se);
                }
            }
        }
    }
    eprintln!("white furnace: albedo in [{min_mean:.5}, {max_mean:.7}], largest standard error {max_se:.1e}");
}

#[test]
fn lambert_furnace_is_exactly_one() {
    // specular = metallic = 0 is exact Lambert: cosine sampling makes every weight exactly ρ = 1 (up to the
    // f32 rounding of cos/π · π/cos).
    let m = material(1.0, 0.3, 0.0, 0.0);
    let (mean, se) = albedo(&m, 0.3, 32, 4, &mut Rng::new(7));
    assert!((mean - 1.0).abs() < 1e-6 && se < 1e-6, "{mean} ± {se}");
}
