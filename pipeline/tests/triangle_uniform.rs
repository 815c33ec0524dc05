//! "Uniform objects stay as they are": on the default scene (data-fixtures/scenes/demo.toml,
//! every object one colour) the per-triangle stage, started from the per-object values, (1) splits no triangle
//! and (2) leaves every triangle of every non-emitting object within a noise-derived tolerance of its object's
//! value. The split test is Holm-corrected at family-wise level `split_significance` = 0.01 per round, so for
//! any seed a round splits a uniform scene with probability ≤ 1 % (≤ 3 % over the 3 split decisions); the run
//! is seeded, so zero is asserted. (3) The assumption behind that guarantee holds on this scene's renders: the
//! split test's p-values of the final state are not smaller than uniform ones (residual noise independent per
//! pixel, the F test calibrated). In-memory scene with 256-path photos; the stage runs with its default settings.
//! A second test starts two objects with a channel at 0 and checks that one round's fit moves it to its truth;
//! a third, that an object the object stage left unconstrained keeps its value through a round's fit.

mod common;

use optim::triangle::{family, pixels, ratio, run_rounds, split};
use workflow::config::TriangleConfig;

#[test]
fn every_triangle_of_a_uniform_object_keeps_the_object_value() {
    // Photo noise: 256 paths per pixel (the fixture's 1024 would only lower it; 256 keeps the test short).
    let (built, images) = common::synth_scene("demo", 256);
    let k = built.desc.objects.len();
    let start = lab::synth::true_triangle_start(&built).unwrap();
    let setup = common::RoundSetup::new(TriangleConfig::default(), k);
    let (config, inputs) = (&setup.config, setup.inputs(&built, &images));
    let bar = optim::NoProgress;
    let out = run_rounds(&inputs, start.clone(), &mut |_| Ok(()), &bar).unwrap();

    // (1) No split: every round marked nothing, the mesh is the scan's.
    let marked: Vec<usize> = out.log.iter().map(|r| r.marked).collect();
    eprintln!("marked per round: {marked:?}");
    assert!(marked.iter().all(|&m| m == 0), "false splits on a uniform scene: {marked:?}");
    assert_eq!(out.triangles, start.triangles);
    // The lobe family look of the final round switched no object: every one is in its true family (Lambert)
    // already. Which objects it looked at is checked below, with the pixels.
    let families = &out.log.last().unwrap().families;
    for f in families {
        eprintln!("lobe family look: {f:?}");
    }
    assert!(families.iter().all(|f| !f.switched), "{families:?}");

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
    // object-level noise (measured: mean 0.0012, worst 0.043, the ceiling, over 3 rounds with the former false
    // splits; mean 0.00068, worst 0.020 in the 1 round the stage now runs). The mean bound sits at half the
    // per-triangle noise, so a stage that passed per-triangle noise through fails it; the worst-case bound is
    // the measured worst with margin for another seed, far below the 0.198 of the unshrunk estimates.
    assert!(mean < 0.01, "mean per-triangle albedo error {mean:.4}: per-triangle noise was not held back");
    assert!(worst < 0.08, "worst per-triangle albedo error {worst:.4}");

    // (3) The split test's p-values on a fresh fit of the final state (render key of a round the stage did not
    // use). Under independent pixel noise each triangle's p (3 × its smallest per-channel p-value, Bonferroni)
    // satisfies P(p < x) ≤ x, so the count below 5 % is at most binomial(m, 0.05): bounded here at its mean + 4
    // standard deviations (a seeded run; exceeding it means the residuals carry structure the test mistakes
    // for texture). Measured: see docs/optim/design-measurements.md.
    let mut state = out.clone();
    let scene = state.scene().unwrap();
    let n = state.triangles.len();
    let pix = pixels::collect(&scene, &built.cameras, &images, n, config.pixels_per_triangle as usize, config.seed);
    let pix = pix.samples;
    // The look looked at every non-emitting object with two halves of pixels (all of them on this scene; the
    // ceiling, in 84, the fewest), and at no other.
    let rows = family::object_rows(&pix, &state.face_object, k, config.family_pixels as usize, config.seed, 0);
    let lookable: Vec<usize> = (0..k)
        .filter(|&o| built.params.emission[o].max_element() <= 0.0 && rows[o].len() / 2 >= family::MIN_HALF)
        .collect();
    assert_eq!(lookable.len() + 1, k, "{lookable:?}");
    assert_eq!(families.iter().map(|f| f.object).collect::<Vec<_>>(), lookable);
    let fitted = ratio::fit_round(&inputs, &scene, &pix, &mut state, config.rounds + 1, &optim::NoProgress).unwrap();
    let ev = split::evidence(state.triangles.len(), &pix, &fitted);
    let p: Vec<f64> = ev.iter().zip(&fitted.free).filter(|(_, f)| **f).filter_map(|(e, _)| e.map(|e| e.p)).collect();
    let m = p.len() as f64;
    let below = p.iter().filter(|&&x| x < 0.05).count() as f64;
    let min = p.iter().copied().fold(1.0f64, f64::min);
    eprintln!("{m} triangles tested: {below} with p < 0.05 (uniform: {:.1}); smallest p {min:.2e}", 0.05 * m);
    // 226 are testable on this scene; far fewer would mean the pixel collection broke and the count says little.
    assert!(m > 100.0, "only {m} triangles testable");
    assert!(below <= 0.05 * m + 4.0 * (0.05 * 0.95 * m).sqrt(), "{below} of {m} triangles with p < 0.05");
}

/// The per-triangle pixel budget: every triangle keeps at most the budget, a triangle within it keeps all its
/// pixels, the kept pixels are a subset of all pixels in the same order, and the split's footprint counts
/// (pixel centres in the best view) are those of all pixels whatever the budget.
#[test]
fn the_pixel_budget_bounds_every_triangle_and_keeps_the_footprint_counts() {
    let (built, images) = common::synth_scene("demo", 16);
    let start = lab::synth::true_triangle_start(&built).unwrap();
    let scene = start.scene().unwrap();
    let n = start.triangles.len();
    let all = pixels::collect(&scene, &built.cameras, &images, n, usize::MAX, 0);
    let budget = 8;
    let capped = pixels::collect(&scene, &built.cameras, &images, n, budget, 0);
    assert_eq!(all.seen, all.samples.len() as u64);
    assert_eq!(capped.seen, all.seen);
    assert_eq!(capped.best_view, all.best_view);
    let count = |s: &[pixels::TriSample]| {
        let mut c = vec![0usize; n];
        for x in s {
            c[x.tri as usize] += 1;
        }
        c
    };
    let (c_all, c_cap) = (count(&all.samples), count(&capped.samples));
    let mut over = 0;
    for t in 0..n {
        assert_eq!(c_cap[t], c_all[t].min(budget), "triangle {t}: {} of {} pixels kept", c_cap[t], c_all[t]);
        over += usize::from(c_all[t] > budget);
    }
    assert!(over > 0, "no triangle has more than {budget} pixels: the budget was not exercised");
    // A subset, in (view, row, column) order.
    let key = |s: &pixels::TriSample| (s.pixel.view, s.pixel.y, s.pixel.x);
    assert!(capped.samples.windows(2).all(|w| key(&w[0]) < key(&w[1])));
    let full: std::collections::HashSet<_> = all.samples.iter().map(key).collect();
    assert!(capped.samples.iter().all(|s| full.contains(&key(s))));
    // Per view, the best view's count is the largest count of any view.
    for t in 0..n {
        let mut per_view = std::collections::HashMap::new();
        for s in all.samples.iter().filter(|s| s.tri as usize == t) {
            *per_view.entry(s.pixel.view).or_insert(0u32) += 1;
        }
        assert_eq!(all.best_view[t], per_view.values().copied().max().unwrap_or(0));
    }
}

/// A base colour channel at exactly 0 is not a fixed point of the ratio steps: on the default scene, started
/// from the true values but with the west wall's red (truth 0.30) and the first box's blue (truth 0.20) set to 0
/// on every triangle, as an object stage that fitted a channel to its lower bound leaves them, one round's
/// fit (3 ratio steps at the stage's defaults) brings each back near its truth. A multiplicative step ρ·T/R
/// alone keeps both at 0.
#[test]
fn a_channel_the_object_stage_left_at_zero_is_fitted_back() {
    let (built, images) = common::synth_scene("demo", 256);
    let k = built.desc.objects.len();
    let mut state = lab::synth::true_triangle_start(&built).unwrap();
    let label = |o: usize| built.desc.objects[o].label.as_str();
    let wall = (0..k).find(|&o| label(o) == "wall west").unwrap();
    let boxed = (0..k).find(|&o| label(o) == "box").unwrap();
    let zeroed = [(wall, 0usize), (boxed, 2usize)];
    for (t, m) in state.materials.iter_mut().enumerate() {
        for &(o, c) in &zeroed {
            if state.face_object[t] as usize == o {
                m.base_color[c] = 0.0;
            }
        }
    }
    let setup = common::RoundSetup::new(TriangleConfig::default(), k);
    let (config, inputs) = (&setup.config, setup.inputs(&built, &images));
    let scene = state.scene().unwrap();
    let n = state.triangles.len();
    let pix = pixels::collect(&scene, &built.cameras, &images, n, config.pixels_per_triangle as usize, config.seed);
    ratio::fit_round(&inputs, &scene, &pix.samples, &mut state, 0, &optim::NoProgress).unwrap();
    for &(o, c) in &zeroed {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for (t, m) in state.materials.iter().enumerate().filter(|(t, _)| state.face_object[*t] as usize == o) {
            assert!(m.base_color[c] > 0.0, "{}: triangle {t} kept channel {c} at 0", label(o));
            sum += f64::from(m.base_color[c]);
            n += 1;
        }
        let (mean, truth) = (sum / n as f64, f64::from(built.params.materials[o].base_color[c]));
        eprintln!("{} channel {c}: 0 → {mean:.4} over {n} triangles (truth {truth:.2})", label(o));
        // Within 0.03 of the truth: a tenth of it and 25 times the object-level noise of this scene (0.0012,
        // measured in the test above); a channel stuck at 0 or still climbing from the floor is far outside.
        assert!((mean - truth).abs() < 0.03, "{} channel {c}: {mean:.4} for a truth of {truth}", label(o));
    }
}

/// An object the object stage left unconstrained (too few pixels for its material, so its value is an estimate
/// weighed against a prior) keeps that value through a round's ratio steps, while a constrained one started as
/// far off is fitted: on the default scene, started from the true values but with the east and west walls at
/// grey 0.5, only the west wall marked unconstrained.
#[test]
fn an_unconstrained_object_keeps_its_value_through_the_ratio_steps() {
    let (built, images) = common::synth_scene("demo", 256);
    let k = built.desc.objects.len();
    let mut state = lab::synth::true_triangle_start(&built).unwrap();
    let label = |o: usize| built.desc.objects[o].label.as_str();
    let west = (0..k).find(|&o| label(o) == "wall west").unwrap();
    let east = (0..k).find(|&o| label(o) == "wall east").unwrap();
    let grey = glam::Vec3::splat(0.5);
    for (t, m) in state.materials.iter_mut().enumerate() {
        if [west, east].contains(&(state.face_object[t] as usize)) {
            m.base_color = grey;
        }
    }
    let setup = common::RoundSetup::new(TriangleConfig::default(), k).unconstrained(west);
    let (config, inputs) = (&setup.config, setup.inputs(&built, &images));
    let scene = state.scene().unwrap();
    let n = state.triangles.len();
    let pix = pixels::collect(&scene, &built.cameras, &images, n, config.pixels_per_triangle as usize, config.seed);
    let fitted = ratio::fit_round(&inputs, &scene, &pix.samples, &mut state, 0, &optim::NoProgress).unwrap();
    let face_object = &state.face_object;
    let of = |o: usize| (0..n).filter(move |&t| face_object[t] as usize == o).collect::<Vec<_>>();
    for t in of(west) {
        assert_eq!(state.materials[t].base_color, grey, "west wall triangle {t}");
        assert!(!fitted.free[t], "west wall triangle {t} counted as fitted");
    }
    // The east wall (truth 0.75 / 0.70 / 0.45, 0.50 from grey summed over the channels) leaves grey: less than
    // half of that distance is left (the grey west wall, held, still bounces the wrong colour onto it).
    let truth = built.params.materials[east].base_color;
    let east_tris = of(east);
    let mean = east_tris.iter().map(|&t| state.materials[t].base_color).sum::<glam::Vec3>() / east_tris.len() as f32;
    let (left, start) = ((mean - truth).abs().element_sum(), (grey - truth).abs().element_sum());
    eprintln!("east wall: grey → {mean:?} (truth {truth:?}), L1 sum {start:.3} → {left:.3}");
    assert!(left < 0.5 * start, "{mean:?} against {truth:?}");
}
