//! The tone-curve exponent's judge (`optim::photometric::trial_misfit` on comparison fits,
//! `optim::fit::FitMode::Comparison`), on the small room's linear photos, whose true exponent is 1: fitted with
//! only the hidden light free to emit, the photos raised to 0.8 or to 1.25 are explained worse than the photos as
//! they are, and no other object is given an emission.

use optim::fit::{FitMode, ObjectFitSettings};
use std::path::Path;

#[test]
fn comparison_fits_judge_linear_photos_best_at_exponent_one() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/small.toml");
    let built = lab::synth::build(lab::synth::load_desc(&path).unwrap(), &path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let n = built.desc.objects.len();
    let light = built.desc.objects.iter().position(|o| o.hidden).unwrap();
    let emitters: Vec<bool> = (0..n).map(|k| k == light).collect();
    // A third of the default Adam iterations: the misfits at 0.8 and 1.25 are 3.6× and 5.7× the one at 1 with
    // the defaults, and the refinement steps converge the base colours either way.
    let settings = ObjectFitSettings { iterations: 30, ..ObjectFitSettings::default() };
    let sets = optim::fit::pixels::collect(
        &built.scene,
        &built.cameras,
        &images,
        n,
        settings.holdout_fraction,
        settings.holdout_pixels as usize,
        settings.train_pool as usize,
        settings.seed,
    );
    assert!(sets.holdout.len() > 100, "{} held-out pixels", sets.holdout.len());

    let mut misfit = Vec::new();
    for exponent in [0.8, 1.0, 1.25] {
        let mut raised = images.clone();
        workflow::artefacts::preprocess::raise_to_exponent(&mut raised, [exponent; 3]);
        let mode = FitMode::Comparison { emitters: &emitters };
        let out = lab::synth::fit_in_mode(&built, &raised, &settings, mode, None, &mut |_| Ok(()), &optim::NoProgress)
            .unwrap();
        for k in 0..n {
            let e = out.params.emission[k];
            if k == light {
                assert!(e.min_element() > 0.0, "exponent {exponent}: the light lost its emission {e}");
                assert_eq!(out.per_object[k].model, "diffuse+emission");
            } else {
                assert_eq!(e.max_element(), 0.0, "exponent {exponent}: object {k} was given an emission {e}");
                assert_eq!(out.per_object[k].model, "diffuse");
            }
        }
        let m = optim::photometric::trial_misfit(
            &built.scene,
            &built.cameras,
            &out.params,
            &built.settings,
            &sets.holdout,
            exponent,
            settings.holdout_spp,
            settings.seed,
        )
        .unwrap();
        eprintln!("exponent {exponent}: held-out log misfit {:.4e} (R/G/B {:?})", m.value, m.channel);
        assert!(m.value.is_finite() && m.terms > 0);
        misfit.push(m.value);
    }
    assert!(misfit[1] < misfit[0] && misfit[1] < misfit[2], "misfit at 0.8 / 1 / 1.25: {misfit:?}");
}

#[test]
fn a_comparison_fit_needs_one_emitter_flag_per_object() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/small.toml");
    let built = lab::synth::build(lab::synth::load_desc(&path).unwrap(), &path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let emitters = vec![true; built.desc.objects.len() + 1];
    let mode = FitMode::Comparison { emitters: &emitters };
    let err = lab::synth::fit_in_mode(
        &built,
        &images,
        &ObjectFitSettings::default(),
        mode,
        None,
        &mut |_| Ok(()),
        &optim::NoProgress,
    )
    .unwrap_err();
    assert!(err.to_string().contains("emitters"), "{err}");
}
