//! The Embree query log (feature `ray-log`, on in tracer's own tests and benches through its dev-dependency
//! on itself) holds exactly the queries the tracer counts, and nothing made outside a recording.

mod common;

use common::{look_at_camera, small_room};
use glam::Vec3;
use tracer::embree::ray_log;
use tracer::{Material, Params, PixelRef, Renderer, Scene, TracerSettings};

#[test]
fn a_recording_holds_every_query_of_the_render_and_only_those() {
    let scene = Scene::new(small_room()).expect("scene");
    let params = Params {
        materials: vec![Material::default(); 4],
        emission: vec![Vec3::ZERO, Vec3::splat(5.0), Vec3::splat(0.1)],
        horizon: Default::default(),
    };
    let cam = look_at_camera(8, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
    let pixels: Vec<PixelRef> = (0..8).flat_map(|y| (0..8).map(move |x| PixelRef { view: 0, x, y })).collect();
    let settings = TracerSettings { max_depth: 5, rr_depth: 2, ..Default::default() };
    let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
    let render = || renderer.render_pixels(&[cam], &pixels, 4, 1, 0).expect("render");
    // A render outside any recording is not logged.
    let _ = render();
    let ((values, stats), log) = ray_log::record(render);
    assert!(stats.rays > stats.shadow_rays && stats.shadow_rays > 0, "{stats:?}");
    assert_eq!(log.len() as u64, stats.rays);
    assert_eq!(log.iter().filter(|r| r.shadow).count() as u64, stats.shadow_rays);
    // Every path starts with a closest-hit query from the camera's eye.
    let from_eye = log.iter().filter(|r| !r.shadow && (r.org - Vec3::new(0.2, 0.1, 0.95)).length() < 1e-5).count();
    assert_eq!(from_eye as u64, stats.paths);
    assert!(values.iter().all(|v| v.is_finite()));
    assert!(ray_log::record(|| ()).1.is_empty(), "a recording starts empty");
}
