//! The path-gradient estimator against central finite differences of renders, on `small_room`: for base
//! colour, roughness, metallic and emission of several objects (including an object that emits nothing, whose
//! emission gradient must still be found), the mean of many gradient estimates equals the mean of many
//! finite-difference estimates within 3 combined standard errors. Each finite difference uses common random
//! numbers (same seed and iteration at θ ± h); independent iterations give the standard errors. The light is
//! also checked split at a horizon with its sky graded (`tracer::params::Horizon`), with each of its emission
//! entries (sky at the horizon, ground, sky at the zenith) checked.

mod common;

use common::{look_at_camera, mean_se, small_room};
use glam::Vec3;
use tracer::{
    EmissionProfile, Grads, Material, Params, PixelRef, Scene, TracerSettings, gradient_pixels, render_pixels,
};

#[derive(Debug, Clone, Copy)]
enum Param {
    BaseColor(usize, usize),
    Roughness(usize),
    Metallic(usize),
    Emission(usize, usize),
}

fn get_mut(p: &mut Params, which: Param) -> &mut f32 {
    match which {
        Param::BaseColor(m, c) => &mut p.materials[m].base_color[c],
        Param::Roughness(m) => &mut p.materials[m].roughness,
        Param::Metallic(m) => &mut p.materials[m].metallic,
        Param::Emission(e, c) => &mut p.emission[e][c],
    }
}

fn get_grad(g: &Grads, which: Param) -> f64 {
    match which {
        Param::BaseColor(m, c) => g.materials[m].base_color[c],
        Param::Roughness(m) => g.materials[m].roughness,
        Param::Metallic(m) => g.materials[m].metallic,
        Param::Emission(e, c) => g.emission[e][c],
    }
}

#[test]
fn path_gradients_match_finite_differences_uniform_emission() {
    check_against_finite_differences(EmissionProfile::Uniform, false);
}

#[test]
fn path_gradients_match_finite_differences_cosine_emission() {
    check_against_finite_differences(EmissionProfile::Cosine, false);
}

#[test]
fn path_gradients_match_finite_differences_emission_split_at_a_horizon() {
    check_against_finite_differences(EmissionProfile::Uniform, true);
}

/// `split`: the ceiling light (slot 1) emits entry 3 towards directions above a tilted horizon and below it
/// a sky graded from entry 1 (level) to entry 4 (straight down) (the tilt puts the boundary across the light's
/// hemisphere, so every entry reaches the pixels).
fn check_against_finite_differences(emission_profile: EmissionProfile, split: bool) {
    let scene = Scene::new(small_room()).expect("scene");
    let mut params = Params {
        materials: vec![
            Material { base_color: Vec3::new(0.6, 0.5, 0.4), roughness: 0.35, metallic: 0.7, specular: 0.5 },
            Material { base_color: Vec3::splat(0.7), roughness: 0.5, metallic: 0.0, specular: 0.0 },
            Material { base_color: Vec3::new(0.3, 0.6, 0.3), roughness: 0.5, metallic: 0.0, specular: 0.0 },
            Material { base_color: Vec3::new(0.7, 0.4, 0.2), roughness: 0.5, metallic: 0.3, specular: 1.0 },
        ],
        emission: vec![Vec3::ZERO, Vec3::new(6.0, 5.0, 4.0), Vec3::ZERO],
        horizon: Default::default(),
    };
    let size = 12;
    let cam = look_at_camera(size, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
    let pixels: Vec<PixelRef> = (0..size).flat_map(|y| (0..size).map(move |x| PixelRef { view: 0, x, y })).collect();
    // A fixed, mixed-sign weight vector (like an L1 loss' signs).
    let weights: Vec<Vec3> = (0..pixels.len())
        .map(|j| {
            let s = if (j * 7) % 5 < 3 { 1.0 } else { -0.5 };
            Vec3::new(1.0, 0.8, 0.6) * s / pixels.len() as f32
        })
        .collect();
    let settings = TracerSettings { max_depth: 4, rr_depth: 2, emission_profile };
    if split {
        // Split, its sky graded from the horizon (entry 1) to the zenith (entry 4).
        params.emission.extend([Vec3::new(2.0, 3.0, 5.0), Vec3::new(3.0, 2.0, 1.0)]);
        params.horizon = tracer::params::Horizon {
            up: Vec3::new(1.0, -0.3, 0.4).normalize(),
            ground: vec![None, Some(3), None],
            zenith: vec![None, Some(4), None],
        };
    }
    let mut checks = vec![
        (Param::BaseColor(0, 0), 0.05),
        (Param::BaseColor(2, 1), 0.05),
        (Param::BaseColor(3, 2), 0.05),
        // Roughness enters through α = r² and the GGX lobe's sharp shape: the truncation error of a 0.05
        // step is already ~2 standard errors here, 0.02 brings it well below.
        (Param::Roughness(0), 0.02),
        (Param::Metallic(3), 0.05),
        (Param::Emission(1, 0), 0.5),
        (Param::Emission(2, 1), 0.1),
    ];
    if split {
        checks.push((Param::Emission(3, 2), 0.5));
        checks.push((Param::Emission(4, 0), 0.5));
    }
    let objective = |p: &Params, it: u64| -> f64 {
        let img = render_pixels(&scene, p, &[cam], &pixels, 24, &settings, 1234, it).expect("render");
        img.iter().zip(&weights).map(|(i, w)| f64::from(i.dot(*w))).sum()
    };
    let iterations = 64u64;
    let mut grads = vec![Vec::new(); checks.len()];
    let mut fds = vec![Vec::new(); checks.len()];
    for it in 0..iterations {
        let g = gradient_pixels(&scene, &params, &[cam], &pixels, &weights, 24, &settings, 99, it).expect("grad");
        assert_eq!(g.emission.len(), params.emission.len());
        for (k, &(which, h)) in checks.iter().enumerate() {
            grads[k].push(get_grad(&g, which));
            let mut plus = params.clone();
            *get_mut(&mut plus, which) += h;
            let mut minus = params.clone();
            *get_mut(&mut minus, which) -= h;
            fds[k].push((objective(&plus, it) - objective(&minus, it)) / (2.0 * f64::from(h)));
        }
    }
    let mut failures = Vec::new();
    for (k, &(which, _)) in checks.iter().enumerate() {
        let (mg, sg) = mean_se(&grads[k]);
        let (mf, sf) = mean_se(&fds[k]);
        let tol = 3.0 * (sg * sg + sf * sf).sqrt();
        eprintln!(
            "{emission_profile:?} {which:?}: path gradient {mg:.5} ± {sg:.5}, finite difference {mf:.5} ± {sf:.5}"
        );
        // The test only has power if the derivative is resolved: demand it differs from 0 by > 3 SE.
        if !(mg.is_finite() && mg.abs() > 3.0 * sg) {
            failures.push(format!("{which:?}: no resolved signal"));
        }
        if (mg - mf).abs() > tol {
            failures.push(format!("{which:?}: {mg} vs {mf} (tol {tol})"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
