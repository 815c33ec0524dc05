//! The `ingest` stage: loads the scan once (`ingest::load_scan`) and stores it in the run directory, so every
//! later stage (and `pipeline render`) reads a compact, checked copy instead of the scan.
//!
//! Artefacts in `output.path/ingest/` ([`crate::artefacts::ingest`] reads them back):
//! - `mesh.ply` — binary PLY (ingest's writer): vertex positions (+ normals when the scan has them),
//!   triangles, and per-face `int` columns `object` (index into `scene.json`'s `objects`), `segment_id`,
//!   `category_id`, `material_id` (the scan's ids, `-1` where absent).
//! - `scene.json` — `{"format": "ipt-ingest/1", "objects": [{"id", "label", "triangles"}],
//!   "views": [{"name", "image_path", "camera"}]}`; cameras in the convention of `ingest::camera`.

use std::path::PathBuf;

use ingest::ply::{FaceProperty, FaceValues, PlyMesh};

use crate::artefacts::ingest::{MESH_FILE, SCENE_FILE, SCENE_FORMAT, SceneIndex};
use crate::atomic_file::{write_atomic, write_json_atomic};
use crate::stage_contract::{StageContext, StageError};

/// Runs the stage.
pub fn run(ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
    let plan = ctx.plan;
    let scan = ingest::scan::load_scan(&plan.scan.path, plan.scan.format, plan.scan.group_by)?;
    if scan.views.is_empty() {
        return Err(StageError::Artefact { path: plan.scan.path.clone(), message: "the scan has no views".into() });
    }
    let mesh = &scan.mesh;
    let ply = PlyMesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        triangles: mesh.triangles.clone(),
        face_props: vec![
            FaceProperty {
                name: "object".into(),
                values: FaceValues::I32(scan.face_object.iter().map(|&o| o as i32).collect()),
            },
            FaceProperty { name: "segment_id".into(), values: FaceValues::I32(mesh.face_segment.clone()) },
            FaceProperty { name: "category_id".into(), values: FaceValues::I32(mesh.face_category.clone()) },
            FaceProperty { name: "material_id".into(), values: FaceValues::I32(mesh.face_material.clone()) },
        ],
    };
    let mesh_path = ctx.dir.join(MESH_FILE);
    let bytes = ingest::ply::encode_ply(&mesh_path, &ply)?;
    write_atomic(&mesh_path, &bytes)?;
    let index = SceneIndex { format: SCENE_FORMAT.into(), objects: scan.objects.clone(), views: scan.views.clone() };
    write_json_atomic(&ctx.dir.join(SCENE_FILE), &index)?;
    tracing::info!(
        triangles = mesh.triangles.len(),
        objects = scan.objects.len(),
        views = scan.views.len(),
        "ingested {}",
        plan.scan.path.display()
    );
    ctx.note(&format!(
        "{} triangles, {} objects, {} views",
        mesh.triangles.len(),
        scan.objects.len(),
        scan.views.len()
    ));
    let removed = &scan.removed;
    if removed.zero_area_triangles > 0 {
        let objects: Vec<String> = removed.objects_without_area.iter().map(|o| o.id.to_string()).collect();
        let left_out = if objects.is_empty() {
            String::new()
        } else {
            format!("; objects {} had no area and are left out", objects.join(", "))
        };
        ctx.note(&format!("{} zero-area triangles dropped{left_out}", removed.zero_area_triangles));
    }
    Ok(vec![PathBuf::from("ingest").join(MESH_FILE), PathBuf::from("ingest").join(SCENE_FILE)])
}
