//! A window pane is an emitter split at the horizon, a lamp on a wall is not (`optim::fit::horizon`):
//! `data-fixtures/scenes/window.toml`, a room lit through a window whose pane emits the sky's radiance towards
//! the directions that point down or level and the ground's, 3–6× dimmer and warmer, towards those that point
//! up, and by a lamp facing sideways with one radiance. Fitted with one radiance the pane sends the sky's light
//! to the ceiling, which comes out dark. The fit must split the pane and recover both halves, keep the lamp
//! whole, and recover the room's albedos.

use optim::fit::ObjectFitSettings;
use std::path::Path;

#[test]
fn a_window_pane_is_split_at_the_horizon_and_a_wall_lamp_is_not() {
    let desc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/window.toml");
    let built = lab::synth::build(lab::synth::load_desc(&desc_path).unwrap(), &desc_path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let out = lab::synth::fit(&built, &images, &ObjectFitSettings::default()).unwrap();
    let truth = &built.params;
    let find = |label: &str| built.desc.objects.iter().position(|o| o.label == label).unwrap();
    let (pane, lamp) = (find("window pane"), find("wall lamp"));
    let fitted = |k: usize| out.params.horizon.ground_of(k as u32).map(|g| out.params.emission[g as usize]);
    let mut l1 = 0.0;
    let mut n = 0;
    for (k, o) in built.desc.objects.iter().enumerate() {
        let (m, t) = (&out.params.materials[k], &truth.materials[k]);
        eprintln!(
            "{:>12}: {:.3?} (true {:.3?}), emission {:.3?} ground {:?}; {}: {}",
            o.label,
            m.base_color.to_array(),
            t.base_color.to_array(),
            out.params.emission[k].to_array(),
            fitted(k).map(|g| g.to_array()),
            out.per_object[k].model,
            out.per_object[k].why
        );
        if k != lamp && k != pane {
            l1 += (m.base_color - t.base_color).abs().element_sum() / 3.0;
            n += 1;
        }
    }
    let l1 = l1 / n as f32;
    let rel = |e: glam::Vec3, t: glam::Vec3| (e - t).abs().element_sum() / t.element_sum();
    let ground_true = truth.emission[truth.horizon.ground_of(pane as u32).unwrap() as usize];
    let ground = fitted(pane).expect("the pane is not split at the horizon");
    let (sky_err, ground_err) = (rel(out.params.emission[pane], truth.emission[pane]), rel(ground, ground_true));
    let lamp_err = rel(out.params.emission[lamp], truth.emission[lamp]);
    eprintln!("window: albedo L1 {l1:.4}; pane sky {sky_err:.3}, ground {ground_err:.3}; lamp {lamp_err:.3}");
    assert!(fitted(lamp).is_none(), "the lamp, one radiance in every direction, is split");
    // The walls' faint emissions from the refinement are tested again split at the horizon (they face
    // sideways), and a split fitted on their test pixels gains there (1 % at t = 11.6 when measured) only as
    // much as one radiance fitted there: none of them may come out an emitter.
    for (k, o) in built.desc.objects.iter().enumerate().filter(|&(k, _)| k != lamp && k != pane) {
        assert_eq!(out.params.emission[k], glam::Vec3::ZERO, "{} emits: {}", o.label, out.per_object[k].why);
    }
    // The pane is black and seen directly from above and below its centre, so the photos show both halves;
    // the lamp is found through the light it sends (2 % off when measured). A uniform pane fits the walls,
    // floor and ceiling with albedo L1 far above 0.01 (the ceiling takes the sky's light).
    assert!(sky_err <= 0.05, "pane's sky half off by {sky_err}");
    assert!(ground_err <= 0.10, "pane's ground half off by {ground_err}");
    assert!(lamp_err <= 0.06, "lamp off by {lamp_err}");
    assert!(l1 <= 0.01, "albedo L1 {l1}");
}
