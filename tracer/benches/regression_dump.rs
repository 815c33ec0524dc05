//! TEMPORARY (perf work): dumps exact render/gradient bits to compare before/after optimisation.
#[path = "../tests/common/mod.rs"]
mod common;
use common::{look_at_camera, small_room};
use glam::Vec3;
use tracer::{EmissionProfile, Material, Params, PixelRef, Scene, TracerSettings, gradient_pixels, render_pixels};

#[test]
fn dump() {
    let out = std::env::var("REGRESS_OUT").unwrap_or_else(|_| "/tmp/regress/out.txt".into());
    let mut input = small_room();
    // vertex normals (perturbed) on half the runs
    let mut lines = Vec::new();
    for with_normals in [false, true] {
        if with_normals {
            let n: Vec<Vec3> = input.positions.iter().map(|p| (Vec3::new(0.1, 1.0, 0.2) + *p * 0.3)).collect();
            input.normals = Some(n);
        }
        let scene = Scene::new(input.clone()).expect("scene");
        let mut params = Params {
            materials: vec![Material::default(); 4],
            emission: vec![Vec3::ZERO, Vec3::splat(5.0), Vec3::new(0.1, 0.2, 0.0)],
        };
        params.materials[3] =
            Material { base_color: Vec3::new(0.8, 0.5, 0.2), roughness: 0.3, metallic: 0.5, specular: 0.5 };
        params.materials[0] =
            Material { base_color: Vec3::new(0.3, 0.6, 0.9), roughness: 0.05, metallic: 0.0, specular: 0.7 };
        params.materials[2] =
            Material { base_color: Vec3::new(0.7, 0.7, 0.2), roughness: 0.0, metallic: 1.0, specular: 0.0 };
        let cam = look_at_camera(24, 70.0, Vec3::new(0.2, 0.1, 0.95), Vec3::new(-0.2, -0.6, -0.3));
        let pixels: Vec<PixelRef> = (0..24).flat_map(|y| (0..24).map(move |x| PixelRef { view: 0, x, y })).collect();
        let weights: Vec<Vec3> =
            (0..pixels.len()).map(|j| Vec3::new(if j % 3 == 0 { -1.0 } else { 1.0 }, 0.5, 2.0)).collect();
        for profile in [EmissionProfile::Uniform, EmissionProfile::Cosine] {
            let settings = TracerSettings { max_depth: 7, rr_depth: 2, emission_profile: profile };
            let img = render_pixels(&scene, &params, &[cam], &pixels, 16, &settings, 3, 17).expect("render");
            let g = gradient_pixels(&scene, &params, &[cam], &pixels, &weights, 8, &settings, 3, 17).expect("grad");
            for c in &img {
                lines.push(format!("{:e} {:e} {:e}", c.x, c.y, c.z));
            }
            for m in &g.materials {
                lines.push(format!(
                    "{:e} {:e} {:e} {:e} {:e} {:e}",
                    m.base_color.x, m.base_color.y, m.base_color.z, m.roughness, m.metallic, m.specular
                ));
            }
            for e in &g.emission {
                lines.push(format!("{:e} {:e} {:e}", e.x, e.y, e.z));
            }
        }
    }
    std::fs::write(out, lines.join("\n")).expect("write");
}
