//! Determinism and resume: the same seed gives the same result, and a fit stopped at a checkpoint and resumed
//! from its serialised state ends bit-identical to an uninterrupted run.

use pipeline::fit::{FitError, FitInputs, FitOutcome, FitState, ObjectFitSettings};
use std::path::Path;

fn run(
    built: &pipeline::synth::BuiltScene,
    images: &[ingest::photo::LinearImage],
    settings: &ObjectFitSettings,
    resume: Option<FitState>,
    stop_at: Option<u32>,
    saved: &mut Option<String>,
) -> Result<FitOutcome, FitError> {
    let objects = pipeline::synth::fit_objects(built);
    let inputs = FitInputs {
        scene: &built.scene,
        cameras: &built.cameras,
        images,
        objects: &objects,
        settings,
        tracer: &built.settings,
    };
    let mut on_checkpoint = |st: &FitState| {
        *saved = Some(serde_json::to_string(st).unwrap());
        if Some(st.iteration) == stop_at {
            return Err(FitError::Checkpoint("simulated kill".into()));
        }
        Ok(())
    };
    pipeline::fit::fit_objects(&inputs, resume, &mut on_checkpoint, &indicatif::ProgressBar::hidden())
}

#[test]
fn same_seed_same_result_and_resume_equals_uninterrupted() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/small.toml");
    let mut desc = pipeline::synth::load_desc(&path).unwrap();
    // Photos at fewer paths: this test compares runs with each other, not with the truth.
    desc.spp = 64;
    let built = pipeline::synth::build(desc, &path).unwrap();
    let images = pipeline::synth::photos(&built).unwrap();
    let settings = ObjectFitSettings {
        iterations: 12,
        refine_steps: 3,
        checkpoint_every: 4,
        emission_solve_every: 5,
        solve_pixels: 128,
        solve_spp: 8,
        specular_trial_steps: 2,
        ..ObjectFitSettings::default()
    };
    let mut saved = None;
    let a = run(&built, &images, &settings, None, None, &mut saved).unwrap();
    let b = run(&built, &images, &settings, None, None, &mut saved).unwrap();
    assert_eq!(a.params, b.params, "same seed, different result");
    assert_eq!(a.history, b.history);

    let mut saved = None;
    let err = run(&built, &images, &settings, None, Some(8), &mut saved).unwrap_err();
    assert!(matches!(err, FitError::Checkpoint(_)));
    let state: FitState = serde_json::from_str(saved.as_deref().unwrap()).unwrap();
    assert_eq!(state.iteration, 8);
    let resumed = run(&built, &images, &settings, Some(state), None, &mut saved).unwrap();
    assert_eq!(resumed.params, a.params, "resumed run differs from the uninterrupted one");
    assert_eq!(resumed.history, a.history);
    assert_eq!(resumed.per_object, a.per_object);
    // The path-sample counts cover the whole fit, the checkpointed part included.
    assert!(a.traced_paths > 0);
    assert_eq!((resumed.traced_paths, resumed.discarded_samples), (a.traced_paths, a.discarded_samples));

    let other = ObjectFitSettings { seed: 1, ..settings };
    let c = run(&built, &images, &other, None, None, &mut saved).unwrap();
    assert_ne!(c.params, a.params, "the seed must matter");
}
