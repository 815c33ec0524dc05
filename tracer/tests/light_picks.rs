//! The light pick's parts that the path loops call apart: `LightSampler::slot` is the slot `pick` draws from,
//! and the pick tables' prefetches (`Scene::prefetch_emitter_guide`, `Scene::prefetch_emitter_cdf`) accept
//! every slot and draw, also those a pick never sees, and leave the picks as they were.

mod common;

use common::add_quad;
use glam::Vec3;
use tracer::{LightSampler, Material, Params, Scene, SceneInput};

/// Emitter slots: 0 a floor of 2 × 20 × 20 triangles of unequal areas, 1 a single triangle, 2 a quad with a
/// zero-area triangle beside it, 3 none (no triangle at all), 4 a single triangle again.
fn scene() -> Scene {
    let mut input = SceneInput::default();
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    for i in 0..20 {
        for j in 0..20 {
            // Cells widen along x, so the cdf's steps are unequal and the guide's buckets hold 0–2 entries.
            let (x0, x1) = ((i * i) as f32 / 40.0, ((i + 1) * (i + 1)) as f32 / 40.0);
            let (z0, z1) = (j as f32, j as f32 + 1.0);
            add_quad(&mut input, [v(x0, 0.0, z0), v(x0, 0.0, z1), v(x1, 0.0, z1), v(x1, 0.0, z0)], 0, 0);
        }
    }
    let base = input.positions.len() as u32;
    input.positions.extend([v(0.0, 3.0, 0.0), v(1.0, 3.0, 0.0), v(0.0, 3.0, 1.0)]);
    input.triangles.push([base, base + 1, base + 2]);
    input.material_of_tri.push(0);
    input.emitter_of_tri.push(1);
    add_quad(&mut input, [v(0.0, 2.0, 0.0), v(1.0, 2.0, 0.0), v(1.0, 2.0, 1.0), v(0.0, 2.0, 1.0)], 0, 2);
    let base = input.positions.len() as u32;
    input.positions.extend([v(0.0, 2.0, 0.0), v(1.0, 2.0, 0.0), v(2.0, 2.0, 0.0)]);
    input.triangles.push([base, base + 1, base + 2]);
    input.material_of_tri.push(0);
    input.emitter_of_tri.push(2);
    let base = input.positions.len() as u32;
    input.positions.extend([v(0.0, 4.0, 0.0), v(1.0, 4.0, 0.0), v(0.0, 4.0, 1.0)]);
    input.triangles.push([base, base + 1, base + 2]);
    input.material_of_tri.push(0);
    input.emitter_of_tri.push(4);
    Scene::new(input).expect("scene")
}

#[test]
fn the_slot_is_the_picks_slot_and_prefetches_change_no_pick() {
    let scene = scene();
    // Selection weights (mean emission × area) 1, 1/3, 1/2, 0 and 1/4: every drawn slot spans several draws.
    let emission = vec![Vec3::splat(0.005), Vec3::new(2.0, 0.0, 0.0), Vec3::splat(0.5), Vec3::ONE, Vec3::splat(0.5)];
    let params = Params { materials: vec![Material::default()], emission, horizon: Default::default() };
    let lights = LightSampler::new(&scene, &params);
    let draws: Vec<f32> = (0..=64).map(|i| i as f32 / 64.0).chain([0.999_999_9, -1.0, 2.0, f32::NAN]).collect();
    let mut slots_seen = std::collections::BTreeSet::new();
    for &u_slot in &draws {
        for &u_tri in &draws {
            let before = lights.pick(&scene, u_slot, u_tri);
            for slot in 0..8 {
                scene.prefetch_emitter_guide(slot, f64::from(u_tri));
                scene.prefetch_emitter_cdf(slot, f64::from(u_tri));
            }
            let pick = lights.pick(&scene, u_slot, u_tri);
            assert_eq!(pick, before, "u_slot {u_slot}, u_tri {u_tri}");
            let slot = lights.slot(u_slot);
            assert_eq!(pick.map(|p| scene.emitter_of(p.tri)), slot, "u_slot {u_slot}, u_tri {u_tri}");
            slots_seen.extend(slot);
        }
    }
    // Every slot with area and emission is drawn by some u_slot; slot 3 has no triangle.
    assert_eq!(slots_seen.into_iter().collect::<Vec<_>>(), vec![0, 1, 2, 4]);
}
