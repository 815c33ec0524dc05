//! Emission profiles and one-sidedness, seen directly by the camera (max_depth 0, so the pixel value is the
//! emitted radiance itself): uniform L = e on the front side, cosine L = e·cosθ, and nothing from the back.

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
    let params = Params { materials: vec![Material::default()], emission: vec![e] };
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
