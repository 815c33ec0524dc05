//! Bad input is reported as a typed error naming what is wrong, never a panic.

mod common;

use common::{add_quad, look_at_camera};
use glam::Vec3;
use tracer::{
    Material, Params, PixelRef, Scene, SceneInput, TracerError, TracerSettings, gradient_pixels, render_pixels,
};

fn quad_scene() -> SceneInput {
    let mut s = SceneInput::default();
    add_quad(&mut s, [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y], 1, 2);
    s
}

#[test]
fn bad_scene_input_is_an_error() {
    let mut s = quad_scene();
    s.material_of_tri.pop();
    assert!(matches!(Scene::new(s), Err(TracerError::LengthMismatch { what: "material_of_tri", .. })));
    let mut s = quad_scene();
    s.positions[2].x = f32::NAN;
    assert!(matches!(Scene::new(s), Err(TracerError::NonFinite { vertex: 2, .. })));
    let mut s = quad_scene();
    s.normals = Some(vec![Vec3::Z; 3]);
    assert!(matches!(Scene::new(s), Err(TracerError::LengthMismatch { what: "normals", .. })));
    let mut s = quad_scene();
    s.triangles[1][2] = 99;
    let e = Scene::new(s).unwrap_err();
    assert!(e.to_string().contains("vertex 99"), "{e}");
}

#[test]
fn bad_render_arguments_are_errors() {
    let scene = Scene::new(quad_scene()).expect("scene");
    let cam = look_at_camera(4, 40.0, Vec3::new(0.5, 0.5, 2.0), Vec3::new(0.5, 0.5, 0.0));
    let settings = TracerSettings::default();
    let px = [PixelRef { view: 0, x: 1, y: 1 }];
    // Tables shorter than the indices the scene uses (material 1, emitter 2).
    let short =
        Params { materials: vec![Material::default()], emission: vec![Vec3::ZERO; 3], horizon: Default::default() };
    let e = render_pixels(&scene, &short, &[cam], &px, 1, &settings, 0, 0).unwrap_err();
    assert!(matches!(e, TracerError::LengthMismatch { what: "Params::materials", expected: 2, got: 1 }), "{e}");
    let ok =
        Params { materials: vec![Material::default(); 2], emission: vec![Vec3::ZERO; 3], horizon: Default::default() };
    let outside = [PixelRef { view: 0, x: 4, y: 0 }];
    assert!(matches!(
        render_pixels(&scene, &ok, &[cam], &outside, 1, &settings, 0, 0),
        Err(TracerError::BadPixel { index: 0, x: 4, .. })
    ));
    let no_view = [PixelRef { view: 1, x: 0, y: 0 }];
    assert!(matches!(
        render_pixels(&scene, &ok, &[cam], &no_view, 1, &settings, 0, 0),
        Err(TracerError::BadPixel { .. })
    ));
    assert!(matches!(render_pixels(&scene, &ok, &[cam], &px, 0, &settings, 0, 0), Err(TracerError::BadSetting { .. })));
    let w = [Vec3::ONE, Vec3::ONE];
    assert!(matches!(
        gradient_pixels(&scene, &ok, &[cam], &px, &w, 1, &settings, 0, 0),
        Err(TracerError::LengthMismatch { what: "weights", .. })
    ));
    let deep = TracerSettings { max_depth: 1 << 20, ..settings };
    assert!(matches!(render_pixels(&scene, &ok, &[cam], &px, 1, &deep, 0, 0), Err(TracerError::BadSetting { .. })));
}
