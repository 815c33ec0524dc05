//! The `object` stage: per-object material and emission fit ([`optim::fit::fit_objects`]) on the ingested
//! mesh and the prepared photos, with checkpoints so an interrupted run resumes where it stopped. When the
//! photos' calibration left the tone curve's exponent open, the fit is followed by a measurement of that exponent
//! against its renders (`optim::photometric`): comparison fits of the photos raised to a few exponents, with
//! emission only on the first fit's lights, are compared by their held-out log misfit, the search settles on the
//! best, and a whole fit of the photos raised to it is the result; the exponent goes to `photometric.json` for
//! the later stages.
//!
//! Artefacts in `output.path/object/`:
//! - `materials.json` — the result in the `ipt-materials/1` schema ([`crate::materials`]);
//! - `history.json` — `{"format": "ipt-object-history/1", "history": [...], "why": [...], "traced_paths",
//!   "discarded_samples"}`: the fit's per-iteration trajectory, each object's model decision, and how many
//!   path samples the fit traced and how many of them the tracer discarded as non-finite;
//! - `checkpoint.json` while the stage runs — `{"format": "ipt-object-checkpoint/3", "config_sha256",
//!   "inputs_sha256", "state"}`, rewritten atomically at every checkpoint the fit hands out and deleted once
//!   the outputs above are written. A rerun resumes from it only when both hashes match the current run
//!   (same config section, same inputs), so a stale checkpoint is never mixed into a different fit.

use std::path::PathBuf;

use crate::artefacts::checkpoint;
use crate::artefacts::ingest::Ingested;
use crate::artefacts::object::{
    CHECKPOINT_FORMAT, ExponentRound, HISTORY_FILE, HISTORY_FORMAT, HistoryFile, MATERIALS_FILE, PHOTOMETRIC_FILE,
    PHOTOMETRIC_FORMAT, PhotometricFile, SearchEmitter,
};
use crate::artefacts::preprocess::{CalibrationFile, Prepared, raise_to_exponent};
use crate::atomic_file::write_json_atomic;
use crate::config::profile_name;
use crate::materials::{HorizonEmission, MATERIALS_FORMAT, MaterialsFile, ObjectMaterial};
use crate::stage_contract::{StageContext, StageError};
use optim::fit::{FitError, FitInputs, FitMode, FitOutcome, FitState, ObjectDesc};
use optim::photometric::NextExponent;

/// The exponent is judged on held-out pixels; a config with no held-out pixels still gets this share.
const EXPONENT_HOLDOUT_FRACTION: f64 = 0.1;

/// Runs the stage.
pub fn run(ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
    let plan = ctx.plan;
    let scene_data = Ingested::read(&plan.output)?;
    let prepared = Prepared::read(&plan.output)?;
    let scene = tracer::Scene::new(scene_data.scene_input())?;
    let cameras = prepared.tracer_cameras();
    let tris = scene_data.object_triangles();
    let objects: Vec<ObjectDesc> = scene_data
        .objects
        .iter()
        .zip(&tris)
        .enumerate()
        .map(|(i, (o, t))| ObjectDesc { id: o.id, label: scene_data.label(i), triangles: t.clone() })
        .collect();
    let settings = plan.tracer.settings();
    let calibration = CalibrationFile::read(&plan.output)?;
    // The photos' calibration may leave the tone curve's exponent open; linear light transport then decides it.
    let search = calibration.as_ref().is_some_and(|c| !c.exponent_reliable);
    // One fit of the photos raised to `exponent`. Only the first whole fit checkpoints: the others fit
    // re-exponentiated photos, which a checkpoint of the first must never resume (the first replays
    // deterministically on a resumed run).
    let fit_at = |exponent: f64, mode: FitMode<'_>, checkpointed: bool| -> Result<FitOutcome, StageError> {
        let raised;
        let images = if exponent == 1.0 {
            &prepared.images
        } else {
            let mut copy = prepared.images.clone();
            raise_to_exponent(&mut copy, [exponent; 3]);
            raised = copy;
            &raised
        };
        let inputs = FitInputs {
            scene: &scene,
            cameras: &cameras,
            images,
            objects: &objects,
            settings: &plan.object,
            tracer: &settings,
            mode,
        };
        let resume: Option<FitState> = if checkpointed { checkpoint::resumable(ctx, CHECKPOINT_FORMAT) } else { None };
        if let Some(state) = &resume {
            ctx.note(&format!("resuming from the checkpoint at iteration {}", state.iteration));
        }
        let mut on_checkpoint = |state: &FitState| -> Result<(), FitError> {
            if checkpointed {
                checkpoint::write(ctx, CHECKPOINT_FORMAT, state).map_err(|e| FitError::Checkpoint(e.to_string()))?;
                tracing::debug!(iteration = state.iteration, "checkpoint written");
            }
            Ok(())
        };
        let label = match (search, mode) {
            (false, _) => "fit".to_owned(),
            (true, FitMode::Full) => format!("fit (photos ^ {exponent:.3})"),
            (true, FitMode::Comparison { .. }) => format!("comparison fit (photos ^ {exponent:.3})"),
        };
        let progress = ctx.progress(&label, u64::from(plan.object.iterations));
        Ok(optim::fit::fit_objects(&inputs, resume, &mut on_checkpoint, progress.as_ref())?)
    };
    let first = fit_at(1.0, FitMode::Full, true)?;
    let mut exponent = 1.0f64;
    let mut search_record = None;
    let outcome = if search {
        // The trials are comparison fits with the first whole fit's lights only. With every object free to
        // emit, the L1-penalised solve leaves faint emissions on walls, more of them the lower the exponent (7
        // at 1.0, 1 at 1.56 on the consumer-camera fixture), and such a glow flattens compressed contrast as
        // higher albedos do, which biased the judge low; model selection, which removes them at the right
        // exponent, keeps some at a wrong one and flips between neighbouring exponents. So the emitters whose
        // emission is a small share of what the photos show of them are left out
        // (docs/photo/self-calibration.md, "Comparison fits").
        let sets = optim::fit::pixels::collect(
            &scene,
            &cameras,
            &prepared.images,
            objects.len(),
            plan.object.holdout_fraction.max(EXPONENT_HOLDOUT_FRACTION),
            plan.object.holdout_pixels as usize,
            plan.object.train_pool as usize,
            plan.object.seed,
        );
        // The objects' own emission entries (a split emitter's sky half; its ground half follows the objects').
        let own = &first.params.emission[..objects.len().min(first.params.emission.len())];
        let (emitters, shares) = optim::photometric::comparison_emitters(own, &sets);
        let record: Vec<SearchEmitter> = shares
            .iter()
            .map(|e| SearchEmitter {
                id: objects[e.object].id,
                label: objects[e.object].label.clone(),
                share: e.share,
                light: e.light,
            })
            .collect();
        let described: Vec<String> = record
            .iter()
            .map(|e| {
                let share =
                    e.share.map_or("unseen".to_owned(), |s| format!("emission {:.0} % of its radiance", 100.0 * s));
                format!("{} (id {}, {share}{})", e.label, e.id, if e.light { "" } else { ", left out" })
            })
            .collect();
        ctx.note(&format!(
            "tone-curve exponent search: comparison fits with emission on {} of {} objects; the whole fit's emitters: {}",
            emitters.iter().filter(|&&e| e).count(),
            objects.len(),
            if described.is_empty() { "none".to_owned() } else { described.join(", ") }
        ));
        let mut rounds: Vec<ExponentRound> = Vec::new();
        loop {
            let trial = fit_at(exponent, FitMode::Comparison { emitters: &emitters }, false)?;
            // Every trial is judged with the same random numbers on the same pixels (the held-out set depends on
            // the photos' validity masks only).
            let m = optim::photometric::trial_misfit(
                &scene,
                &cameras,
                &trial.params,
                &settings,
                &sets.holdout,
                exponent,
                plan.object.holdout_spp,
                plan.object.seed,
            )?;
            let misfit = m.channel;
            // Each channel's misfit relative to its first trial, and the mean of the three: the darkest
            // channel's log misfit is the largest and the noisiest, so summed it would decide alone.
            let reference = rounds.first().map_or(misfit, |r| r.misfit);
            let criterion = optim::photometric::relative_mean(misfit, reference);
            rounds.push(ExponentRound { exponent, misfit, criterion, terms: m.terms });
            ctx.note(&format!(
                "tone-curve exponent {exponent:.3}: held-out log misfit {} (R / G / B, {} terms), relative {criterion:.4}",
                misfit.map(|v| format!("{v:.4e}")).join(" / "),
                m.terms
            ));
            let trials: Vec<(f64, f64)> = rounds.iter().map(|r| (r.exponent, r.criterion)).collect();
            match optim::photometric::next_exponent(&trials) {
                NextExponent::Try(e) => exponent = e,
                NextExponent::Final(e) => {
                    exponent = e;
                    break;
                }
            }
        }
        search_record = Some((rounds, record));
        if exponent == 1.0 {
            ctx.note("exponent 1 kept: the first whole fit is the final one");
            first
        } else {
            fit_at(exponent, FitMode::Full, false)?
        }
    } else {
        first
    };
    let mut outputs = Vec::new();
    if let Some((rounds, emitters)) = search_record {
        let file = PhotometricFile { format: PHOTOMETRIC_FORMAT.into(), exponent: [exponent; 3], emitters, rounds };
        write_json_atomic(&ctx.dir.join(PHOTOMETRIC_FILE), &file)?;
        outputs.push(PathBuf::from("object").join(PHOTOMETRIC_FILE));
        ctx.note(&format!("photos raised to the exponent {exponent:.3} for the final fit and every later stage"));
    }

    // An emitter split at the horizon is written with both halves and, as its `emission`, the uniform radiance
    // of the same flux (the materials.json schema).
    let horizon = &outcome.params.horizon;
    let uniform = if horizon.ground.iter().any(Option::is_some) {
        outcome.params.uniform_emission(&scene.horizon_geometry(horizon.up))
    } else {
        outcome.params.emission.clone()
    };
    let materials = MaterialsFile {
        format: MATERIALS_FORMAT.into(),
        emission_profile: plan.tracer.emission_profile,
        objects: objects
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let m = outcome.params.materials[i];
                let e = uniform[i];
                let split = HorizonEmission::of_slot(horizon, &outcome.params.emission, i);
                ObjectMaterial {
                    id: o.id,
                    label: o.label.clone(),
                    triangles: o.triangles.len(),
                    base_color: m.base_color.to_array(),
                    roughness: m.roughness,
                    metallic: m.metallic,
                    specular: m.specular,
                    emission: e.to_array(),
                    model: outcome.per_object.get(i).map(|p| p.model.clone()).unwrap_or_default(),
                    why: outcome.per_object.get(i).map(|p| p.why.clone()),
                    constrained: outcome.per_object.get(i).map(|p| p.constrained),
                    horizon: split,
                }
            })
            .collect(),
    };
    let history = HistoryFile {
        format: HISTORY_FORMAT.into(),
        history: outcome.history.iter().map(|h| serde_json::to_value(h).unwrap_or(serde_json::Value::Null)).collect(),
        why: outcome.per_object.iter().map(|p| p.why.clone()).collect(),
        traced_paths: outcome.traced_paths,
        discarded_samples: outcome.discarded_samples,
        train_pixels: outcome.train_pixels,
        holdout_pixels: outcome.holdout_pixels,
    };
    write_json_atomic(&ctx.dir.join(MATERIALS_FILE), &materials)?;
    write_json_atomic(&ctx.dir.join(HISTORY_FILE), &history)?;
    // The result is on disk; the checkpoint has served its purpose.
    checkpoint::remove(&ctx.dir)?;
    ctx.note(&format!(
        "fitted {} objects ({} emission profile); {} of {} path samples discarded as non-finite",
        objects.len(),
        profile_name(plan.tracer.emission_profile),
        outcome.discarded_samples,
        outcome.traced_paths
    ));
    outputs.extend([PathBuf::from("object").join(MATERIALS_FILE), PathBuf::from("object").join(HISTORY_FILE)]);
    Ok(outputs)
}
