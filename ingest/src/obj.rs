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

/// Loads one OBJ file already in memory; `path` is used in error messages and labels. Every `mtllib` it names
/// is read from `mtl` (`None`: no material library, material groups stay unnamed).
pub fn load_obj_bytes(path: &Path, obj: &[u8], mtl: Option<&[u8]>) -> Result<LabeledMesh, IngestError> {
    let mut out = LabeledMesh::default();
    append_obj_from(path, obj, false, &mut out, |_| match mtl {
        Some(bytes) => material_names(bytes),
        None => Err(tobj::LoadError::OpenFileFailed),
    })?;
    Ok(out)
}

fn append_obj(path: &Path, prefix_names: bool, out: &mut LabeledMesh) -> Result<(), IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    append_obj_from(path, &bytes, prefix_names, out, |mtl| {
        std::fs::read(dir.join(mtl)).map_err(|_| tobj::LoadError::OpenFileFailed).and_then(|b| material_names(&b))
    })
}

/// A material library reduced to its `newmtl` lines (trimmed) before `tobj` parses it: only material names are
/// used here, and `tobj` panics on some malformed value lines (a `Kd` with fewer than three numbers), so value
/// lines never reach it.
fn material_names(bytes: &[u8]) -> tobj::MTLLoadResult {
    let text = std::str::from_utf8(bytes).map_err(|_| tobj::LoadError::ReadError)?;
    let names: String = text
        .lines()
        .map(str::trim)
        .filter(|l| l.split_whitespace().next() == Some("newmtl"))
        .flat_map(|l| [l, "\n"])
        .collect();
    tobj::load_mtl_buf(&mut names.as_bytes())
}

/// Checks every index of the `f`, `l` and `p` lines before `tobj` sees them: an integer that refers to an element
/// (`v`, `vt`, `vn`) defined on an earlier line, counted from 1, or from the latest backwards when negative.
/// `tobj` computes positions from these indices without overflow checks, so a zero or far out-of-range index
/// would make it panic or index the wrong vertex.
fn check_indices(path: &Path, text: &str) -> Result<(), IngestError> {
    let mut counts = [0usize; 3];
    for (k, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f" | "l" | "p") => {
                for vertex in words {
                    for (slot, part) in vertex.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let what = ["vertex", "texture coordinate", "normal"].get(slot).ok_or_else(|| {
                            IngestError::line(path, k + 1, format!("face vertex {vertex:?} has more than 3 indices"))
                        })?;
                        let n = counts[slot];
                        let ok = part.parse::<i64>().is_ok_and(|i| {
                            let magnitude = usize::try_from(i.unsigned_abs()).unwrap_or(usize::MAX);
                            i != 0 && magnitude <= n
                        });
                        if !ok {
                            return Err(IngestError::line(
                                path,
                                k + 1,
                                format!("{what} index {part:?} does not refer to one of the {n} defined before it"),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn append_obj_from(
    path: &Path,
    bytes: &[u8],
    prefix_names: bool,
    out: &mut LabeledMesh,
    material_loader: impl Fn(&Path) -> tobj::MTLLoadResult,
) -> Result<(), IngestError> {
    let text = crate::error::utf8(path, bytes)?;
    check_indices(path, text)?;
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, material_loader)
        .map_err(|e| IngestError::format(path, format!("cannot load OBJ: {e}")))?;
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
