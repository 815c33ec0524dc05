//! The `triangle` stage's artefacts, their writer ([`write_result`], called by `crate::stages::triangle`) and
//! their reader ([`read_result`]).
//!
//! In `output.path/triangle/`:
//! - `mesh.ply` — the (subdivided) mesh in binary little-endian PLY (ingest's writer): vertex positions
//!   (+ normals when the scan has them) and, per triangle, the face columns [`FACE_COLUMNS`]: `int object`
//!   (index into the ingested object list) and `float base_color_r base_color_g base_color_b roughness
//!   metallic specular`. Binary floats round-trip exactly; the house-sized scan's result takes 28 MB here,
//!   against 168 MB as pretty JSON (docs/scale/README.md, "The run's disk cache").
//! - `result.json` — `{"format": "ipt-triangle/2", "vertices", "triangles", "emission", "horizon",
//!   "rounds_done", "log"}` ([`ResultFile`]): what is not per triangle, and the mesh's counts, checked on reading. Written after the mesh, so a `result.json` only exists beside a complete `mesh.ply`.
//! - `checkpoint.json` while the stage runs (format `ipt-triangle-checkpoint/1`, [`super::checkpoint`]).

use std::path::{Path, PathBuf};

use glam::Vec3;
use ingest::ply::{FaceProperty, FaceValues, PlyMesh};
use serde::{Deserialize, Serialize};

use crate::atomic_file::write_json_atomic;
use crate::stage_contract::StageError;
use optim::triangle::{RESULT_FORMAT, RoundRecord, TriangleState};

/// The result's file name.
pub const RESULT_FILE: &str = "result.json";
/// The result's mesh, beside it.
pub const MESH_FILE: &str = "mesh.ply";
pub use super::checkpoint::CHECKPOINT_FILE;
/// Format tag of the checkpoint.
pub const CHECKPOINT_FORMAT: &str = "ipt-triangle-checkpoint/1";

/// The face columns of `mesh.ply` after `vertex_indices`, in file order.
pub const FACE_COLUMNS: [&str; 7] =
    ["object", "base_color_r", "base_color_g", "base_color_b", "roughness", "metallic", "specular"];

/// `result.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResultFile {
    pub format: String,
    /// Vertex and triangle counts of the mesh ([`MESH_FILE`], beside this file).
    pub vertices: usize,
    pub triangles: usize,
    /// Per object, then the ground half of every emitter split at the horizon.
    pub emission: Vec<Vec3>,
    /// The emitters split at the horizon (absent in results written before splits: none).
    #[serde(default)]
    pub horizon: tracer::params::Horizon,
    pub rounds_done: u32,
    pub log: Vec<RoundRecord>,
}

/// Writes `state` as `dir/mesh.ply` and then `dir/result.json`, each atomically; returns their paths
/// relative to the run directory.
pub fn write_result(dir: &Path, state: &TriangleState) -> Result<Vec<PathBuf>, StageError> {
    let m = &state.materials;
    let col = |name: &str, f: &dyn Fn(&tracer::Material) -> f32| FaceProperty {
        name: name.to_owned(),
        values: FaceValues::F32(m.iter().map(f).collect()),
    };
    let object = state.face_object.iter().map(|&o| i32::try_from(o)).collect::<Result<Vec<i32>, _>>();
    let mesh_path = dir.join(MESH_FILE);
    let object = object.map_err(|_| StageError::Artefact {
        path: mesh_path.clone(),
        message: "an object index does not fit in a PLY int".into(),
    })?;
    let ply = PlyMesh {
        positions: state.positions.clone(),
        normals: state.normals.clone(),
        triangles: state.triangles.clone(),
        face_props: vec![
            FaceProperty { name: FACE_COLUMNS[0].to_owned(), values: FaceValues::I32(object) },
            col(FACE_COLUMNS[1], &|m| m.base_color.x),
            col(FACE_COLUMNS[2], &|m| m.base_color.y),
            col(FACE_COLUMNS[3], &|m| m.base_color.z),
            col(FACE_COLUMNS[4], &|m| m.roughness),
            col(FACE_COLUMNS[5], &|m| m.metallic),
            col(FACE_COLUMNS[6], &|m| m.specular),
        ],
    };
    ingest::ply::write_ply(&mesh_path, &ply)?;
    let file = ResultFile {
        format: RESULT_FORMAT.into(),
        vertices: state.positions.len(),
        triangles: state.triangles.len(),
        emission: state.emission.clone(),
        horizon: state.horizon.clone(),
        rounds_done: state.rounds_done,
        log: state.log.clone(),
    };
    write_json_atomic(&dir.join(RESULT_FILE), &file)?;
    Ok(vec![PathBuf::from("triangle").join(MESH_FILE), PathBuf::from("triangle").join(RESULT_FILE)])
}

/// Removes the result (both files) from `dir` if present.
pub fn remove_result(dir: &Path) -> Result<(), StageError> {
    crate::stage_contract::remove_if_present(dir.join(RESULT_FILE))?;
    crate::stage_contract::remove_if_present(dir.join(MESH_FILE))
}

/// Reads `run_dir/triangle/result.json` and its mesh; `Ok(None)` when the stage wrote none (disabled or not
/// run). Errors name the file and what is wrong with it (an older format, a missing or damaged mesh, a
/// column or count that differs from what `result.json` says).
pub fn read_result(run_dir: &Path) -> Result<Option<TriangleState>, StageError> {
    let dir = run_dir.join("triangle");
    let path = dir.join(RESULT_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(StageError::Io { path, source }),
    };
    // The format first, so that a result of an older layout is named as such rather than as unparsable.
    let format = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("format").and_then(|f| f.as_str()).map(str::to_owned));
    if let Some(found) = format
        && found != RESULT_FORMAT
    {
        return Err(StageError::OldFormat { path, found, expected: RESULT_FORMAT, stage: "triangle" });
    }
    let r: ResultFile =
        serde_json::from_str(&text).map_err(|e| StageError::Artefact { path: path.clone(), message: e.to_string() })?;
    let mesh_path = dir.join(MESH_FILE);
    let bad = |message: String| StageError::Artefact { path: mesh_path.clone(), message };
    let read = ingest::ply::read_ply(&mesh_path)?;
    let mut ply = read.mesh;
    if ply.positions.len() != r.vertices || ply.triangles.len() != r.triangles || read.polygons_triangulated != 0 {
        return Err(bad(format!(
            "{} vertices and {} triangles, result.json says {} and {}",
            ply.positions.len(),
            ply.triangles.len(),
            r.vertices,
            r.triangles
        )));
    }
    let mut f32_col = |name: &str| match ply.face_props.iter_mut().find(|p| p.name == name).map(|p| &mut p.values) {
        Some(FaceValues::F32(v)) => Ok(std::mem::take(v)),
        _ => Err(bad(format!("no float face column {name:?}"))),
    };
    let [r_, g, b, rough, metal, spec] = [
        f32_col(FACE_COLUMNS[1])?,
        f32_col(FACE_COLUMNS[2])?,
        f32_col(FACE_COLUMNS[3])?,
        f32_col(FACE_COLUMNS[4])?,
        f32_col(FACE_COLUMNS[5])?,
        f32_col(FACE_COLUMNS[6])?,
    ];
    // The objects' own entries come first; the ground halves and zeniths of split emitters follow them.
    let objects = r.emission.len().saturating_sub(r.horizon.extra_entries());
    let face_object = super::face_objects(&ply, objects, &mesh_path, RESULT_FILE)?;
    let materials = (0..r.triangles)
        .map(|t| tracer::Material {
            base_color: Vec3::new(r_[t], g[t], b[t]),
            roughness: rough[t],
            metallic: metal[t],
            specular: spec[t],
        })
        .collect();
    Ok(Some(TriangleState {
        positions: ply.positions,
        normals: ply.normals,
        triangles: ply.triangles,
        face_object,
        materials,
        emission: r.emission,
        horizon: r.horizon,
        rounds_done: r.rounds_done,
        log: r.log,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> TriangleState {
        let m = |x: f32| tracer::Material {
            base_color: Vec3::new(x, 0.5 * x, 1.0 / 3.0),
            roughness: 0.1 + x,
            metallic: x * x,
            specular: 0.7,
        };
        TriangleState {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 1e-7)],
            normals: Some(vec![Vec3::Z; 4]),
            triangles: vec![[0, 1, 2], [1, 3, 2]],
            face_object: vec![1, 0],
            materials: vec![m(0.123_456_79), m(0.987_654_3)],
            // Object 1 is split at the horizon: its ground half is the entry after the objects'.
            emission: vec![Vec3::ZERO, Vec3::new(3.0, 2.0, 1.0), Vec3::new(0.5, 0.4, 0.3)],
            horizon: tracer::params::Horizon { up: Vec3::Z, ground: vec![None, Some(2)], zenith: Vec::new() },
            rounds_done: 2,
            log: Vec::new(),
        }
    }

    #[test]
    fn a_result_reads_back_exactly_and_a_damaged_mesh_is_named() {
        let dir = std::env::temp_dir().join(format!("ipt-triangle-artefact-{}", std::process::id()));
        let stage = dir.join("triangle");
        std::fs::create_dir_all(&stage).unwrap();
        let s = state();
        write_result(&stage, &s).unwrap();
        assert_eq!(read_result(&dir).unwrap().unwrap(), s);

        // An object index beyond the objects of result.json.
        let mut wrong = s.clone();
        wrong.face_object[0] = 2;
        write_result(&stage, &wrong).unwrap();
        let mut r: ResultFile =
            serde_json::from_str(&std::fs::read_to_string(stage.join(RESULT_FILE)).unwrap()).unwrap();
        assert!(read_result(&dir).unwrap_err().to_string().contains("mesh.ply"));

        // A mesh whose counts differ from result.json's.
        write_result(&stage, &s).unwrap();
        r.triangles = 3;
        write_json_atomic(&stage.join(RESULT_FILE), &r).unwrap();
        let e = read_result(&dir).unwrap_err().to_string();
        assert!(e.contains("mesh.ply") && e.contains("says"), "{e}");

        // The older, all-JSON layout is named as such.
        std::fs::write(stage.join(RESULT_FILE), r#"{"format": "ipt-triangle/1", "state": {}}"#).unwrap();
        let e = read_result(&dir).unwrap_err().to_string();
        assert!(e.contains("ipt-triangle/1"), "{e}");

        remove_result(&stage).unwrap();
        assert!(read_result(&dir).unwrap().is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
