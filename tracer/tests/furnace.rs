//! Closed-form checks in a closed box whose walls all emit E (uniform) and reflect with Lambert albedo a:
//! the radiance everywhere is E·Σ_{k=0..D} a^k for at most D scatterings (E/(1−a) for D → ∞), and its
//! derivatives are Σ a^k with respect to E and E·Σ k·a^(k−1) with respect to a.

mod common;

use common::{add_box, look_at_camera, mean_se};
use glam::Vec3;
use tracer::{Material, Params, PixelRef, Scene, SceneInput, TracerSettings, gradient_pixels, render_image};

fn furnace_scene() -> Scene {
    let mut input = SceneInput::default();
    add_box(&mut input, Vec3::splat(-1.0), Vec3::splat(1.0), true, 0, 0);
    Scene::new(input).expect("scene")
}

fn params(albedo: f32, e: f32) -> Params {
    Params {
        materials: vec![Material { base_color: Vec3::splat(albedo), roughness: 0.5, metallic: 0.0, specular: 0.0 }],
        emission: vec![Vec3::splat(e)],
        horizon: Default::default(),
    }
}

fn geometric(a: f64, d: u32) -> (f64, f64) {
    let v = (0..=d).map(|k| a.powi(k as i32)).sum();
    let dv = (1..=d).map(|k| f64::from(k) * a.powi(k as i32 - 1)).sum();
    (v, dv)
}

#[test]
fn furnace_radiance_matches_the_geometric_series() {
    let scene = furnace_scene();
    let cam = look_at_camera(16, 60.0, Vec3::new(0.1, -0.2, 0.3), Vec3::new(1.0, 0.5, -0.7));
    for (a, depth, rr) in [(0.5f32, 3u32, 100u32), (0.5, 64, 2), (0.8, 64, 1), (0.0, 4, 0)] {
        let settings = TracerSettings { max_depth: depth, rr_depth: rr, ..Default::default() };
        let img = render_image(&scene, &params(a, 1.5), &cam, 16, &settings, 11, 0).expect("render");
        let xs: Vec<f64> = img.iter().flat_map(|c| [c.x, c.y, c.z]).map(f64::from).collect();
        let (m, se) = mean_se(&xs);
        let expect = 1.5 * geometric(f64::from(a), depth).0;
        eprintln!("furnace a {a} depth {depth}: {m} ± {se} (expected {expect})");
        // Rendering noise only: 4 standard errors, plus 1e-4 relative for f32 accumulation.
        assert!((m - expect).abs() <= 4.0 * se + 1e-4 * expect, "a {a} depth {depth}: {m} ± {se} vs {expect}");
    }
}

#[test]
fn furnace_gradients_match_closed_form() {
    let scene = furnace_scene();
    let cam = look_at_camera(16, 60.0, Vec3::new(0.1, -0.2, 0.3), Vec3::new(1.0, 0.5, -0.7));
    let pixels: Vec<PixelRef> = (0..16).flat_map(|y| (0..16).map(move |x| PixelRef { view: 0, x, y })).collect();
    let (a, e, depth) = (0.5f32, 1.5f32, 3u32);
    let settings = TracerSettings { max_depth: depth, rr_depth: 100, ..Default::default() };
    let (sv, sdv) = geometric(f64::from(a), depth);
    // One estimate per iteration with weights 1/N per pixel (the image mean); spread over iterations → SE.
    let w = vec![Vec3::splat(1.0 / pixels.len() as f32); pixels.len()];
    let (mut de, mut da) = (Vec::new(), Vec::new());
    for it in 0..24 {
        let g = gradient_pixels(&scene, &params(a, e), &[cam], &pixels, &w, 4, &settings, 5, it).expect("grad");
        de.push(g.emission[0].x);
        da.push(g.materials[0].base_color.y);
    }
    let (me, see) = mean_se(&de);
    let (ma, sea) = mean_se(&da);
    eprintln!("furnace dE {me} ± {see} (expected {sv}), da {ma} ± {sea}");
    assert!((me - sv).abs() <= 4.0 * see + 1e-4, "dE: {me} ± {see} vs {sv}");
    let expect_da = f64::from(e) * sdv;
    assert!((ma - expect_da).abs() <= 4.0 * sea + 1e-4, "da: {ma} ± {sea} vs {expect_da}");
}

#[test]
fn zero_albedo_still_has_a_base_color_gradient() {
    // At a = 0 the image is E alone but ∂I/∂a = E (one bounce): the adjoint pass must not lose it.
    let scene = furnace_scene();
    let cam = look_at_camera(8, 60.0, Vec3::ZERO, Vec3::X);
    let pixels: Vec<PixelRef> = (0..8).flat_map(|y| (0..8).map(move |x| PixelRef { view: 0, x, y })).collect();
    let w = vec![Vec3::splat(1.0 / pixels.len() as f32); pixels.len()];
    let settings = TracerSettings { max_depth: 5, rr_depth: 0, ..Default::default() };
    let mut da = Vec::new();
    for it in 0..16 {
        let g = gradient_pixels(&scene, &params(0.0, 2.0), &[cam], &pixels, &w, 4, &settings, 9, it).expect("grad");
        da.push(g.materials[0].base_color.x);
    }
    let (m, se) = mean_se(&da);
    assert!((m - 2.0).abs() <= 4.0 * se + 1e-4, "{m} ± {se}");
}
