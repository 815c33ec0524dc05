//! `sample` against `pdf` and `eval`: returned values agree, the pdf integrates to the probability that a
//! sample is produced, and the sampled directions follow the pdf (χ² goodness of fit on a (θ, φ) histogram).

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{Vec2, Vec3};

use super::super::Material;
use super::{Rng, chi2_p_value, dir, material};

#[test]
fn sample_returns_pdf_and_eval() {
    let mut rng = Rng::new(0x5A4D);
    for _ in 0..200_000 {
        let m = Material {
            base_color: Vec3::new(rng.f32(), rng.f32(), rng.f32()),
            roughness: rng.f32() * rng.f32(),
            metallic: if rng.f32() < 0.2 { 0.0 } else { rng.f32() },
            specular: if rng.f32() < 0.2 { 0.0 } else { rng.f32() },
        };
        let wo = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32()));
        let Some(s) = m.sample(wo, Vec2::new(rng.f32(), rng.f32()), rng.f32()) else { continue };
        assert!(s.wi.z > 0.0 && (s.wi.length() - 1.0).abs() < 1e-5, "{m:?} wo={wo}: wi={}", s.wi);
        assert!(s.pdf > 0.0 && s.pdf.is_finite());
        assert_eq!(s.pdf, m.pdf(wo, s.wi), "{m:?} wo={wo} wi={}", s.wi);
        assert_eq!(s.f, m.eval(wo, s.wi), "{m:?} wo={wo} wi={}", s.wi);
        assert_eq!(s.f, m.eval_grad(wo, s.wi).0, "{m:?} wo={wo} wi={}", s.wi);
        assert!(s.f.is_finite() && s.f.min_element() >= 0.0);
    }
}

/// Midpoint-rule integral of the pdf over the upper hemisphere on an n_θ × 2n_θ grid in (θ, φ).
fn integrate_pdf(m: &Material, wo: Vec3, n_theta: usize) -> f64 {
    let n_phi = 2 * n_theta;
    let (dt, dp) = (FRAC_PI_2 / n_theta as f64, TAU / n_phi as f64);
    let mut sum = 0.0;
    for i in 0..n_theta {
        let theta = (i as f64 + 0.5) * dt;
        let mut row = 0.0;
        for j in 0..n_phi {
            row += f64::from(m.pdf(wo, dir(theta.cos(), (j as f64 + 0.5) * dp)));
        }
        sum += row * theta.sin();
    }
    sum * dt * dp
}

#[test]
fn pdf_integrates_to_the_sampled_fraction() {
    let mut rng = Rng::new(0x1D7F);
    let n = 400_000;
    for (roughness, metallic, cos_o) in [(0.3, 0.0, 0.9), (0.5, 0.5, 0.4), (1.0, 1.0, 0.1), (0.7, 1.0, 0.02)] {
        let m = material(0.5, roughness, metallic, 0.5);
        let wo = dir(cos_o, 1.0);
        let integral = integrate_pdf(&m, wo, 1024);
        let produced = (0..n).filter(|_| m.sample(wo, Vec2::new(rng.f32(), rng.f32()), rng.f32()).is_some()).count();
        let p = produced as f64 / n as f64;
        let se = (p * (1.0 - p) / n as f64).sqrt().max(1.0 / n as f64);
        eprintln!("r={roughness} m={metallic} cos_o={cos_o}: ∫pdf = {integral:.5}, sampled fraction {p:.5} ± {se:.1e}");
        // 1e-4: the midpoint rule's error for these lobes is below 1e-5 (doubling the grid changes no integral
        // by more than that).
        assert!(integral <= 1.0 + 1e-4, "∫pdf = {integral}");
        assert!((integral - p).abs() < 4.0 * se + 1e-4, "∫pdf = {integral}, sampled fraction {p} ± {se}");
        if roughness == 1.0 && metallic == 1.0 {
            // Closed form: α = 1 makes D = 1/π and S(wo) = 1, so p_s = 1/(2π(cosθo + 1)) on the whole
            // hemisphere, and a metal (m = 1) always picks the specular lobe: ∫pdf = 1/(1 + cosθo).
            let exact = 1.0 / (1.0 + cos_o);
            assert!((integral - exact).abs() < 1e-4, "∫pdf = {integral}, closed form {exact}");
        }
    }
}

/// Composite Simpson integral of pdf·sinθ over one (θ, φ) cell with n×n panels (n even).
fn cell_integral(m: &Material, wo: Vec3, theta: (f64, f64), phi: (f64, f64), n: usize) -> f64 {
    let weight = |i: usize| {
        if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        }
    };
    let (ht, hp) = ((theta.1 - theta.0) / n as f64, (phi.1 - phi.0) / n as f64);
    let mut sum = 0.0;
    for i in 0..=n {
        let t = theta.0 + i as f64 * ht;
        let mut row = 0.0;
        for j in 0..=n {
            row += weight(j) * f64::from(m.pdf(wo, dir(t.cos(), phi.0 + j as f64 * hp)));
        }
        sum += weight(i) * row * t.sin();
    }
    sum * ht * hp / 9.0
}

/// χ² test of `sampler.sample` against `density.pdf` (after pbrt-v4's `chi2` test): histogram the samples in
/// (θ, φ) cells plus one "no sample" cell, pool cells expecting fewer than 5, and return the p-value.
fn chi2_test(sampler: &Material, density: &Material, wo: Vec3, rng: &mut Rng) -> f64 {
    const N_THETA: usize = 16;
    const N_PHI: usize = 32;
    const SAMPLES: usize = 400_000;
    let mut observed = vec![0.0f64; N_THETA * N_PHI + 1];
    for _ in 0..SAMPLES {
        let cell = match sampler.sample(wo, Vec2::new(rng.f32(), rng.f32()), rng.f32()) {
            None => N_THETA * N_PHI,
            Some(s) => {
                let theta = f64::from(s.wi.z).clamp(0.0, 1.0).acos();
                let phi = f64::from(s.wi.y).atan2(f64::from(s.wi.x)).rem_euclid(TAU);
                let i = ((theta / FRAC_PI_2 * N_THETA as f64) as usize).min(N_THETA - 1);
                let j = ((phi / TAU * N_PHI as f64) as usize).min(N_PHI - 1);
                i * N_PHI + j
            }
        };
        observed[cell] += 1.0;
    }
    // Simpson panels per cell and axis: the lobe in wi has a width of about 2α; resolve it with ≥ 10 panels
    // (a cell is 0.1 rad × 0.2 rad). Too few panels bias the expected counts by O(1 %), which 400k samples
    // detect: roughness 0.1 failed with 32 panels and passes with 128.
    let alpha = density.roughness * density.roughness;
    let panels = if alpha < 0.03 { 128 } else { 32 };
    let mut expected = vec![0.0f64; N_THETA * N_PHI + 1];
    let (dt, dp) = (FRAC_PI_2 / N_THETA as f64, TAU / N_PHI as f64);
    for i in 0..N_THETA {
        for j in 0..N_PHI {
            let t = (i as f64 * dt, (i + 1) as f64 * dt);
            let p = (j as f64 * dp, (j + 1) as f64 * dp);
            expected[i * N_PHI + j] = SAMPLES as f64 * cell_integral(density, wo, t, p, panels);
        }
    }
    let total: f64 = expected.iter().sum();
    expected[N_THETA * N_PHI] = (SAMPLES as f64 - total).max(0.0);

    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut stat, mut dof) = (0.0, 0usize);
    let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
    for &c in &order {
        if expected[c] < 5.0 {
            pooled_obs += observed[c];
            pooled_exp += expected[c];
        } else {
            stat += (observed[c] - expected[c]).powi(2) / expected[c];
            dof += 1;
        }
    }
    if pooled_exp > 0.0 {
        stat += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
        dof += 1;
    } else {
        assert!(pooled_obs == 0.0, "{pooled_obs} samples where the pdf is 0");
    }
    chi2_p_value(stat, dof - 1)
}

#[test]
fn sampling_passes_chi2() {
    // (base, roughness, metallic, specular, cosθo): rough to glossy lobes, dielectric mixtures, metals, grazing.
    let cases = [
        (0.5, 0.5, 0.0, 0.0, 0.6),
        (0.5, 0.3, 0.0, 0.5, 0.8),
        (0.8, 0.6, 0.5, 0.5, 0.3),
        (0.9, 1.0, 1.0, 0.5, 0.05),
        (0.9, 0.2, 1.0, 0.0, 0.6),
        (0.2, 0.4, 0.0, 1.0, 0.15),
        (0.7, 0.5, 0.2, 0.5, 1.0),
        (0.9, 0.1, 1.0, 0.5, 0.7),
        (0.6, 0.15, 0.0, 0.5, 0.4),
    ];
    // Šidák correction: overall false-alarm rate 1 % across all cases.
    let significance = 1.0 - (1.0 - 0.01f64).powf(1.0 / cases.len() as f64);
    let mut rng = Rng::new(0xC41);
    for (base, roughness, metallic, specular, cos_o) in cases {
        let m = material(base, roughness, metallic, specular);
        let wo = dir(cos_o, 0.4);
        let p = chi2_test(&m, &m, wo, &mut rng);
        eprintln!("χ²: {m:?} cos_o={cos_o}: p = {p:.4}");
        assert!(p > significance, "{m:?} cos_o={cos_o}: χ² p-value {p} < {significance}");
    }
}

#[test]
fn chi2_rejects_a_wrong_pdf() {
    // Power of the harness: samples of a Lambert material tested against a glossy metal's pdf must fail.
    let lambert = material(0.5, 0.5, 0.0, 0.0);
    let glossy = material(0.5, 0.3, 1.0, 0.5);
    let p = chi2_test(&lambert, &glossy, dir(0.6, 0.4), &mut Rng::new(0xBAD));
    assert!(p < 1e-6, "p = {p}");
}
