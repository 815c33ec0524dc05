//! Renders and gradients are bit-identical whatever the number of threads, and repeatable.

mod common;

use common::{look_at_camera, small_room};
use glam::Vec3;
use tracer::{Material, Params, PixelRef, Scene, TracerSettings, gradient_pixels, render_pixels};

#[test]
fn results_do_not_depend_on_thread_count() {
    let scene = Scene::new(small_room()).expect("scene");
    let mut params = Params {
        materials: vec![Material::default(); 4],
        emission: vec![Vec3::ZERO, Vec3::splat(5.0), Vec3::splat(0.1)],
    };
    params.materials[3] =
        Material { base_color: Vec3::new(0.8, 0.5, 0.2), roughness: 0.3, metallic: 0.5, specular: 0.5 };
    let cam = look_at_camera(16, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
    let pixels: Vec<PixelRef> = (0..16).flat_map(|y| (0..16).map(move |x| PixelRef { view: 0, x, y })).collect();
    let weights: Vec<Vec3> = (0..pixels.len()).map(|j| Vec3::splat(if j % 3 == 0 { -1.0 } else { 1.0 })).collect();
    let settings = TracerSettings { max_depth: 6, rr_depth: 1, ..Default::default() };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| {
            let img = render_pixels(&scene, &params, &[cam], &pixels, 8, &settings, 3, 17).expect("render");
            let g = gradient_pixels(&scene, &params, &[cam], &pixels, &weights, 4, &settings, 3, 17).expect("grad");
            (img, g)
        })
    };
    let (img1, g1) = run(1);
    let (img2, g2) = run(2);
    let (img2b, g2b) = run(2);
    assert!(img1.iter().zip(&img2).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
    assert_eq!(img2, img2b);
    assert_eq!(g1, g2);
    assert_eq!(g2, g2b);
    // The value and gradient streams differ, and a different iteration gives a different image.
    let other = render_pixels(&scene, &params, &[cam], &pixels, 8, &settings, 3, 18).expect("render");
    assert_ne!(img1, other);
    assert!(img1.iter().any(|c| c.max_element() > 0.0));
}
