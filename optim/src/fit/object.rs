//! The per-object fit loop: initial emission solve, Adam on base colour with periodic emission re-solves,
//! Gauss–Newton refinement, model selection. See the module docs of [`crate::fit`].

use super::adam::{AdamConfig, AdamState};
use super::emission_solve::{Unknowns, solve_step_pinned};
use super::jacobian::Ctx;
use super::layout::{self, BASE_COLOR, EMISSION, PER_OBJECT, idx};
use super::pixels::{self, PixelSets};
use super::prior::UnseenPrior;
use super::samples::{self, SampleCounter};
use super::settings::AdamLoss;
use super::solve::{self, MIN_PIXELS, solve_options, step_samples};
use super::{
    FitError, FitInputs, FitMode, FitOutcome, FitState, IterationRecord, ObjectFitSettings, ObjectModel, select,
    step_check,
};
use crate::streams::{draw, key};
use glam::Vec3;
use tracer::PixelRef;

fn validate(inputs: &FitInputs<'_>) -> Result<(), FitError> {
    let s = inputs.settings;
    if inputs.images.len() != inputs.cameras.len() {
        return Err(FitError::ImageCount { cameras: inputs.cameras.len(), images: inputs.images.len() });
    }
    for (view, (c, i)) in inputs.cameras.iter().zip(inputs.images).enumerate() {
        if c.width != i.width || c.height != i.height {
            return Err(FitError::ImageSize {
                view,
                got_w: i.width,
                got_h: i.height,
                want_w: c.width,
                want_h: c.height,
            });
        }
    }
    if inputs.scene.material_slots() > inputs.objects.len() || inputs.scene.emitter_slots() > inputs.objects.len() {
        return Err(FitError::ObjectCount { slots: inputs.scene.material_slots(), objects: inputs.objects.len() });
    }
    let positive = |key: &'static str, v: u32| {
        if v == 0 { Err(FitError::Setting { key, message: "must be ≥ 1".into() }) } else { Ok(()) }
    };
    positive("batch_pixels", s.batch_pixels)?;
    positive("n_value", s.n_value)?;
    positive("n_grad", s.n_grad)?;
    positive("solve_pixels", s.solve_pixels)?;
    positive("solve_spp", s.solve_spp)?;
    positive("interim_solve_spp", s.interim_solve_spp)?;
    positive("check_spp", s.check_spp)?;
    positive("holdout_spp", s.holdout_spp)?;
    positive("holdout_pixels", s.holdout_pixels)?;
    if !(s.lr.is_finite() && s.lr > 0.0) {
        return Err(FitError::Setting { key: "lr", message: format!("{} is not a positive number", s.lr) });
    }
    if !(s.lr_final_fraction > 0.0 && s.lr_final_fraction <= 1.0) {
        return Err(FitError::Setting { key: "lr_final_fraction", message: "must lie in (0, 1]".into() });
    }
    if !(s.emission_l1.is_finite() && s.emission_l1 >= 0.0) {
        return Err(FitError::Setting { key: "emission_l1", message: "must be finite and ≥ 0".into() });
    }
    if !(0.0..0.5).contains(&s.holdout_fraction) {
        return Err(FitError::Setting { key: "holdout_fraction", message: "must lie in [0, 0.5)".into() });
    }
    if let FitMode::Comparison { emitters } = inputs.mode {
        if emitters.len() != inputs.objects.len() {
            return Err(FitError::Setting {
                key: "emitters",
                message: format!("{} flags for {} objects", emitters.len(), inputs.objects.len()),
            });
        }
    }
    Ok(())
}

/// Learning rate of Adam iteration `it` (1-based): geometric decay from `lr` to `lr · lr_final_fraction`.
#[must_use]
pub(crate) fn learning_rate(s: &ObjectFitSettings, it: u32) -> f64 {
    let t = if s.iterations <= 1 { 0.0 } else { f64::from(it - 1) / f64::from(s.iterations - 1) };
    s.lr * s.lr_final_fraction.powf(t)
}

pub(crate) fn record(x: &[f64], iteration: u32, phase: &str, loss: f64, lr: f64) -> IterationRecord {
    let n = x.len() / PER_OBJECT;
    let v3 = |k: usize, p: usize| [x[idx(k, p)], x[idx(k, p + 1)], x[idx(k, p + 2)]];
    IterationRecord {
        iteration,
        phase: phase.into(),
        loss,
        lr,
        base_color: (0..n).map(|k| v3(k, BASE_COLOR)).collect(),
        emission: (0..n).map(|k| v3(k, EMISSION)).collect(),
        step_fraction: 1.0,
    }
}

/// dLoss/dI of one pixel (per channel) for the difference `d` = I − I_target; see [`AdamLoss`].
#[must_use]
pub fn loss_weight(s: &ObjectFitSettings, d: Vec3, target: Vec3) -> Vec3 {
    let sign = |x: f32| {
        if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        }
    };
    match s.loss {
        AdamLoss::L1 => Vec3::new(sign(d.x), sign(d.y), sign(d.z)),
        AdamLoss::Huber => {
            // The corner never shrinks below 1e-6 (in image units) so black target pixels stay finite.
            let delta = (target.abs() * s.huber_delta as f32).max(Vec3::splat(1e-6));
            (d / delta).clamp(Vec3::splat(-1.0), Vec3::splat(1.0))
        }
    }
}

/// One Adam iteration on the parameters whose `lr_mask` entry is non-zero: L1 loss on a uniform batch,
/// independent value (`n_value`) and gradient (`n_grad`) paths. Returns the batch loss before the step.
pub(crate) fn adam_iteration(
    ctx: &Ctx<'_>,
    s: &ObjectFitSettings,
    train: &PixelSets,
    x: &mut [f64],
    adam: &mut AdamState,
    lr_mask: &[f64],
    lr: f64,
    key: u64,
) -> Result<f64, FitError> {
    let k_count = x.len() / PER_OBJECT;
    let batch = train.draw_train(s.batch_pixels as usize, ctx.seed, draw::BATCH, key);
    let pix: Vec<PixelRef> = batch.iter().map(|b| b.pixel).collect();
    let params = ctx.params(x);
    let values = ctx.render(&params, &pix, s.n_value, key)?;
    let b = batch.len().max(1) as f32;
    let mut loss = 0.0;
    let weights: Vec<Vec3> = values
        .iter()
        .zip(&batch)
        .map(|(v, t)| {
            let d = *v - t.target;
            loss += f64::from(d.abs().element_sum()) / (3.0 * f64::from(b));
            loss_weight(s, d, t.target) / b
        })
        .collect();
    let g = ctx.gradient(&params, &pix, &weights, s.n_grad, key)?;
    let grad = layout::flatten_grads(&g, k_count);
    // The tracer discards non-finite samples (counted in `ctx.samples`), so a non-finite gradient or loss here
    // is a bug (e.g. a non-finite weight), not an overflowing path: it aborts the fit.
    if !grad.iter().all(|v| v.is_finite()) || !loss.is_finite() {
        return Err(FitError::NonFinite { what: "gradient or loss", iteration: key as u32 });
    }
    let lrs: Vec<f64> = lr_mask.iter().map(|m| m * lr).collect();
    let (lo, hi) = layout::bounds(k_count);
    adam.step(x, &grad, &lrs, &lo, &hi);
    Ok(loss)
}

/// Runs the fit; see [`crate::fit`]. `resume` continues a checkpointed run; `on_checkpoint` is called every
/// `checkpoint_every` steps and at the end of each phase.
pub fn fit_objects(
    inputs: &FitInputs<'_>,
    resume: Option<FitState>,
    on_checkpoint: &mut dyn FnMut(&FitState) -> Result<(), FitError>,
    progress: &dyn crate::Progress,
) -> Result<FitOutcome, FitError> {
    validate(inputs)?;
    let s = inputs.settings;
    let k_count = inputs.objects.len();
    let samples = match &resume {
        Some(st) => SampleCounter::starting_at(st.traced_paths, st.discarded_samples),
        None => SampleCounter::default(),
    };
    let ctx = Ctx {
        scene: inputs.scene,
        cameras: inputs.cameras,
        settings: inputs.tracer,
        seed: s.seed,
        samples: &samples,
        split: &crate::fit::layout::NO_SPLIT,
    };
    let sets = pixels::collect(
        inputs.scene,
        inputs.cameras,
        inputs.images,
        k_count,
        s.holdout_fraction,
        s.holdout_pixels as usize,
        s.train_pool as usize,
        s.seed,
    );
    if sets.train.is_empty() {
        return Err(FitError::NoPixels);
    }
    let free: Vec<bool> = sets.train_per_object.iter().map(|&n| n >= MIN_PIXELS).collect();
    // Every base colour is an unknown of Adam and of the refinement, also those of objects no photo sees: they
    // are reached through the light they reflect onto the ones the photos see (`prior`).
    let every = vec![true; k_count];
    // A comparison fit holds every object outside its emitter set at zero emission in every solve.
    let no_emission: Vec<bool> = match inputs.mode {
        FitMode::Full => vec![false; k_count],
        FitMode::Comparison { emitters } => emitters.iter().map(|&e| !e).collect(),
    };
    let total = s.iterations + s.refine_steps;

    let mut state = match resume {
        Some(st) => {
            if st.params.len() != PER_OBJECT * k_count || st.adam.m.len() != st.params.len() {
                return Err(FitError::BadCheckpoint(format!("{} parameters for {k_count} objects", st.params.len())));
            }
            st
        }
        None => {
            let mut x = layout::initial(k_count);
            let opts = solve_options(s, Unknowns::Emission);
            let samples = step_samples(&sets, s, Unknowns::Emission, s.seed, key::SOLVE);
            let spp = solve::adam_solve_spp(s, 0);
            solve_step_pinned(&ctx, &mut x, &samples, spp, key::SOLVE, &free, &no_emission, &opts)?;
            FitState {
                iteration: 0,
                adam: AdamState::new(x.len(), AdamConfig::default()),
                params: x,
                history: Vec::new(),
                traced_paths: 0,
                discarded_samples: 0,
            }
        }
    };
    // Two phases, each with its own progress: the Adam iterations, then the refinement steps.
    let announce = |iteration: u32| {
        if iteration < s.iterations {
            progress.phase("Adam: iteration", u64::from(s.iterations), u64::from(iteration));
        } else if iteration < total {
            progress.phase("refinement: step", u64::from(s.refine_steps), u64::from(iteration - s.iterations));
        }
    };
    announce(state.iteration);

    // Adam learns the base colours; emission is solved, the lobe parameters are tried in `select`.
    let mut lr_mask = vec![0.0; PER_OBJECT * k_count];
    for k in 0..k_count {
        for c in 0..3 {
            lr_mask[idx(k, BASE_COLOR + c)] = 1.0;
        }
    }
    while state.iteration < total {
        let it = state.iteration + 1;
        let rec = if it <= s.iterations {
            let lr = learning_rate(s, it);
            let loss = adam_iteration(&ctx, s, &sets, &mut state.params, &mut state.adam, &lr_mask, lr, u64::from(it))?;
            if s.emission_solve_every > 0 && it % s.emission_solve_every == 0 && it < s.iterations {
                // The solve costs as much as hundreds of iterations on a large scan: say so while it runs.
                progress.set_message("emission solve");
                let key = key::SOLVE + u64::from(it);
                let samples = step_samples(&sets, s, Unknowns::Emission, s.seed, key);
                solve_step_pinned(
                    &ctx,
                    &mut state.params,
                    &samples,
                    solve::adam_solve_spp(s, it),
                    key,
                    &free,
                    &no_emission,
                    &solve_options(s, Unknowns::Emission),
                )?;
            }
            record(&state.params, it, "adam", loss, lr)
        } else {
            let key = key::REFINE + u64::from(it);
            let samples = step_samples(&sets, s, Unknowns::EmissionAndBaseColor, s.seed, key);
            let opts = solve_options(s, Unknowns::EmissionAndBaseColor);
            let start = state.params.clone();
            let loss =
                solve_step_pinned(&ctx, &mut state.params, &samples, s.solve_spp, key, &every, &no_emission, &opts)?;
            let check = step_check::check_step(
                &ctx,
                &start,
                &mut state.params,
                &samples,
                solve::check_spp(s),
                key::REFINE_CHECK + u64::from(it),
            )?;
            if check.fraction < 1.0 || check.held_back() > 0 {
                tracing::debug!(
                    iteration = it,
                    fraction = check.fraction,
                    held_back = check.held_back(),
                    loss_start = check.loss_start,
                    loss_taken = check.loss_taken,
                    "refinement step shortened: the full step was significantly worse on its own pixels, or on some objects' own"
                );
            }
            IterationRecord { step_fraction: check.fraction, ..record(&state.params, it, "refine", loss, 0.0) }
        };
        if !state.params.iter().all(|v| v.is_finite()) {
            return Err(FitError::NonFinite { what: "parameter", iteration: it });
        }
        tracing::debug!(
            iteration = it,
            phase = %rec.phase,
            loss = rec.loss,
            discarded_samples = samples.discarded(),
            "fit step"
        );
        let loss = rec.loss;
        state.history.push(rec);
        state.iteration = it;
        state.traced_paths = samples.paths();
        state.discarded_samples = samples.discarded();
        // The position first, then the message: a message that ends an emission solve is logged at once, and
        // its line then carries the rate with the solve in it.
        if it <= s.iterations {
            progress.set_position(u64::from(it));
        } else {
            progress.set_position(u64::from(it - s.iterations));
        }
        progress.set_message(&format!("loss {loss:.4}"));
        if it == s.iterations {
            announce(it);
        }
        let phase_end = it == s.iterations || it == total;
        let stop = progress.stop_requested();
        if (s.checkpoint_every > 0 && it % s.checkpoint_every == 0) || phase_end || stop {
            on_checkpoint(&state)?;
        }
        if stop {
            return Err(FitError::Interrupted { iteration: it });
        }
    }
    // Model selection keeps no checkpoint of its own: the one written after the last step is where a rerun
    // resumes.
    if progress.stop_requested() {
        return Err(FitError::Interrupted { iteration: state.iteration });
    }

    let x = average_refinement(&state, s);
    let (mut x, mut per_object, split) = match inputs.mode {
        FitMode::Full => select::choose_models(&ctx, s, &sets, &x, &free, progress)?,
        FitMode::Comparison { .. } => {
            let per_object = (0..k_count)
                .map(|k| {
                    let emits = (0..3).any(|c| x[idx(k, EMISSION + c)] > 0.0);
                    ObjectModel {
                        model: if emits { "diffuse+emission" } else { "diffuse" }.into(),
                        why: "comparison fit: emission on the given objects only, no model selection".into(),
                        constrained: free[k],
                    }
                })
                .collect();
            (x, per_object, layout::Split::default())
        }
    };
    // Everything after model selection renders with the emitters it split at the horizon.
    let ctx = Ctx { split: &split, ..ctx };
    // The unseen objects' estimates, weighed against the prior by their standard errors (`prior`).
    let prior = UnseenPrior::new(inputs.scene, inputs.objects, &free);
    let unseen = if inputs.mode == FitMode::Full { prior.unseen() } else { Vec::new() };
    if !unseen.is_empty() {
        progress.phase(&format!("unseen objects: standard errors of {} base colours, step", unseen.len()), 1, 0);
        let draw = step_samples(&sets, s, Unknowns::Emission, s.seed, key::UNSEEN_PRIOR);
        let averaged = (s.refine_steps - s.refine_steps / 2) as usize;
        let se = super::prior::standard_errors(&ctx, &x, &draw, s.solve_spp, key::UNSEEN_PRIOR, &unseen, averaged)?;
        progress.set_position(1);
        for (&k, se) in unseen.iter().zip(se) {
            let p = prior.prior(&x, k);
            let estimate = layout::base_color(&x, k);
            let (rho, weight) = super::prior::combine(estimate, se, &p);
            for c in 0..3 {
                x[idx(k, BASE_COLOR + c)] = rho[c];
            }
            let text = super::prior::describe(rho, estimate, se, weight, &p);
            tracing::info!(object = k, "{text}");
            per_object[k].why = format!("{}; {text}", per_object[k].why);
        }
    }
    // No non-finite parameter is ever clamped away silently: like every step above, the model selection's
    // result is checked and a non-finite value aborts the fit (tests/stability_extremes.rs). Non-finite path
    // samples are the one thing discarded, by the tracer, and they are counted and bounded below.
    if !x.iter().all(|v| v.is_finite()) {
        return Err(FitError::NonFinite { what: "parameter after model selection", iteration: total });
    }
    let (traced_paths, discarded_samples) = (samples.paths(), samples.discarded());
    if discarded_samples > 0 {
        tracing::warn!(
            discarded_samples,
            traced_paths,
            "the tracer discarded {discarded_samples} of {traced_paths} path samples as non-finite (f32 overflow)"
        );
    } else {
        tracing::info!(traced_paths, "fit finished; no path sample was discarded");
    }
    if !samples::within_bound(discarded_samples, traced_paths) {
        return Err(FitError::TooManyDiscarded { discarded: discarded_samples, paths: traced_paths });
    }
    Ok(FitOutcome {
        params: split.params(&x),
        history: state.history,
        per_object,
        traced_paths,
        discarded_samples,
        train_pixels: sets.train_total(),
        holdout_pixels: sets.holdout.len(),
    })
}

/// The parameters after the fit: once the Gauss–Newton steps have converged they scatter around the solution
/// by the Monte Carlo noise of their Jacobians (±1–2 % on the small room), so base colour and emission are
/// averaged over the second half of the refinement steps (Polyak–Ruppert averaging), read from the history.
fn average_refinement(state: &FitState, s: &ObjectFitSettings) -> Vec<f64> {
    let mut x = state.params.clone();
    let tail: Vec<&IterationRecord> = state
        .history
        .iter()
        .filter(|h| h.phase == "refine" && h.iteration > s.iterations + s.refine_steps / 2)
        .collect();
    if tail.len() < 2 {
        return x;
    }
    let n = tail.len() as f64;
    for k in 0..x.len() / PER_OBJECT {
        for c in 0..3 {
            x[idx(k, BASE_COLOR + c)] = tail.iter().map(|h| h.base_color[k][c]).sum::<f64>() / n;
            x[idx(k, EMISSION + c)] = tail.iter().map(|h| h.emission[k][c]).sum::<f64>() / n;
        }
    }
    x
}
