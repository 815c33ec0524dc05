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

#[test]
fn an_emitter_split_at_the_horizon_sends_each_half_its_own_radiance() {
    // A vertical emitting square (plane x = 0, front face +x) with world up +z: a camera below its centre
    // looks up at it and receives light travelling down (the sky's half), one above receives the ground's.
    let mut input = SceneInput::default();
    let s = 50.0;
    add_quad(
        &mut input,
        [Vec3::new(0.0, -s, -s), Vec3::new(0.0, s, -s), Vec3::new(0.0, s, s), Vec3::new(0.0, -s, s)],
        0,
        0,
    );
    let scene = Scene::new(input).expect("scene");
    let (sky, ground) = (Vec3::new(2.0, 2.5, 3.5), Vec3::new(0.8, 0.7, 0.5));
    let horizon = tracer::params::Horizon { up: Vec3::Z, ground: vec![Some(1)] };
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
    one.horizon = tracer::params::Horizon { up: Vec3::new(0.6, 0.0, 0.8), ground: vec![None, Some(3)] };
    let split = render_pixels(&room, &one, &[cam], &pixels, 8, &settings, 5, 3).expect("render");
    assert_eq!(unsplit, split);
    assert!(unsplit.iter().any(|v| v.max_element() > 0.0));
    // A horizon that is not a unit vector, and a ground entry inside the slots, are refused.
    one.horizon.up = Vec3::new(0.6, 0.0, 0.0);
    assert!(render_pixels(&room, &one, &[cam], &pixels, 1, &settings, 5, 3).is_err());
    one.horizon = tracer::params::Horizon { up: Vec3::Z, ground: vec![None, Some(2)] };
    assert!(render_pixels(&room, &one, &[cam], &pixels, 1, &settings, 5, 3).is_err());
}
