//! External reference: Bitterli's Cornell box (Mitsuba XML read by our own test loader) rendered by us
//! against the Tungsten reference render. Criteria: per-channel image means within 1 %, and the mean absolute
//! pixel difference to the reference at most 1.5× the one between two independent renders of ours at the same
//! spp (i.e. no structure beyond our own noise). Rendered at 128² against the 1024² reference box-downsampled
//! by 8 (a box filter over the same footprint as our 128² pixels).

mod common;

use common::{channel_means, downsample, mean_abs_diff, mitsuba_xml, shared_data};
use glam::Vec3;
use tracer::{Camera, Params, Scene, TracerSettings, render_image};

fn read_exr(path: &std::path::Path) -> (Vec<Vec3>, usize, usize) {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (vec![Vec3::ZERO; res.width() * res.height()], res.width(), res.height()),
        |(px, w, _), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b),
    )
    .expect("read TungstenRender.exr");
    img.layer_data.channel_data.pixels
}

#[test]
fn cornell_box_matches_tungsten() {
    let dir = shared_data().join("bitterli-cornell-box");
    if !dir.join("scene.xml").exists() || !dir.join("TungstenRender.exr").exists() {
        eprintln!("skipping: {} not found", dir.display());
        return;
    }
    let xml = std::fs::read_to_string(dir.join("scene.xml")).expect("read scene.xml");
    let loaded = mitsuba_xml::load(&xml).expect("parse scene.xml");
    let scene = Scene::new(loaded.input).expect("scene");
    let params = Params { materials: loaded.materials, emission: loaded.emission, horizon: Default::default() };
    let (reference, w, h) = read_exr(&dir.join("TungstenRender.exr"));
    assert_eq!((w, h), (1024, 1024));
    let factor = 8;
    let size = (w / factor) as u32;
    let reference = downsample(&reference, w, h, factor);
    // Mitsuba's fov is horizontal by default; the image is square so it is also the vertical fov.
    let cam = Camera::from_fov_y(size, size, loaded.fov_deg.to_radians(), loaded.cam_to_world);
    // Tungsten's reference uses up to 64 bounces; beyond ~30 the remaining energy is < 1e-4 of the image.
    let settings = TracerSettings { max_depth: 64, rr_depth: 5, ..Default::default() };
    let spp = 256;
    let a = render_image(&scene, &params, &cam, spp, &settings, 1, 0).expect("render");
    let b = render_image(&scene, &params, &cam, spp, &settings, 2, 0).expect("render");
    let (ma, mr) = (channel_means(&a), channel_means(&reference));
    let rel = (ma - mr) / mr;
    let (d_ref, d_self) = (mean_abs_diff(&a, &reference), mean_abs_diff(&a, &b));
    eprintln!(
        "means ours {ma:.5} reference {mr:.5} relative {rel:.5}; MAD to reference {d_ref:.5}, ours vs ours {d_self:.5}"
    );
    assert!(rel.abs().max_element() < 0.01, "channel means differ by {rel}");
    assert!(d_ref <= 1.5 * d_self, "MAD to reference {d_ref} > 1.5 × {d_self}");
}
