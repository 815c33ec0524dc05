//! Wavefront OBJ meshes via `tobj`. Every `*.obj` in a directory is loaded (sorted by name) into one mesh; the
//! segment column numbers the `o`/`g` groups and the material column the `usemtl` materials (both labelled by
//! name, prefixed with the file stem when there are several files). Polygons are fan-triangulated.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::error::IngestError;
use crate::listing::files_with_extension;
use crate::mesh::{LabeledMesh, Mesh};

/// Loads every `*.obj` in `dir`. Returns the mesh and the path used in messages (the single file, or `dir`).
pub fn load_obj_dir(dir: &Path) -> Result<(LabeledMesh, PathBuf), IngestError> {
    let files = files_with_extension(dir, "obj")?;
    if files.is_empty() {
        return Err(IngestError::Layout { dir: dir.to_path_buf(), message: "no *.obj file".into() });
    }
    let mut out = LabeledMesh { mesh: Mesh::default(), ..LabeledMesh::default() };
    let prefix = files.len() > 1;
    for f in &files {
        append_obj(f, prefix, &mut out)?;
    }
    let source = if let [one] = files.as_slice() { one.clone() } else { dir.to_path_buf() };
    Ok((out, source))
}

/// Loads one OBJ file.
pub fn load_obj(path: &Path) -> Result<LabeledMesh, IngestError> {
    let mut out = LabeledMesh::default();
    append_obj(path, false, &mut out)?;
    Ok(out)
}

fn append_obj(path: &Path, prefix_names: bool, out: &mut LabeledMesh) -> Result<(), IngestError> {
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, materials) =
        tobj::load_obj(path, &options).map_err(|e| IngestError::format(path, format!("cannot load OBJ: {e}")))?;
    let materials = match materials {
        Ok(m) => m,
        Err(e) => {
            tracing::warn!("{}: materials not loaded ({e}); material groups are unnamed", path.display());
            Vec::new()
        }
    };
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = |n: &str| if prefix_names { format!("{stem}/{n}") } else { n.to_string() };
    // Group ids continue after those of earlier files so that files never share an id.
    let seg_base = out.segment_labels.keys().max().map_or(0, |m| m + 1);
    let mat_base = out
        .material_labels
        .keys()
        .max()
        .map_or(0, |m| m + 1)
        .max(out.mesh.face_material.iter().copied().max().map_or(0, |m| m + 1));
    let mut group_ids: BTreeMap<String, i32> = BTreeMap::new();
    let mut material_seen: HashMap<usize, i32> = HashMap::new();
    let mesh = &mut out.mesh;
    let mut vertex_index = 0usize;
    for model in &models {
        let m = &model.mesh;
        let base =
            u32::try_from(mesh.positions.len()).map_err(|_| IngestError::format(path, "more than 2^32 vertices"))?;
        for p in m.positions.chunks_exact(3) {
            let v = Vec3::new(p[0], p[1], p[2]);
            if !v.is_finite() {
                return Err(IngestError::element(
                    path,
                    "vertex",
                    vertex_index,
                    format!("position {v} is not finite (NaN or Inf)"),
                ));
            }
            mesh.positions.push(v);
            vertex_index += 1;
        }
        // tobj calls faces before any `o`/`g` "unnamed_object"; such a group is named after its file.
        let unnamed = model.name.is_empty() || model.name == "unnamed_object";
        let group_name = if unnamed { String::new() } else { model.name.clone() };
        let next = seg_base + group_ids.len() as i32;
        let seg = *group_ids.entry(group_name.clone()).or_insert(next);
        out.segment_labels.entry(seg).or_insert_with(|| if unnamed { stem.clone() } else { name(&group_name) });
        let mat = match m.material_id {
            None => -1,
            Some(id) => {
                let next = mat_base + material_seen.len() as i32;
                let mat = *material_seen.entry(id).or_insert(next);
                if let Some(mtl) = materials.get(id) {
                    out.material_labels.entry(mat).or_insert_with(|| name(&mtl.name));
                }
                mat
            }
        };
        let n_local = m.positions.len() / 3;
        for tri in m.indices.chunks_exact(3) {
            if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n_local) {
                return Err(IngestError::format(
                    path,
                    format!("group {group_name:?}: vertex index {bad} out of range"),
                ));
            }
            mesh.triangles.push([base + tri[0], base + tri[1], base + tri[2]]);
            mesh.face_segment.push(seg);
            mesh.face_category.push(-1);
            mesh.face_material.push(mat);
        }
    }
    Ok(())
}
