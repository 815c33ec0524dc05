//! Analytic derivatives (`eval_grad`, f32) against central finite differences of `eval`'s formulas evaluated
//! in f64 (the same generic code), on a grid with roughness 0, 1e-4 and 1, albedo 0 and 1, metallic and
//! specular at their bounds, and cosines down to 1e-4; plus: no NaN/Inf from eval, eval_grad, pdf, sample.

use glam::{Vec2, Vec3};

use super::super::{Material, Params, eval_generic, fresnel, ggx};
use super::{Rng, dir};

const ROUGHNESS: [f32; 8] = [0.0, 1e-4, 0.005, 0.02, 0.05, 0.2, 0.5, 1.0];
const METALLIC: [f32; 3] = [0.0, 0.3, 1.0];
// 0.25 puts F0 = 0.02, the F90 kink, on the grid for metallic = 0 (finite differences across it are skipped).
const SPECULAR: [f32; 4] = [0.0, 0.25, 0.5, 1.0];
const BASE: [[f32; 3]; 3] = [[0.0; 3], [1.0; 3], [0.2, 0.5, 0.9]];
const COS: [f64; 5] = [1.0, 0.7, 0.2, 1e-2, 1e-4];

/// (wo, wi) pairs: every pair of cosines from COS, with wi in the mirror plane of wo (exact mirror when the
/// cosines match: the specular peak), 0.01 rad off it, 2 rad away, and on wo's side (back-scattering).
fn direction_pairs() -> Vec<(Vec3, Vec3)> {
    let phi_o = 0.3;
    let mut out = Vec::new();
    for &co in &COS {
        for &ci in &COS {
            for dphi in [std::f64::consts::PI, std::f64::consts::PI + 0.01, 2.0, 0.0] {
                out.push((dir(co, phi_o), dir(ci, phi_o + dphi)));
            }
        }
    }
    out
}

fn grid() -> impl Iterator<Item = Material> {
    ROUGHNESS.into_iter().flat_map(|roughness| {
        METALLIC.into_iter().flat_map(move |metallic| {
            SPECULAR.into_iter().flat_map(move |specular| {
                BASE.into_iter().map(move |b| Material {
                    base_color: Vec3::from_array(b),
                    roughness,
                    metallic,
                    specular,
                })
            })
        })
    })
}

fn to_f64(m: &Material) -> Params<f64> {
    Params {
        base: m.base_color.as_dvec3().to_array(),
        roughness: f64::from(m.roughness),
        metallic: f64::from(m.metallic),
        specular: f64::from(m.specular),
    }
}

/// The six scalar parameters: base r, g, b, roughness, metallic, specular.
fn param_mut(p: &mut Params<f64>, j: usize) -> &mut f64 {
    match j {
        0..=2 => &mut p.base[j],
        3 => &mut p.roughness,
        4 => &mut p.metallic,
        _ => &mut p.specular,
    }
}

/// True when [x − h, x + h] in parameter j crosses a kink of the model (α clamp, F90 = min(1, 50 F0)) for
/// channel k, where finite differences do not measure a derivative.
fn straddles_kink(p: &Params<f64>, j: usize, k: usize, h: f64) -> bool {
    let (mut lo, mut hi) = (*p, *p);
    *param_mut(&mut lo, j) -= h;
    *param_mut(&mut hi, j) += h;
    let clamped = |q: &Params<f64>| ggx::alpha(q.roughness).1 == 0.0;
    let full_grazing = |q: &Params<f64>| fresnel::f0(q.base[k], q.metallic, q.specular).0 * fresnel::F90_PER_F0 >= 1.0;
    clamped(&lo) != clamped(&hi) || full_grazing(&lo) != full_grazing(&hi)
}

#[test]
fn derivatives_match_central_differences() {
    // Step of the extrapolated central difference: f64 round-off ~1e-16·|f|/H = 1e-11·|f|; truncation
    // ~(H/scale)⁴ ≤ 1e-12 relative for the smallest parameter scale on the grid (roughness 0.02 just above the
    // clamp, where a = r⁴). A plain central difference left an h²·f''' error of 5e-5 relative where f is tiny
    // but f''' is not (metallic → 1, where the diffuse term is cubic in 1 − m).
    const H: f64 = 1e-5;
    // The issue's tolerance, relative to the finite difference ...
    const TOL: f64 = 1e-3;
    // ... or to FLOOR_REL·|f| when the derivative is smaller than that: the error then allowed,
    // 1e-3·1e-5·|f| = 1e-8·|f| per unit parameter, changes a first-order prediction of f over the parameter's
    // whole range [0, 1] by less than f32's own rounding of f (6e-8·|f|). (The f64 difference quotient's
    // round-off, ~1e-16·|f|/H = 1e-10·|f|, is far below that.) Where f = 0 the floor is 0: pure relative.
    const FLOOR_REL: f64 = 1e-5;
    let pairs = direction_pairs();
    let names = ["base.r", "base.g", "base.b", "roughness", "metallic", "specular"];
    let mut worst: [(f64, String); 6] = std::array::from_fn(|_| (0.0, String::new()));
    let mut worst64 = (0.0f64, String::new());
    let mut worst_value = (0.0f64, String::new());
    let (mut checked, mut skipped) = (0usize, 0usize);
    for m in grid() {
        let p = to_f64(&m);
        for &(wo, wi) in &pairs {
            let (wo64, wi64) = (wo.as_dvec3().to_array(), wi.as_dvec3().to_array());
            let (f, g) = m.eval_grad(wo, wi);
            let (f64v, g64) = eval_generic::<f64, true>(&p, wo64, wi64);
            for k in 0..3 {
                let rel = (f64::from(f[k]) - f64v[k]).abs() / f64v[k].abs().max(f64::MIN_POSITIVE);
                if rel > worst_value.0 {
                    worst_value = (rel, format!("{m:?} wo={wo} wi={wi} k={k}: {:e} vs f64 {:e}", f[k], f64v[k]));
                }
            }
            for j in 0..6 {
                let central = |h: f64| {
                    let (mut lo, mut hi) = (p, p);
                    *param_mut(&mut lo, j) -= h;
                    *param_mut(&mut hi, j) += h;
                    let (flo, _) = eval_generic::<f64, false>(&lo, wo64, wi64);
                    let (fhi, _) = eval_generic::<f64, false>(&hi, wo64, wi64);
                    [0, 1, 2].map(|k| (fhi[k] - flo[k]) / (2.0 * h))
                };
                // Richardson extrapolation of two central differences cancels the h² error term.
                let (d1, d2) = (central(H), central(0.5 * H));
                for k in 0..3 {
                    let fd = (4.0 * d2[k] - d1[k]) / 3.0;
                    let (analytic, analytic64) = match j {
                        0..=2 if k != j => {
                            // Off-diagonal Jacobian entries are exactly zero.
                            assert_eq!(fd, 0.0, "∂f_{k}/∂base_{j} ≠ 0 for {m:?}");
                            continue;
                        }
                        0..=2 => (g.d_base_color[k], g64.d_base[k]),
                        3 => (g.d_roughness[k], g64.d_roughness[k]),
                        4 => (g.d_metallic[k], g64.d_metallic[k]),
                        _ => (g.d_specular[k], g64.d_specular[k]),
                    };
                    if straddles_kink(&p, j, k, H) {
                        skipped += 1;
                        continue;
                    }
                    checked += 1;
                    let floor = (FLOOR_REL * f64v[k].abs()).max(f64::MIN_POSITIVE);
                    let err = (f64::from(analytic) - fd).abs() / fd.abs().max(floor);
                    let err64 = (analytic64 - fd).abs() / fd.abs().max(floor);
                    assert!(
                        err <= TOL,
                        "{}: {m:?} wo={wo} wi={wi} k={k}: analytic {analytic:e} vs fd {fd:e}",
                        names[j]
                    );
                    if err64 > worst64.0 {
                        worst64 = (
                            err64,
                            format!(
                                "{} {m:?} wo={wo} wi={wi} k={k}: {analytic64:e} vs fd {fd:e} (f {:e})",
                                names[j], f64v[k]
                            ),
                        );
                    }
                    if err > worst[j].0 {
                        worst[j] = (
                            err,
                            format!(
                                "{m:?} wo={wo} wi={wi} k={k}: {analytic:e} vs fd {fd:e} (f={:e}, f64 {:e}) a64 {analytic64:e}",
                                f[k], f64v[k]
                            ),
                        );
                    }
                }
            }
        }
    }
    eprintln!(
        "checked {checked} derivatives, skipped {skipped} at kinks; worst error of the f64 analytic: {:.2e} at {}",
        worst64.0, worst64.1
    );
    for (j, (e, s)) in worst.iter().enumerate() {
        eprintln!("{}: worst error of eval_grad (f32) {e:.2e} at {s}", names[j]);
    }
    // The same formulas in f64 must agree far better: this separates formula errors from f32 round-off.
    eprintln!("f32 eval vs f64 eval: worst relative difference {:.2e} at {}", worst_value.0, worst_value.1);
    // The f32 evaluation itself: no cancellation anywhere (1 − F and sin²θh are formed without it), so a few
    // ulps (measured: 5e-7) rather than the 1e-4 that 1 − F lost at cosθ = 1e-4 before.
    assert!(worst_value.0 < 1e-5, "f32 eval off by {:e}", worst_value.0);
    assert!(skipped > 0, "the grid should exercise the kink detection");
    assert!(worst64.0 < 1e-5, "f64 analytic derivative off by {:e}", worst64.0);
}

#[test]
fn no_nan_or_inf_on_the_grid() {
    let mut pairs = direction_pairs();
    // Directions on and below the horizon: zero f, zero pdf, no sample, never NaN.
    for (co, ci) in [(0.0, 0.5), (0.5, 0.0), (0.0, 0.0), (-0.3, 0.5), (0.5, -0.3), (1e-30, 1e-30), (1e-13, 0.5)] {
        pairs.push((dir(co, 0.3), dir(ci, 2.0)));
    }
    let mut rng = Rng::new(0xF1_1E);
    for m in grid() {
        for &(wo, wi) in &pairs {
            let f = m.eval(wo, wi);
            let (fg, g) = m.eval_grad(wo, wi);
            assert_eq!(f, fg, "{m:?}");
            let all = [f, g.d_base_color, g.d_roughness, g.d_metallic, g.d_specular];
            assert!(all.iter().all(|v| v.is_finite()), "{m:?} wo={wo} wi={wi}: {all:?}");
            let pdf = m.pdf(wo, wi);
            assert!(pdf.is_finite() && pdf >= 0.0, "{m:?} wo={wo} wi={wi}: pdf {pdf}");
            for u in
                [Vec2::ZERO, Vec2::new(0.5, 0.5), Vec2::new(0.999_999_9, 0.999_999_9), Vec2::new(rng.f32(), rng.f32())]
            {
                for u_lobe in [0.0, 0.5, 0.999_999_9] {
                    if let Some(s) = m.sample(wo, u, u_lobe) {
                        assert!(
                            s.wi.is_finite() && s.f.is_finite() && s.pdf.is_finite() && s.pdf > 0.0,
                            "{m:?}: {s:?}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn zero_specular_and_metallic_is_exactly_lambert() {
    // F0 = 0 ⇒ F ≡ 0: the general formulas must give the Lambert value bit for bit (eval_grad never takes the
    // fast path), for any roughness, and the pdf must be the cosine pdf.
    let mut rng = Rng::new(0x1A3B);
    for _ in 0..10_000 {
        let m = Material {
            base_color: Vec3::new(rng.f32(), rng.f32(), rng.f32()),
            roughness: rng.f32(),
            metallic: 0.0,
            specular: 0.0,
        };
        let wo = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32()));
        let wi = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32()));
        let (f, g) = m.eval_grad(wo, wi);
        assert_eq!(f, m.base_color * std::f32::consts::FRAC_1_PI);
        assert_eq!(m.pdf(wo, wi), wi.z * std::f32::consts::FRAC_1_PI);
        assert_eq!(m.specular_probability(wo), 0.0);
        // Specular and metallic still have a gradient at 0 (the optimiser must be able to leave 0); its sign
        // depends on whether the added specular reflection outweighs the diffuse light it takes away.
        assert!(g.d_specular.cmpne(Vec3::ZERO).all() && g.d_metallic.cmpne(Vec3::ZERO).all(), "{g:?}");
        assert_eq!(g.d_roughness, Vec3::ZERO);
    }
}
