//! Helmholtz reciprocity: f(wo, wi) = f(wi, wo), and hence also for every derivative.

use glam::Vec3;

use super::super::{Material, Params, eval_generic};
use super::{Rng, dir};

#[test]
fn brdf_and_gradient_are_reciprocal() {
    let mut rng = Rng::new(0x5EC1);
    let mut worst: f32 = 0.0;
    for _ in 0..20_000 {
        let m = Material {
            base_color: Vec3::new(rng.f32(), rng.f32(), rng.f32()),
            // Squaring spreads roughness towards the sharp, clamped end of the range.
            roughness: rng.f32() * rng.f32(),
            metallic: rng.f32(),
            specular: rng.f32(),
        };
        let wo = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32()));
        let wi = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32()));
        let (a, ga) = m.eval_grad(wo, wi);
        let (b, gb) = m.eval_grad(wi, wo);
        // Only the order of two products differs between the two calls: a few f32 ulps of the larger of the
        // value and the terms of each (possibly cancelling) derivative sum, whose size is that of |f|.
        let scale = a.abs().max(b.abs()).max(Vec3::splat(1e-30));
        let pairs = [(a, b), (ga.d_base_color, gb.d_base_color), (ga.d_metallic, gb.d_metallic)];
        let pairs = pairs.into_iter().chain([(ga.d_specular, gb.d_specular), (ga.d_roughness, gb.d_roughness)]);
        for (x, y) in pairs {
            let rel = ((x - y).abs() / x.abs().max(y.abs()).max(scale)).max_element();
            worst = worst.max(rel);
            assert!(rel < 1e-5, "{m:?} wo={wo} wi={wi}: {x} vs {y}");
        }
    }
    eprintln!("reciprocity: worst relative asymmetry {worst:e}");
}

#[test]
fn f64_reference_is_reciprocal() {
    let mut rng = Rng::new(0x5EC2);
    for _ in 0..5_000 {
        let p = Params {
            base: [f64::from(rng.f32()); 3],
            roughness: f64::from(rng.f32()),
            metallic: f64::from(rng.f32()),
            specular: f64::from(rng.f32()),
        };
        let wo = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32())).as_dvec3().to_array();
        let wi = dir(f64::from(rng.f32()).max(1e-4), 6.3 * f64::from(rng.f32())).as_dvec3().to_array();
        let (a, _) = eval_generic::<f64, false>(&p, wo, wi);
        let (b, _) = eval_generic::<f64, false>(&p, wi, wo);
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() <= 1e-13 * a[k].abs(), "{p:?}: {a:?} vs {b:?}");
        }
    }
}
