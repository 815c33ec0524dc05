//! The `triangle` stage: per-triangle fit with adaptive subdivision ([`optim::triangle`]) starting from the
//! `object` stage's result.
//!
//! Artefacts in `output.path/triangle/`:
//! - `mesh.ply` + `result.json` ([`crate::artefacts::triangle`]): the (subdivided) mesh with per-triangle
//!   materials as face columns, and the per-object emission and the log of every round. Not written when
//!   `triangle.enabled = false` (an old result is removed, so `export` falls back to the per-object result).
//! - `checkpoint.json` while the stage runs — `{"format": "ipt-triangle-checkpoint/1", "config_sha256",
//!   "inputs_sha256", "state"}` after every round that ended with a split; a rerun with the same hashes
//!   resumes from it.

use std::path::PathBuf;

use crate::artefacts::checkpoint;
use crate::artefacts::ingest::Ingested;
use crate::artefacts::object::{MATERIALS_FILE, read_result as read_object_result};
use crate::artefacts::triangle::{CHECKPOINT_FORMAT, remove_result, write_result};
use crate::config::TriangleConfig;
use crate::materials::ObjectMaterial;
use crate::stage_contract::{StageContext, StageError};
use optim::triangle::{RoundInputs, TriangleError, TriangleSettings, TriangleState};

/// Runs the stage.
pub fn run(ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
    let plan = ctx.plan;
    if !plan.triangle.enabled {
        remove_result(&ctx.dir)?;
        checkpoint::remove(&ctx.dir)?;
        ctx.note("disabled (triangle.enabled = false); export uses the per-object result");
        return Ok(Vec::new());
    }
    let scene_data = Ingested::read(&plan.output)?;
    let prepared = crate::artefacts::object::read_prepared(&plan.output)?;
    let materials = read_object_result(&plan.output)?;
    let ids: Vec<i64> = scene_data.objects.iter().map(|o| o.id).collect();
    let params = materials.params_for(&ids, &plan.output.join("object").join(MATERIALS_FILE))?;
    let specular: Vec<bool> =
        ids.iter().map(|id| materials.objects.iter().any(|o| o.id == *id && o.model.contains("specular"))).collect();
    // An object `materials.json` does not list counts as constrained, as one that does not say.
    let constrained: Vec<bool> = ids
        .iter()
        .map(|id| materials.objects.iter().find(|o| o.id == *id).is_none_or(ObjectMaterial::is_constrained))
        .collect();
    let cameras = prepared.tracer_cameras();
    let settings = plan.tracer.settings();
    let triangle = TriangleSettings::from(&plan.triangle);
    let inputs = RoundInputs {
        cameras: &cameras,
        images: &prepared.images,
        settings: &triangle,
        object: &plan.object,
        tracer: &settings,
        specular: &specular,
        constrained: &constrained,
    };
    let state = match checkpoint::resumable::<TriangleState>(ctx, CHECKPOINT_FORMAT) {
        Some(s) => {
            ctx.note(&format!("resuming from the checkpoint after round {}", s.rounds_done));
            s
        }
        None => TriangleState::from_objects(
            scene_data.positions.clone(),
            scene_data.normals.clone(),
            scene_data.triangles.clone(),
            scene_data.face_object.clone(),
            &params,
        )
        .map_err(triangle_err)?,
    };
    let before = scene_data.triangles.len();
    let mut on_round = |s: &TriangleState| -> Result<(), TriangleError> {
        checkpoint::write(ctx, CHECKPOINT_FORMAT, s).map_err(|e| TriangleError::Checkpoint(e.to_string()))
    };
    let progress = ctx.progress("rounds", u64::from(plan.triangle.rounds) + 1);
    let state = optim::triangle::run_rounds(&inputs, state, &mut on_round, progress.as_ref()).map_err(triangle_err)?;
    drop(progress);
    let written = write_result(&ctx.dir, &state)?;
    checkpoint::remove(&ctx.dir)?;
    ctx.note(&format!("{before} → {} triangles", state.triangles.len()));
    Ok(written)
}

impl From<&TriangleConfig> for TriangleSettings {
    /// The optimiser's settings from the `[triangle]` table (`enabled` is the stage's own).
    fn from(c: &TriangleConfig) -> Self {
        Self {
            rounds: c.rounds,
            fit_steps: c.fit_steps,
            spp: c.spp,
            pixels_per_triangle: c.pixels_per_triangle,
            paths_per_triangle: c.paths_per_triangle,
            paths_per_object: c.paths_per_object,
            paths_per_step: c.paths_per_step,
            adam_iterations: c.adam_iterations,
            adam_lr: c.adam_lr,
            smoothness: c.smoothness,
            split_significance: c.split_significance,
            split_contrast: c.split_contrast,
            min_pixels: c.min_pixels,
            max_triangles: c.max_triangles,
            light_steps: c.light_steps,
            light_precision: c.light_precision,
            light_fit_steps: c.light_fit_steps,
            family_pixels: c.family_pixels,
            seed: c.seed,
        }
    }
}

fn triangle_err(e: TriangleError) -> StageError {
    StageError::Triangle(e)
}
