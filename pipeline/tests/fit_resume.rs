//! Determinism and resume: the same seed gives the same result, and a fit stopped at a checkpoint and resumed
//! from its serialised state ends bit-identical to an uninterrupted run.

mod common;

use optim::fit::{FitError, FitOutcome, FitState, ObjectFitSettings};

fn run(
    built: &lab::synth::BuiltScene,
    images: &[ingest::photo::LinearImage],
    settings: &ObjectFitSettings,
    resume: Option<FitState>,
    stop_at: Option<u32>,
    saved: &mut Option<String>,
) -> Result<FitOutcome, FitError> {
    let mut on_checkpoint = |st: &FitState| {
        *saved = Some(serde_json::to_string(st).unwrap());
        if Some(st.iteration) == stop_at {
            return Err(FitError::Checkpoint("simulated kill".into()));
        }
        Ok(())
    };
    lab::synth::fit_resumable(built, images, settings, resume, &mut on_checkpoint)
}

#[test]
fn same_seed_same_result_and_resume_equals_uninterrupted() {
    // Photos at fewer paths: this test compares runs with each other, not with the truth.
    let (built, images) = common::synth_scene("small", 64);
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

    // A stop requested during model selection (one step into its first phase) ends the fit before any more
    // work, with the checkpoint of the last fit step as the last one written; resumed from it, the fit ends
    // where the uninterrupted run ends.
    let stopping = common::StopAfter::on_phase("model selection");
    let mut last: Option<FitState> = None;
    let err = lab::synth::fit_in_mode(
        &built,
        &images,
        &settings,
        optim::fit::FitMode::Full,
        None,
        &mut |st: &FitState| {
            last = Some(st.clone());
            Ok(())
        },
        &stopping,
    )
    .unwrap_err();
    assert!(matches!(err, FitError::Stopped(_)), "{err}");
    assert!(stopping.asked(), "the stop was never asked for");
    assert_eq!(stopping.positions_after_stop(), 0, "work went on after the stop was requested");
    let last = last.unwrap();
    assert_eq!(last.iteration, settings.iterations + settings.refine_steps, "the last checkpoint is the fit's end");
    let resumed = run(&built, &images, &settings, Some(last), None, &mut saved).unwrap();
    assert_eq!(resumed.params, a.params, "resumed after a stop in model selection, the run differs");
    assert_eq!(resumed.per_object, a.per_object);

    let other = ObjectFitSettings { seed: 1, ..settings };
    let c = run(&built, &images, &other, None, None, &mut saved).unwrap();
    assert_ne!(c.params, a.params, "the seed must matter");
}
