//! The object stage's hidden light on the checker scene (data-fixtures/checker: a 4 × 4 checker floor that the
//! scan models as one object, so one colour must stand for two) does not depend on which pixels the solves
//! draw: `pipeline run --until object` with three fit seeds, each light within 5 % of the truth per channel.
//!
//! The light of a room no photo shows it in is fixed per channel only by interreflection (albedo ρ → ρ/s and
//! emission L → sL leave direct light unchanged), so a loss whose minimum is flat on the floor's two-mode
//! residuals let the solves' pixel draw move it: with an L1 data term the light's blue channel was 8.3 instead
//! of 15 (44 %) for one seed in five, and per-step jumps of the Gauss–Newton refinement reached the whole
//! light (docs/optim/design-measurements.md, "Solve pixels per object and the checker light"). Measured here,
//! fitting at the photos' depth of 6: seeds 0–2 end 1.6 %, 3.7 %, 1.0 % off, 76 s for the three runs (debug
//! build); at depth 8, two bounces more than the photos, 2.2 %, 2.8 %, 2.7 % (red high).

mod common;
use common::{pipeline, workspace_root};

#[test]
fn checker_light_is_within_five_percent_for_every_fit_seed() {
    let scan = workspace_root().join("data-fixtures/checker");
    let desc = lab::synth::load_desc(&workspace_root().join("data-fixtures/scenes/checker.toml")).unwrap();
    let light = desc.objects.iter().find(|o| o.hidden).expect("the checker scene has a hidden light");
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("run.toml");
    std::fs::write(&cfg, lab::synth::run_config(&scan, &desc)).unwrap();
    let mut lights = Vec::new();
    // Three seeds: the 5 seeds measured with the fix ended 1.3–2.6 % off at depth 8 (a consistent +2 % in red),
    // and the failure this guards against was one seed in five with L1.
    for seed in 0..3 {
        let out = dir.path().join(format!("out{seed}"));
        let (code, err) = pipeline(&[
            "run",
            cfg.to_str().unwrap(),
            "--until",
            "object",
            "--set",
            &format!("output.path={}", out.display()),
            "--set",
            &format!("object.seed={seed}"),
        ]);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(out.join("object/materials.json")).unwrap();
        let materials: serde_json::Value = serde_json::from_str(&text).unwrap();
        let fitted = materials["objects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["id"].as_i64() == Some(i64::from(light.id)))
            .expect("the light in materials.json");
        let e: Vec<f64> = fitted["emission"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        lights.push(e);
    }
    for (seed, e) in lights.iter().enumerate() {
        let rel: Vec<f64> = (0..3).map(|c| (e[c] / f64::from(light.emission[c]) - 1.0).abs()).collect();
        eprintln!("seed {seed}: light {e:.3?} (truth {:?}), relative errors {rel:.4?}", light.emission);
        // 5 %: twice the largest error measured over 5 seeds (2.6 %); the L1 loss's failure was 44 %.
        assert!(rel.iter().all(|&r| r < 0.05), "seed {seed}: light {e:?} vs {:?}", light.emission);
    }
}
