//! Emission profiles and one-sidedness, seen directly by the camera (max_depth 0, so the pixel value is the
//! emitted radiance itself): uniform L = e on the front side, cosine L = e·cosθ, and nothing from the back;
//! an emitter split at a horizon sends each half of its directions its own radiance.

mod common;

use common::{add_quad, look_at_camera};
use glam::Vec3;
use tracer::{EmissionProfile, Material, Params, PixelRef, Scene, SceneInput, TracerSettings, render_pixels};

#[test]
fn emitted_radiance_follows_the_profile_and_only_the_front_face_emits() {
    // A large emitting square in the plane z = 0, front face +z.
    let mut input = SceneInput::default();
    let s = 50.0;
    add_quad(
        &mut input,
        [Vec3::new(-s, -s, 0.0), Vec3::new(s, -s, 0.0), Vec3::new(s, s, 0.0), Vec3::new(-s, s, 0.0)],
        0,
        0,
    );
    let scene = Scene::new(input).expect("scene");
    let e = Vec3::new(2.0, 1.0, 0.5);
    let params = Params { materials: vec![Material::default()], emission: vec![e], horizon: Default::default() };
    for theta_deg in [0.0f32, 30.0, 60.0, 80.0] {
        let theta = theta_deg.to_radians();
        let dir = Vec3::new(theta.sin(), 0.0, -theta.cos());
        // A narrow camera looking at the origin along `dir` from the front side (z > 0).
        let front = look_at_camera(1, 0.01, -dir * 3.0, Vec3::ZERO);
        let back = look_at_camera(1, 0.01, dir * 3.0, Vec3::ZERO);
        let px = [PixelRef { view: 0, x: 0, y: 0 }];
        for (profile, factor) in [(EmissionProfile::Uniform, 1.0), (EmissionProfile::Cosine, theta.cos())] {
            let settings = TracerSettings { max_depth: 0, rr_depth: 0, emission_profile: profile };
            let f = render_pixels(&scene, &params, &[front], &px, 4, &settings, 1, 0).expect("render")[0];
            let b = render_pixels(&scene, &params, &[back], &px, 4, &settings, 1, 0).expect("render")[0];
            // The 0.01° field of view changes cosθ by < 2e-4 relative across the pixel.
            assert!((f - e * factor).abs().max_element() <= 1e-3 * e.max_element(), "{profile:?} {theta_deg}: {f}");
            assert_eq!(b, Vec3::ZERO, "{profile:?} {theta_deg}: back face emits {b}");
        }
    }
}

/// A vertical emitting square 100 units wide, in the plane x = 0 with its front face +x, centred on the origin.
fn vertical_square() -> Scene {
    let mut input = SceneInput::default();
    let s = 50.0;
    add_quad(
        &mut input,
        [Vec3::new(0.0, -s, -s), Vec3::new(0.0, s, -s), Vec3::new(0.0, s, s), Vec3::new(0.0, -s, s)],
        0,
        0,
    );
    Scene::new(input).expect("scene")
}

#[test]
fn an_emitter_split_at_the_horizon_sends_each_half_its_own_radiance() {
    // A vertical emitting square (plane x = 0, front face +x) with world up +z: a camera below its centre
    // looks up at it and receives light travelling down (the sky's half), one above receives the ground's.
    let scene = vertical_square();
    let (sky, ground) = (Vec3::new(2.0, 2.5, 3.5), Vec3::new(0.8, 0.7, 0.5));
    let horizon = tracer::params::Horizon { up: Vec3::Z, ground: vec![Some(1)], zenith: Vec::new() };
    let params = Params { materials: vec![Material::default()], emission: vec![sky, ground], horizon };
    let settings = TracerSettings { max_depth: 0, rr_depth: 0, emission_profile: EmissionProfile::Uniform };
    let px = [PixelRef { view: 0, x: 0, y: 0 }];
    let seen = |eye: Vec3| {
        render_pixels(&scene, &params, &[look_at_camera(1, 0.01, eye, Vec3::ZERO)], &px, 4, &settings, 1, 0)
    };
    assert_eq!(seen(Vec3::new(3.0, 0.0, -1.0)).expect("render")[0], sky);
    assert_eq!(seen(Vec3::new(3.0, 0.5, 2.0)).expect("render")[0], ground);

    // Halves of equal radiance render, with light transport and next-event estimation, exactly as the
    // unsplit emitter (the light sampler's weight of the slot is the mean of its halves).
    let room = Scene::new(common::small_room()).expect("scene");
    let mut one = Params {
        materials: vec![Material::default(); 4],
        emission: vec![Vec3::ZERO, Vec3::new(4.0, 3.0, 2.0), Vec3::ZERO],
        horizon: Default::default(),
    };
    let cam = look_at_camera(8, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
    let pixels: Vec<PixelRef> = (0..8).flat_map(|y| (0..8).map(move |x| PixelRef { view: 0, x, y })).collect();
    let settings = TracerSettings { max_depth: 4, rr_depth: 2, ..Default::default() };
    let unsplit = render_pixels(&room, &one, &[cam], &pixels, 8, &settings, 5, 3).expect("render");
    one.emission.push(one.emission[1]);
    one.horizon =
        tracer::params::Horizon { up: Vec3::new(0.6, 0.0, 0.8), ground: vec![None, Some(3)], zenith: Vec::new() };
    let split = render_pixels(&room, &one, &[cam], &pixels, 8, &settings, 5, 3).expect("render");
    assert_eq!(unsplit, split);
    assert!(unsplit.iter().any(|v| v.max_element() > 0.0));
    // A horizon that is not a unit vector, and a ground entry inside the slots, are refused.
    one.horizon.up = Vec3::new(0.6, 0.0, 0.0);
    assert!(render_pixels(&room, &one, &[cam], &pixels, 1, &settings, 5, 3).is_err());
    one.horizon = tracer::params::Horizon { up: Vec3::Z, ground: vec![None, Some(2)], zenith: Vec::new() };
    assert!(render_pixels(&room, &one, &[cam], &pixels, 1, &settings, 5, 3).is_err());
}

#[test]
fn a_graded_sky_blends_its_horizon_and_zenith_by_the_elevation_sine() {
    // The vertical square above, split at the horizon, its sky half graded: a camera below its centre sees light
    // leaving it downward at s = −ω·up, and receives (1 − s)·horizon + s·zenith on average over its paths.
    let scene = vertical_square();
    let (horizon, ground, zenith) = (Vec3::new(2.0, 2.2, 2.6), Vec3::new(0.5, 0.5, 0.4), Vec3::new(0.9, 1.3, 2.6));
    let graded = tracer::params::Horizon { up: Vec3::Z, ground: vec![Some(1)], zenith: vec![Some(2)] };
    let params =
        Params { materials: vec![Material::default()], emission: vec![horizon, ground, zenith], horizon: graded };
    let settings = TracerSettings { max_depth: 0, rr_depth: 0, emission_profile: EmissionProfile::Uniform };
    let px = [PixelRef { view: 0, x: 0, y: 0 }];
    let spp = 4096;
    for eye in [Vec3::new(3.0, 0.0, -1.0), Vec3::new(1.0, 0.5, -2.0), Vec3::new(3.0, 0.0, -0.01)] {
        let cam = look_at_camera(1, 0.01, eye, Vec3::ZERO);
        let got = render_pixels(&scene, &params, &[cam], &px, spp, &settings, 1, 0).expect("render")[0];
        let sine = eye.normalize().dot(-Vec3::Z);
        let want = (1.0 - sine) * horizon + sine * zenith;
        // Each path takes one entry: the mean of `spp` picks has a standard deviation of
        // sqrt(s(1 − s)/spp)·|zenith − horizon| ≤ 0.008·1.1; 4.5σ.
        let tol = 4.5 * (sine * (1.0 - sine) / spp as f32).sqrt() * (zenith - horizon).abs().max_element() + 1e-4;
        assert!((got - want).abs().max_element() <= tol, "eye {eye}: {got} against {want} (±{tol})");
    }
    // Seen from above, the ground half alone.
    let above = look_at_camera(1, 0.01, Vec3::new(3.0, 0.5, 2.0), Vec3::ZERO);
    assert_eq!(render_pixels(&scene, &params, &[above], &px, 16, &settings, 1, 0).expect("render")[0], ground);

    // With light transport and next-event estimation: a zenith equal to the horizon renders exactly as the
    // flat sky, and the picks do not depend on the values, so a render is linear in the two entries.
    let room = Scene::new(common::small_room()).expect("scene");
    let flat_sky = Params {
        materials: vec![Material::default(); 4],
        emission: vec![Vec3::ZERO, Vec3::new(4.0, 3.0, 2.0), Vec3::ZERO, Vec3::new(1.0, 0.5, 0.2)],
        horizon: tracer::params::Horizon {
            up: Vec3::new(0.6, 0.0, 0.8),
            ground: vec![None, Some(3)],
            zenith: Vec::new(),
        },
    };
    let cam = look_at_camera(8, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
    let pixels: Vec<PixelRef> = (0..8).flat_map(|y| (0..8).map(move |x| PixelRef { view: 0, x, y })).collect();
    let settings = TracerSettings { max_depth: 4, rr_depth: 2, ..Default::default() };
    let render = |p: &Params| render_pixels(&room, p, &[cam], &pixels, 8, &settings, 5, 3).expect("render");
    let with_zenith = |h: Vec3, z: Vec3| {
        let mut p = flat_sky.clone();
        p.emission[1] = h;
        p.add_zeniths([(1, z)]);
        p
    };
    let flat = render(&flat_sky);
    assert_eq!(render(&with_zenith(flat_sky.emission[1], flat_sky.emission[1])), flat);
    let (h, z) = (Vec3::new(4.0, 3.0, 2.0), Vec3::new(1.0, 2.0, 6.0));
    let both = render(&with_zenith(h, z));
    let (only_h, only_z) = (render(&with_zenith(h, Vec3::ZERO)), render(&with_zenith(Vec3::ZERO, z)));
    let (mut ground_only, mut differs) = (flat_sky.clone(), false);
    ground_only.emission[1] = Vec3::ZERO;
    let g = render(&ground_only);
    for i in 0..pixels.len() {
        // The ground half's light is in each of the three renders: once in `both`, once in each part.
        let sum = only_h[i] + only_z[i] - g[i];
        assert!((both[i] - sum).abs().max_element() <= 1e-5 * both[i].max_element().max(1.0), "pixel {i}");
        differs |= both[i] != flat[i];
    }
    assert!(differs, "the zenith changes the render");
    // A zenith on a slot that is not split, or inside the slots, is refused.
    let mut bad = with_zenith(h, z);
    bad.horizon.zenith = vec![Some(4)];
    assert!(render_pixels(&room, &bad, &[cam], &pixels, 1, &settings, 5, 3).is_err());
    bad.horizon.zenith = vec![None, Some(2)];
    assert!(render_pixels(&room, &bad, &[cam], &pixels, 1, &settings, 5, 3).is_err());
}
