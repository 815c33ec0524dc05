//! Discarded samples: a path whose estimate is not finite contributes nothing and is counted in
//! `TraceStats::discarded`. An ordinary scene discards nothing; a lamp emitting `f32::MAX` makes every path
//! that sees it and gathers any further light overflow to ∞ (MAX + x rounds to ∞ for x ≥ half an ulp of MAX,
//! 2^103), and those are dropped while every returned pixel value and gradient stays finite.
//!
//! The per-pixel comparison with the lamp at 1 also caught a light-selection bug: the lamp's weight was its
//! f32 channel sum, ∞ at f32::MAX, so next-event estimation silently ignored it (now summed in f64).

mod common;

use common::{look_at_camera, small_room};
use glam::Vec3;
use tracer::{
    Camera, Material, Params, PixelRef, Renderer, Scene, TracerError, TracerSettings, render_image, total_trace_stats,
};

/// The small room (4 material slots, 3 emitter slots: 0 off, 1 the ceiling lamp, 2 the floor) with grey
/// walls and a lamp of emission `lamp`.
fn room(lamp: f32) -> (Scene, Params) {
    let scene = Scene::new(small_room()).expect("scene");
    let grey = |a: f32| Material { base_color: Vec3::splat(a), roughness: 0.5, metallic: 0.0, specular: 0.0 };
    let params = Params {
        materials: vec![grey(0.6), grey(0.7), grey(0.5), grey(0.4)],
        emission: vec![Vec3::ZERO, Vec3::splat(lamp), Vec3::ZERO],
        horizon: Default::default(),
    };
    (scene, params)
}

/// A camera on the floor looking up past the lamp: part of the image sees the lamp directly, the rest the
/// walls and ceiling.
fn camera() -> Camera {
    look_at_camera(24, 70.0, Vec3::new(0.0, -0.8, 0.7), Vec3::new(0.0, 0.98, -0.2))
}

fn all_pixels(cam: &Camera) -> Vec<PixelRef> {
    (0..cam.height).flat_map(|y| (0..cam.width).map(move |x| PixelRef { view: 0, x, y })).collect()
}

#[test]
fn an_ordinary_scene_discards_no_sample() {
    let (scene, params) = room(5.0);
    let cam = camera();
    let pixels = all_pixels(&cam);
    let settings = TracerSettings::default();
    let r = Renderer::new(&scene, &params, &settings).expect("renderer");
    let (values, stats) = r.render_pixels(&[cam], &pixels, 64, 1, 0).expect("render");
    eprintln!("ordinary scene, value paths: {} taken, {} discarded", stats.paths, stats.discarded);
    assert_eq!(stats.paths, pixels.len() as u64 * 64);
    assert_eq!(stats.discarded, 0);
    assert!(values.iter().all(|v| v.is_finite()));
    let weights = vec![Vec3::ONE; pixels.len()];
    let (grads, stats) = r.gradient_pixels(&[cam], &pixels, &weights, 32, 1, 0).expect("gradient");
    eprintln!("ordinary scene, gradient paths: {} taken, {} discarded", stats.paths, stats.discarded);
    assert_eq!(stats.paths, pixels.len() as u64 * 32);
    assert_eq!(stats.discarded, 0);
    // Something was actually differentiated: the lamp's emission gradient is positive (radiance grows with it).
    assert!(grads.emission[1].min_element() > 0.0, "{:?}", grads.emission[1]);
}

#[test]
fn overflowing_paths_are_discarded_and_every_result_stays_finite() {
    let (scene, params) = room(f32::MAX);
    let cam = camera();
    let pixels = all_pixels(&cam);
    let settings = TracerSettings::default();
    let r = Renderer::new(&scene, &params, &settings).expect("renderer");
    let spp = 16;
    let (values, stats) = r.render_pixels(&[cam], &pixels, spp, 1, 0).expect("render");
    eprintln!("f32::MAX lamp, value paths: {} taken, {} discarded", stats.paths, stats.discarded);
    assert!(stats.discarded > 0, "the lamp at f32::MAX must overflow some paths");
    // Only paths that see the lamp and then gather more light overflow; the walls' pixels mostly do not.
    assert!(stats.discarded < stats.paths / 2, "{} of {}", stats.discarded, stats.paths);
    assert!(values.iter().all(|v| v.is_finite() && v.min_element() >= 0.0), "non-finite or negative pixel");
    // Deterministic: the same call discards the same paths and returns the same values.
    let (again, stats_again) = r.render_pixels(&[cam], &pixels, spp, 1, 0).expect("render");
    assert_eq!(again, values);
    assert_eq!(stats_again, stats);

    // Gradient mode: radiance and derivatives overflow alike; every returned sum is finite.
    let weights = vec![Vec3::ONE; pixels.len()];
    let (grads, gstats) = r.gradient_pixels(&[cam], &pixels, &weights, spp, 1, 0).expect("gradient");
    eprintln!("f32::MAX lamp, gradient paths: {} taken, {} discarded", gstats.paths, gstats.discarded);
    assert!(gstats.discarded > 0 && gstats.discarded < gstats.paths);
    for m in &grads.materials {
        let c = m.base_color;
        assert!(c.is_finite() && m.roughness.is_finite() && m.metallic.is_finite() && m.specular.is_finite());
    }
    assert!(grads.emission.iter().all(|e| e.is_finite()));

    // `render_image` reports its discards in the process totals (which other tests may only increase).
    let before = total_trace_stats();
    let img = render_image(&scene, &params, &cam, spp, &settings, 1, 0).expect("render");
    let after = total_trace_stats();
    assert!(img.iter().all(|v| v.is_finite()));
    assert!(after.discarded - before.discarded >= stats.discarded, "{before:?} → {after:?}");
}

#[test]
fn a_non_finite_weight_is_an_error_not_a_discarded_sample() {
    let (scene, params) = room(5.0);
    let cam = camera();
    let pixels = all_pixels(&cam);
    let mut weights = vec![Vec3::ONE; pixels.len()];
    weights[7] = Vec3::new(1.0, f32::NAN, 1.0);
    let r = Renderer::new(&scene, &params, &TracerSettings::default()).expect("renderer");
    let e = r.gradient_pixels(&[cam], &pixels, &weights, 4, 1, 0).unwrap_err();
    assert!(matches!(e, TracerError::BadSetting { what: "gradient weight", .. }), "{e}");
    assert!(e.to_string().contains("at pixel 7"), "{e}");
}

#[test]
fn a_discarded_sample_leaves_the_other_samples_of_its_pixel_intact() {
    // A pixel's estimate is (Σ of its finite samples) / spp: with the lamp at f32::MAX, the wall pixels whose
    // paths all stayed finite equal the render with the lamp at 1, scaled by f32::MAX (radiance is linear in
    // emission), up to f32 rounding; a pixel that lost samples can only be darker than that scaled render.
    let cam = camera();
    let pixels = all_pixels(&cam);
    let settings = TracerSettings::default();
    let spp = 16;
    let (scene, unit) = room(1.0);
    let (_, huge) = room(f32::MAX);
    let per_pixel = |params: &Params| -> Vec<(Vec3, u64)> {
        let r = Renderer::new(&scene, params, &settings).expect("renderer");
        pixels
            .iter()
            .map(|p| {
                let (v, s) = r.render_pixels(&[cam], std::slice::from_ref(p), spp, 3, 0).expect("render");
                (v[0], s.discarded)
            })
            .collect()
    };
    let a = per_pixel(&unit);
    let b = per_pixel(&huge);
    let (mut intact, mut lossy) = (0, 0);
    for ((va, da), (vb, db)) in a.iter().zip(&b) {
        assert_eq!(*da, 0, "the unit lamp discards nothing");
        let scaled = va.as_dvec3() * f64::from(f32::MAX);
        if *db == 0 {
            intact += 1;
            // 1e-5 relative: the same f32 products with one factor scaled, rounded differently.
            let err = (vb.as_dvec3() - scaled).abs().max_element();
            assert!(err <= 1e-5 * scaled.max_element() + 1e-30, "{vb} vs {scaled}");
        } else {
            lossy += 1;
            // Dropped samples only remove non-negative radiance (the same 1e-5 rounding allowance).
            assert!(vb.as_dvec3().cmple(scaled * (1.0 + 1e-5)).all(), "{vb} vs {scaled}");
        }
    }
    eprintln!("pixels without discards: {intact}, with: {lossy}");
    assert!(intact > 0 && lossy > 0);
}
