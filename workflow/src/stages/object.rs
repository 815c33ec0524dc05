//! The `object` stage: per-object material and emission fit ([`optim::fit::fit_objects`]) on the ingested
//! mesh and the prepared photos, with checkpoints so an interrupted run resumes where it stopped. When the
//! photos' calibration left the tone curve's exponent open, the fit is followed by a measurement of that exponent
//! against its renders (`optim::photometric`): fits of the photos raised to a few exponents are compared by
//! their held-out log misfit, the search settles on the best, and the final fit uses it; the exponent goes to
//! `photometric.json` for the later stages.
//!
//! Artefacts in `output.path/object/`:
//! - `materials.json` — the result in the `ipt-materials/1` schema ([`crate::materials`]);
//! - `history.json` — `{"format": "ipt-object-history/1", "history": [...], "why": [...], "traced_paths",
//!   "discarded_samples"}`: the fit's per-iteration trajectory, each object's model decision, and how many
//!   path samples the fit traced and how many of them the tracer discarded as non-finite;
//! - `checkpoint.json` while the stage runs — `{"format": "ipt-object-checkpoint/1", "config_sha256",
//!   "inputs_sha256", "state"}`, rewritten atomically at every checkpoint the fit hands out and deleted once
//!   the outputs above are written. A rerun resumes from it only when both hashes match the current run
//!   (same config section, same inputs), so a stale checkpoint is never mixed into a different fit.

use std::path::PathBuf;

use crate::artefacts::checkpoint;
use crate::artefacts::ingest::Ingested;
use crate::artefacts::object::{
    CHECKPOINT_FORMAT, ExponentRound, HISTORY_FILE, HISTORY_FORMAT, HistoryFile, MATERIALS_FILE, PHOTOMETRIC_FILE,
    PHOTOMETRIC_FORMAT, PhotometricFile,
};
use crate::artefacts::preprocess::{CalibrationFile, Prepared, raise_to_exponent};
use crate::atomic_file::write_json_atomic;
use crate::config::profile_name;
use crate::materials::{MATERIALS_FORMAT, MaterialsFile, ObjectMaterial};
use crate::stage_contract::{StageContext, StageError};
use optim::fit::{FitError, FitInputs, FitState, ObjectDesc};
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
    let mut exponent = 1.0f64;
    let mut rounds: Vec<ExponentRound> = Vec::new();
    let mut last_try = true;
    // Each trial's fit, so that a search ending on an exponent it already tried reuses that fit (same photos,
    // same seed: the final fit would repeat it exactly).
    let mut trial_fits: Vec<(f64, optim::fit::FitOutcome)> = Vec::new();
    let outcome = loop {
        let corrected;
        let images = if exponent == 1.0 {
            &prepared.images
        } else {
            let mut raised = prepared.images.clone();
            raise_to_exponent(&mut raised, [exponent; 3]);
            corrected = raised;
            &corrected
        };
        let inputs = FitInputs {
            scene: &scene,
            cameras: &cameras,
            images,
            objects: &objects,
            settings: &plan.object,
            tracer: &settings,
        };
        // Only the first fit checkpoints: later ones fit re-exponentiated photos, which a checkpoint of the
        // first must never resume (the first replays deterministically on a resumed run).
        let first = rounds.is_empty() && last_try;
        let resume: Option<FitState> = if first { checkpoint::resumable(ctx, CHECKPOINT_FORMAT) } else { None };
        if let Some(state) = &resume {
            ctx.note(&format!("resuming from the checkpoint at iteration {}", state.iteration));
        }
        let mut on_checkpoint = |state: &FitState| -> Result<(), FitError> {
            if first {
                checkpoint::write(ctx, CHECKPOINT_FORMAT, state).map_err(|e| FitError::Checkpoint(e.to_string()))?;
                tracing::debug!(iteration = state.iteration, "checkpoint written");
            }
            Ok(())
        };
        let label = if search { format!("fit (photos ^ {exponent:.3})") } else { "fit".to_owned() };
        let progress = ctx.progress(&label, u64::from(plan.object.iterations));
        let outcome = optim::fit::fit_objects(&inputs, resume, &mut on_checkpoint, progress.as_ref())?;
        drop(progress);
        if !search || !last_try {
            break outcome;
        }
        let sets = optim::fit::pixels::collect(
            &scene,
            &cameras,
            images,
            objects.len(),
            plan.object.holdout_fraction.max(EXPONENT_HOLDOUT_FRACTION),
            plan.object.holdout_pixels as usize,
            plan.object.train_pool as usize,
            plan.object.seed,
        );
        // Every trial is judged with the same random numbers (`render_misfit`). The judge sees the fit before
        // model selection: a decision that flips between neighbouring exponents (faint emissions dropped and
        // the scene re-fitted around them) put a trial's misfit at 1.4–2.8× that of its neighbours' in every
        // channel, while the diffuse fit follows the photos smoothly (docs/photo/self-calibration.md).
        let m = optim::photometric::render_misfit(
            &scene,
            &cameras,
            &outcome.before_selection,
            &settings,
            &sets.holdout,
            plan.object.holdout_spp,
            plan.object.seed,
        )?;
        // In the photos' original log units: raising to e scales every log residual by e.
        let misfit: [f64; 3] = m.channel.map(|v| v / (exponent * exponent));
        // Each channel's misfit relative to its first trial, and the median of the three: the darkest channel's
        // log misfit is the largest and the noisiest, so summed it would decide alone, and one channel's fit
        // can go astray where the other two agree.
        let first = rounds.first().map_or(misfit, |r| r.misfit);
        let criterion = optim::photometric::relative_median(misfit, first);
        rounds.push(ExponentRound { exponent, misfit, criterion, terms: m.terms });
        ctx.note(&format!(
            "tone-curve exponent {exponent:.3}: held-out log misfit {} (R / G / B, {} terms), relative {criterion:.4}",
            misfit.map(|v| format!("{v:.4e}")).join(" / "),
            m.terms
        ));
        trial_fits.push((exponent, outcome));
        let trials: Vec<(f64, f64)> = rounds.iter().map(|r| (r.exponent, r.criterion)).collect();
        match optim::photometric::next_exponent(&trials) {
            NextExponent::Try(e) => exponent = e,
            NextExponent::Final(e) => {
                exponent = e;
                last_try = false;
                if let Some(i) = trial_fits.iter().position(|(tried, _)| *tried == e) {
                    ctx.note(&format!("exponent {e:.3} was tried already: its fit is the final one"));
                    break trial_fits.swap_remove(i).1;
                }
            }
        }
    };
    let mut outputs = Vec::new();
    if search {
        let file = PhotometricFile { format: PHOTOMETRIC_FORMAT.into(), exponent: [exponent; 3], rounds };
        write_json_atomic(&ctx.dir.join(PHOTOMETRIC_FILE), &file)?;
        outputs.push(PathBuf::from("object").join(PHOTOMETRIC_FILE));
        ctx.note(&format!("photos raised to the exponent {exponent:.3} for the final fit and every later stage"));
    }

    let materials = MaterialsFile {
        format: MATERIALS_FORMAT.into(),
        emission_profile: plan.tracer.emission_profile,
        objects: objects
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let m = outcome.params.materials[i];
                let e = outcome.params.emission[i];
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
