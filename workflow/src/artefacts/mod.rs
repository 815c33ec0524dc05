//! What each stage writes into `output.path/<stage>/` and how later stages (and `pipeline render`,
//! `pipeline export`) read it back: file names, format tags, the serialised types and their readers. The
//! stages ([`crate::stages`]) write these files and read each other's only through this module.

pub mod checkpoint;
pub mod ingest;
pub mod object;
pub mod preprocess;
pub mod triangle;

use std::path::Path;

use crate::stage_contract::StageError;

/// The `object` face column of a stage's mesh (`ingest/mesh.ply`, `triangle/mesh.ply`) as object indices,
/// each checked to be below `objects`, the object count of `listed_in` (the JSON file beside the mesh).
/// Errors name `mesh_path` and the first face whose object is missing or out of range.
pub(crate) fn face_objects(
    ply: &::ingest::ply::PlyMesh,
    objects: usize,
    mesh_path: &Path,
    listed_in: &str,
) -> Result<Vec<u32>, StageError> {
    let bad = |message: String| StageError::Artefact { path: mesh_path.to_path_buf(), message };
    let ids = ply.face_ids("object").ok_or_else(|| bad("no per-face `object` column".into()))?;
    ids.iter()
        .enumerate()
        .map(|(t, &o)| {
            u32::try_from(o)
                .ok()
                .filter(|&o| (o as usize) < objects)
                .ok_or_else(|| bad(format!("face {t}: object {o} is not in {listed_in}")))
        })
        .collect()
}
