//! A small lamp seen in a few pixel centres keeps its emission (`optim::fit::select`, the emission test on
//! the pixels that see an emitter): `data-fixtures/scenes/small-lamp.toml`, a room lit by a ceiling light no
//! photo sees and an 8 cm sconce on a wall (emission 4 / 3 / 2) that sends under 1 % of the room's light. The
//! test on the pixels its light reaches does not keep the sconce (−0.7 %, t = 2.1, measured); the pixels that
//! see it must: it emits, within 15 % per channel, and no object that does not emit in truth does.

use optim::fit::ObjectFitSettings;
use std::path::Path;

#[test]
fn a_lamp_seen_in_a_few_pixels_keeps_its_emission() {
    let desc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/small-lamp.toml");
    let built = lab::synth::build(lab::synth::load_desc(&desc_path).unwrap(), &desc_path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let out = lab::synth::fit(&built, &images, &ObjectFitSettings::default()).unwrap();
    let truth = &built.params;
    let find = |label: &str| built.desc.objects.iter().position(|o| o.label == label).unwrap();
    let (sconce, light) = (find("sconce"), find("ceiling light"));
    let mut l1 = 0.0;
    let mut n = 0;
    for (k, o) in built.desc.objects.iter().enumerate() {
        let (m, t) = (&out.params.materials[k], &truth.materials[k]);
        eprintln!(
            "{:>14}: {:.3?} (true {:.3?}), emission {:.3?} (true {:.3?}); {}: {}",
            o.label,
            m.base_color.to_array(),
            t.base_color.to_array(),
            out.params.emission[k].to_array(),
            truth.emission[k].to_array(),
            out.per_object[k].model,
            out.per_object[k].why
        );
        if truth.emission[k].max_element() == 0.0 {
            assert_eq!(out.params.emission[k].max_element(), 0.0, "{} emits", o.label);
            l1 += (m.base_color - t.base_color).abs().element_sum() / 3.0;
            n += 1;
        }
    }
    let l1 = l1 / n as f32;
    let rel = |k: usize| ((out.params.emission[k] - truth.emission[k]) / truth.emission[k]).abs().max_element();
    eprintln!("small lamp: sconce off by {:.3}, ceiling light by {:.3}, albedo L1 {l1:.4}", rel(sconce), rel(light));
    assert!(out.per_object[sconce].model.contains("emission"), "the sconce is lost: {}", out.per_object[sconce].why);
    assert!(rel(sconce) <= 0.15, "sconce emission off by {}", rel(sconce));
    assert!(rel(light) <= 0.1, "ceiling light off by {}", rel(light));
    assert!(l1 <= 0.03, "albedo L1 {l1}");
}
