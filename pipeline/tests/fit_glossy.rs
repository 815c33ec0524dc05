//! Model selection on glossy dielectrics (issue 7): objects with a specular lobe gain it, diffuse walls stay
//! diffuse, and the light is still found.
//!
//! Ignored because issue 7's acceptance is not met yet: the model decisions asserted here hold (measured:
//! floor kept the lobe with t = 3.5, gain 0.8 %; box t = 3.3, gain 1.8 %; walls diffuse), but only marginally
//! above the thresholds, and the recovered roughness is off by more than 0.05 (floor 0.20 for 0.4, box 0.33
//! for 0.25), so this is a measurement to improve on rather than a stable regression test.
//! Run with `cargo test -p pipeline --test fit_glossy -- --ignored --nocapture`.

use pipeline::fit::{FitInputs, ObjectFitSettings};
use std::path::Path;

#[test]
#[ignore = "issue 7 acceptance not met yet: the specular lobe is not kept (see module docs)"]
fn glossy_objects_gain_the_specular_lobe_and_walls_stay_diffuse() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/glossy.toml");
    let built = pipeline::synth::build(pipeline::synth::load_desc(&path).unwrap(), &path).unwrap();
    let images = pipeline::synth::photos(&built).unwrap();
    let objects = pipeline::synth::fit_objects(&built);
    let settings = ObjectFitSettings::default();
    let inputs = FitInputs {
        scene: &built.scene,
        cameras: &built.cameras,
        images: &images,
        objects: &objects,
        settings: &settings,
        tracer: &built.settings,
    };
    let t = std::time::Instant::now();
    let out = pipeline::fit::fit_objects(&inputs, None, &mut |_| Ok(()), &indicatif::ProgressBar::hidden()).unwrap();
    eprintln!("glossy fit: {:.1} s", t.elapsed().as_secs_f64());
    for (k, o) in built.desc.objects.iter().enumerate() {
        let m = out.params.materials[k];
        eprintln!(
            "{:>14}: albedo {:.3?} (true {:.3?}) rough {:.3} (true {:.2}) spec {:.3} (true {:.2}) emission {:.2?} — {}: {}",
            o.label,
            m.base_color.to_array(),
            o.base_color,
            m.roughness,
            o.roughness,
            m.specular,
            o.specular,
            out.params.emission[k].to_array(),
            out.per_object[k].model,
            out.per_object[k].why
        );
    }
    for (k, o) in built.desc.objects.iter().enumerate() {
        let want = if o.hidden {
            "diffuse+emission"
        } else if o.specular > 0.0 {
            "specular"
        } else {
            "diffuse"
        };
        assert_eq!(out.per_object[k].model, want, "{}: {}", o.label, out.per_object[k].why);
    }
}
