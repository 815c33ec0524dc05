//! Model selection on glossy dielectrics: the objects with a specular lobe (floor: specular 0.8,
//! roughness 0.4; box: specular 1, roughness 0.25) gain it and their roughness comes within 0.05 of the truth;
//! the diffuse walls and ceiling stay diffuse, and the hidden light is still found.
//!
//! Measured (seed 0, 49 s on a loaded machine): floor roughness 0.388, specular 0.723 (kept, t = 8.0); box
//! roughness 0.261, specular 0.946 (kept, t = 4.2); every wall's best lobe made the held-out residual worse;
//! light within 2.2 % (7.5 % while `specular_trial_steps` re-fitted the light against those lobes). Other fit
//! seeds: see docs/optim/design-measurements.md.
//! `FIT_GLOSSY_SEED=n` reruns it with another fit seed (a manual robustness check; the default is 0).

use optim::fit::ObjectFitSettings;
use std::path::Path;

#[test]
fn glossy_objects_gain_the_specular_lobe_and_walls_stay_diffuse() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/glossy.toml");
    let built = lab::synth::build(lab::synth::load_desc(&path).unwrap(), &path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let seed = std::env::var("FIT_GLOSSY_SEED").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    let settings = ObjectFitSettings { seed, ..ObjectFitSettings::default() };
    let t = std::time::Instant::now();
    let out = lab::synth::fit(&built, &images, &settings).unwrap();
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
        if o.specular > 0.0 {
            // Roughness within 0.05 of the truth.
            let r = out.params.materials[k].roughness;
            assert!((r - o.roughness).abs() <= 0.05, "{}: roughness {r} for {}", o.label, o.roughness);
        }
    }
    let light = built.desc.objects.iter().position(|o| o.hidden).unwrap();
    let truth = built.params.emission[light];
    let err = ((out.params.emission[light] - truth).abs() / truth).max_element();
    // The demo's 5 % tolerance for the hidden light.
    assert!(err <= 0.05, "light emission {} for {truth}", out.params.emission[light]);
}
