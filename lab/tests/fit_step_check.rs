//! The refinement's step check (`optim::fit::step_check`) on the small room's photos: a step towards the
//! truth is taken whole, a step that makes the fit worse (the light tripled, one wall's albedo at 1) is cut back
//! to a fraction that is not worse than its start, or refused, as a whole or for the objects it harms; a step
//! that is good for all objects but one holds back only that one.

use optim::fit::jacobian::Ctx;
use optim::fit::layout::{self, BASE_COLOR, EMISSION, PER_OBJECT, idx};
use optim::fit::pixels;
use optim::fit::samples::SampleCounter;
use optim::fit::step_check::{HALVINGS, check_step};
use std::path::Path;

fn truth(built: &lab::synth::BuiltScene) -> Vec<f64> {
    layout::from_params(&built.params)
}

/// The small room, its photos' pixel sets (every pixel for training) and a solve draw of 1024 of them (32 per
/// object at least).
fn small_room() -> (lab::synth::BuiltScene, pixels::PixelSets, pixels::WeightedDraw) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data-fixtures/scenes/small.toml");
    let built = lab::synth::build(lab::synth::load_desc(&path).unwrap(), &path).unwrap();
    let images = lab::synth::photos(&built).unwrap();
    let k_count = built.desc.objects.len();
    let sets = pixels::collect(&built.scene, &built.cameras, &images, k_count, 0.0, usize::MAX, usize::MAX, 0);
    let draw = pixels::draw_stratified(&sets.train, 1024, 32, 3, optim::streams::draw::SOLVE_PIXELS, 1);
    (built, sets, draw)
}

/// The fit's context on the built scene, seed 3, counting into `counter`.
fn context<'a>(built: &'a lab::synth::BuiltScene, counter: &'a SampleCounter) -> Ctx<'a> {
    built.fit_context(3, counter)
}

#[test]
fn a_step_towards_the_truth_is_taken_and_a_harmful_one_is_cut_back() {
    let (built, sets, draw) = small_room();
    let k_count = built.desc.objects.len();
    let counter = SampleCounter::default();
    let ctx = context(&built, &counter);
    let x_true = truth(&built);
    let light = (0..k_count).find(|&k| x_true[idx(k, EMISSION)] > 0.0).expect("the small room has a light");
    let wall = (0..k_count).find(|&k| k != light && sets.train_per_object[k] > 200).expect("a wall seen by the photos");

    // From base colours 20 % dark to the truth: better on every object, taken whole.
    let mut start = x_true.clone();
    for k in 0..k_count {
        for c in 0..3 {
            start[idx(k, BASE_COLOR + c)] *= 0.8;
        }
    }
    let mut x = x_true.clone();
    let good = check_step(&ctx, &start, &mut x, &draw, 64, 11).unwrap();
    eprintln!("towards the truth: {good:?}");
    assert_eq!(good.fraction, 1.0);
    assert!(good.fractions.iter().all(|&f| f == 1.0), "{good:?}");
    assert_eq!(x, x_true);
    assert!(good.loss_taken < good.loss_start, "{good:?}");

    // From the truth to a light three times too bright and one wall's albedo at 1: cut back or refused, and
    // the point taken lies on the step at that fraction.
    let mut bad = x_true.clone();
    for c in 0..3 {
        bad[idx(light, EMISSION + c)] *= 3.0;
        bad[idx(wall, BASE_COLOR + c)] = 1.0;
    }
    let mut x = bad.clone();
    let cut = check_step(&ctx, &x_true, &mut x, &draw, 64, 12).unwrap();
    eprintln!("away from the truth: {cut:?}");
    // The light or the wall (or the whole step) is cut back; each object's parameters lie on the step at its own
    // fraction, a power of ½ no larger than the common one, or 0.
    let shares = |f: f64| f == 0.0 || (0..=HALVINGS).any(|i| f == 0.5f64.powi(i as i32));
    assert!(shares(cut.fraction), "{cut:?}");
    assert!(cut.fractions.iter().all(|&f| shares(f) && f <= cut.fraction), "{cut:?}");
    assert!(cut.fractions[light] < 1.0 || cut.fractions[wall] < 1.0, "{cut:?}");
    for i in 0..PER_OBJECT * k_count {
        let expected = x_true[i] + cut.fractions[i / PER_OBJECT] * (bad[i] - x_true[i]);
        assert!((x[i] - expected).abs() <= 1e-12 * expected.abs().max(1.0), "parameter {i}: {} vs {expected}", x[i]);
    }
    // What was taken is not worse than the start by more than the check's noise (a 2-standard-error margin on
    // a paired mean, well below 1 % of the data term at 64 paths with common random numbers).
    assert!(cut.loss_taken <= cut.loss_start * 1.01, "{cut:?}");
}

#[test]
fn a_step_that_harms_one_object_holds_back_only_that_object() {
    let (built, sets, draw) = small_room();
    let k_count = built.desc.objects.len();
    let counter = SampleCounter::default();
    let ctx = context(&built, &counter);
    let x_true = truth(&built);
    // The least-seen object that the photos constrain and that does not emit: its rows are few in the draw.
    let small = (0..k_count)
        .filter(|&k| x_true[idx(k, EMISSION)] == 0.0 && sets.train_per_object[k] >= 16)
        .min_by_key(|&k| sets.train_per_object[k])
        .expect("a seen object that does not emit");
    // From base colours 20 % dark to the truth, except the small object: it starts at its truth and is sent to
    // 40 % of it.
    let mut start = x_true.clone();
    for k in (0..k_count).filter(|&k| k != small) {
        for c in 0..3 {
            start[idx(k, BASE_COLOR + c)] *= 0.8;
        }
    }
    let mut step = x_true.clone();
    for c in 0..3 {
        step[idx(small, BASE_COLOR + c)] *= 0.4;
    }
    let mut x = step.clone();
    let check = check_step(&ctx, &start, &mut x, &draw, 64, 13).unwrap();
    eprintln!("object {small} ({} training pixels) harmed: {check:?}", sets.train_per_object[small]);
    assert!(check.fractions[small] < check.fraction, "{check:?}");
    assert_eq!(check.held_back(), 1, "{check:?}");
    // Every row is rendered at the start, at the whole step and once more to confirm what the rounds that pull
    // the small object back decided; those rounds (at least one, at most `HALVINGS`) render only its own rows.
    assert_eq!(check.fraction, 1.0, "the step as a whole is better: {check:?}");
    let rows = draw.samples.len() as u64;
    let own = draw.samples.iter().filter(|s| s.object == Some(small as u32)).count() as u64;
    let f = check.fractions[small];
    let rounds = if f == 0.0 { u64::from(HALVINGS) } else { (-f.log2()).round() as u64 };
    assert_eq!(counter.paths(), (3 * rows + rounds * own) * 64, "{rounds} rounds: {check:?}");
    for k in (0..k_count).filter(|&k| k != small) {
        for p in 0..PER_OBJECT {
            let i = idx(k, p);
            let expected = start[i] + check.fraction * (step[i] - start[i]);
            assert!((x[i] - expected).abs() <= 1e-12 * expected.abs().max(1.0), "object {k}: {} vs {expected}", x[i]);
        }
    }
}
