//! Renders and gradients are bit-identical whatever the number of threads, and repeatable.

mod common;

use common::{look_at_camera, small_room};
use glam::Vec3;
use tracer::{Camera, Material, Params, PixelRef, Renderer, Scene, TracerSettings, gradient_pixels, render_pixels};

/// What every test here renders: the small room with a glossy, half-metallic box (so that paths mix diffuse
/// and specular scattering), two emitters, a 16×16 view of all of it, Russian roulette from the first bounce.
struct GlossyRoom {
    scene: Scene,
    params: Params,
    cam: Camera,
    pixels: Vec<PixelRef>,
    settings: TracerSettings,
}

fn glossy_room() -> GlossyRoom {
    let mut params = Params {
        materials: vec![Material::default(); 4],
        emission: vec![Vec3::ZERO, Vec3::splat(5.0), Vec3::splat(0.1)],
        horizon: Default::default(),
    };
    params.materials[3] =
        Material { base_color: Vec3::new(0.8, 0.5, 0.2), roughness: 0.3, metallic: 0.5, specular: 0.5 };
    GlossyRoom {
        scene: Scene::new(small_room()).expect("scene"),
        params,
        cam: look_at_camera(16, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3)),
        pixels: (0..16).flat_map(|y| (0..16).map(move |x| PixelRef { view: 0, x, y })).collect(),
        settings: TracerSettings { max_depth: 6, rr_depth: 1, ..Default::default() },
    }
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let GlossyRoom { scene, params, cam, pixels, settings } = glossy_room();
    let weights: Vec<Vec3> = (0..pixels.len()).map(|j| Vec3::splat(if j % 3 == 0 { -1.0 } else { 1.0 })).collect();
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

#[test]
fn columns_match_separate_basis_renders() {
    // Russian roulette from the first bounce (the room's settings): the columns share terminated paths too.
    let GlossyRoom { scene, params, cam, pixels, settings } = glossy_room();
    let slots: Vec<u32> = (0..scene.emitter_slots() as u32).rev().collect();
    check_columns(&scene, &params, &cam, &pixels, &settings, &slots);
}

#[test]
fn columns_of_emitters_split_at_a_horizon_match_separate_basis_renders() {
    // The light (slot 1) and the floor (slot 2) split at a tilted horizon, so that both halves of each reach
    // the pixels: the ground halves are entries 3 and 4, listed among the slots' own entries.
    let GlossyRoom { scene, mut params, cam, pixels, settings } = glossy_room();
    params.emission.extend([Vec3::splat(2.0), Vec3::splat(0.3)]);
    params.horizon = tracer::params::Horizon {
        up: Vec3::new(0.8, 0.1, -0.5).normalize(),
        ground: vec![None, Some(3), Some(4)],
        zenith: Vec::new(),
    };
    check_columns(&scene, &params, &cam, &pixels, &settings, &[4, 1, 0, 3, 2]);
    // An entry past the slots that no slot owns has no column.
    let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
    assert!(renderer.render_emission_columns(&[cam], &pixels, &[5], 8, 3, 17).is_err());
    params.horizon.ground[2] = None;
    let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
    assert!(renderer.render_emission_columns(&[cam], &pixels, &[4], 8, 3, 17).is_err());
}

/// Each column of `entries` equals, bit for bit, the render with emission 1 at that entry and 0 at the others;
/// every column lights some pixel, and the paths were traced once for all of them.
fn check_columns(
    scene: &Scene,
    params: &Params,
    cam: &Camera,
    pixels: &[PixelRef],
    settings: &TracerSettings,
    entries: &[u32],
) {
    let renderer = Renderer::new(scene, params, settings).expect("renderer");
    let (cols, stats) = renderer.render_emission_columns(&[*cam], pixels, entries, 8, 3, 17).expect("columns");
    assert_eq!(cols.len(), entries.len());
    for (col, &k) in cols.iter().zip(entries) {
        let mut basis = params.clone();
        basis.emission.iter_mut().for_each(|e| *e = Vec3::ZERO);
        basis.emission[k as usize] = Vec3::ONE;
        let alone = render_pixels(scene, &basis, &[*cam], pixels, 8, settings, 3, 17).expect("render");
        assert!(
            col.iter().zip(&alone).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)),
            "column of emission entry {k} differs from its own basis render"
        );
    }
    assert!(cols.iter().all(|c| c.iter().any(|v| v.max_element() > 0.0)));
    assert_eq!(stats.paths, pixels.len() as u64 * 8);
    assert!(renderer.render_emission_columns(&[*cam], pixels, &[99], 8, 3, 17).is_err());
}

#[test]
fn weighted_gradients_match_one_weighting_at_a_time() {
    let GlossyRoom { scene, params, cam, pixels, settings } = glossy_room();
    // The three channels, and a weighting that skips every third pixel (zero weight).
    let unit =
        |c: usize| -> Vec<Vec3> { vec![Vec3::from_array(std::array::from_fn(|i| f32::from(u8::from(i == c)))); 256] };
    let sparse: Vec<Vec3> = (0..256).map(|j| if j % 3 == 0 { Vec3::ZERO } else { Vec3::new(1.0, -2.0, 0.5) }).collect();
    let sets = [unit(0), unit(1), unit(2), sparse];
    let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
    let refs: Vec<&[Vec3]> = sets.iter().map(Vec::as_slice).collect();
    let (all, stats) = renderer.gradient_pixels_weighted(&[cam], &pixels, &refs, 4, 3, 17).expect("weighted");
    for (g, w) in all.iter().zip(&sets) {
        let alone = gradient_pixels(&scene, &params, &[cam], &pixels, w, 4, &settings, 3, 17).expect("gradient");
        assert_eq!(*g, alone);
    }
    assert!(all[0].materials[3].roughness != 0.0);
    // The paths were traced once for the four weightings.
    assert_eq!(stats.paths, 256 * 4);
}

#[test]
fn gradient_rows_match_each_pixel_alone() {
    let GlossyRoom { scene, params, cam, pixels, settings } = glossy_room();
    // A weight per pixel, some zero (those pixels trace nothing and have empty rows).
    let weights: Vec<Vec3> =
        (0..256).map(|j| if j % 5 == 0 { Vec3::ZERO } else { Vec3::new(1.0, 0.5 + j as f32 / 256.0, -0.25) }).collect();
    let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
    let (rows, stats) = renderer.gradient_rows(&[cam], &pixels, &weights, 4, 3, 17, |row| row).expect("rows");
    assert_eq!(rows.len(), pixels.len());
    let mut touched = 0;
    for ((row, p), w) in rows.iter().zip(&pixels).zip(&weights) {
        let alone = gradient_pixels(&scene, &params, &[cam], &[*p], &[*w], 4, &settings, 3, 17).expect("gradient");
        // The row holds exactly the dense table's non-zero entries, in ascending slot order, bit for bit.
        let mut dense = tracer::Grads::zeros_like(&params);
        for &(t, m) in &row.materials {
            dense.materials[t as usize] = m;
        }
        for &(k, d) in &row.emission {
            dense.emission[k as usize] = d;
        }
        assert_eq!(dense, alone, "pixel {p:?}");
        assert!(row.materials.windows(2).all(|w| w[0].0 < w[1].0));
        assert!(row.emission.windows(2).all(|w| w[0].0 < w[1].0));
        touched += usize::from(!row.materials.is_empty());
        if *w == Vec3::ZERO {
            assert_eq!(*row, tracer::SparseGrads::default());
        }
    }
    assert!(touched > 200, "{touched} pixels with entries");
    // Zero-weight pixels trace nothing.
    assert_eq!(stats.paths, 4 * weights.iter().filter(|w| **w != Vec3::ZERO).count() as u64);
}
