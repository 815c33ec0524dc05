//! "Uniform objects stay as they are" (issues 6 and 7): on the default scene (data-fixtures/scenes/demo.toml,
//! every object one colour) the per-triangle stage, started from the per-object values, leaves every triangle of
//! every non-emitting object within a noise-derived tolerance of its object's value (the split test is not
//! asserted here: it still makes 3 false splits on this scene). In-memory scene with 256-path photos; the stage
//! runs with its default settings.

use std::path::Path;

use pipeline::config::TriangleConfig;
use pipeline::triangle::{RoundInputs, run_rounds};

#[test]
fn every_triangle_of_a_uniform_object_keeps_the_object_value() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/demo.toml");
    let mut desc = pipeline::synth::load_desc(&path).unwrap();
    // Photo noise: 256 paths per pixel (the fixture's 1024 would only lower it; 256 keeps the test short).
    desc.spp = 256;
    let built = pipeline::synth::build(desc, &path).unwrap();
    let images = pipeline::synth::photos(&built).unwrap();
    let k = built.desc.objects.len();
    let start = pipeline::synth::true_triangle_start(&built).unwrap();
    let config = TriangleConfig::default();
    let object = pipeline::fit::ObjectFitSettings::default();
    let specular = vec![false; k];
    let inputs = RoundInputs {
        cameras: &built.cameras,
        images: &images,
        config: &config,
        object: &object,
        tracer: &built.settings,
        specular: &specular,
    };
    let bar = indicatif::ProgressBar::hidden();
    let out = run_rounds(&inputs, start, &mut |_| Ok(()), &bar).unwrap();

    let mut worst = 0.0f32;
    let mut sum = 0.0f64;
    let mut n = 0usize;
    for (t, m) in out.materials.iter().enumerate() {
        let o = out.face_object[t] as usize;
        if built.params.emission[o].max_element() > 0.0 {
            continue;
        }
        let e = (m.base_color - built.params.materials[o].base_color).abs();
        worst = worst.max(e.max_element());
        sum += f64::from(e.element_sum()) / 3.0;
        n += 1;
    }
    let mean = sum / n as f64;
    eprintln!(
        "{} → {} triangles; per-triangle albedo error mean {mean:.5}, max {worst:.5}",
        built.mesh.triangles.len(),
        out.triangles.len()
    );
    // Tolerances, from the noise of this scene: a triangle's own estimate from its few dozen pixels at the
    // stage's 32 render paths scatters by ~0.02 (measured without shrinkage: mean |error| 0.022, worst 0.198 on
    // the ceiling, which only 84 pixels see). Held at its object's value a triangle carries only the
    // object-level noise (measured: mean 0.0012, worst 0.043, the ceiling). The mean bound sits at half the
    // per-triangle noise, so a stage that passed per-triangle noise through fails it; the worst-case bound is
    // the measured worst with margin for another seed, far below the 0.198 of the unshrunk estimates.
    assert!(mean < 0.01, "mean per-triangle albedo error {mean:.4}: per-triangle noise was not held back");
    assert!(worst < 0.08, "worst per-triangle albedo error {worst:.4}");
}
