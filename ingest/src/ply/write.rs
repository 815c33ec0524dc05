//! Binary little-endian PLY writer.

use std::fmt::Write as _;
use std::path::Path;

use super::{FaceValues, PlyMesh};
use crate::atomic::write_atomic;
use crate::error::IngestError;

/// Writes `mesh` as binary little-endian PLY, atomically (see [`write_atomic`]).
///
/// Vertices carry `float x y z` (+ `float nx ny nz` when normals are present); faces carry
/// `list uchar int vertex_indices` followed by every face column in order (`float`, `int` or `uchar`).
pub fn write_ply(path: &Path, mesh: &PlyMesh) -> Result<(), IngestError> {
    let bytes = encode_ply(path, mesh)?;
    write_atomic(path, &bytes)
}

/// Encodes `mesh` as binary little-endian PLY bytes; `path` is used only in error messages.
pub fn encode_ply(path: &Path, mesh: &PlyMesh) -> Result<Vec<u8>, IngestError> {
    validate(path, mesh)?;
    let n_faces = mesh.triangles.len();
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment written by ipt ingest\n");
    let _ = writeln!(header, "element vertex {}", mesh.positions.len());
    header.push_str("property float x\nproperty float y\nproperty float z\n");
    if mesh.normals.is_some() {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    let _ = writeln!(header, "element face {n_faces}");
    header.push_str("property list uchar int vertex_indices\n");
    for p in &mesh.face_props {
        let _ = writeln!(header, "property {} {}", p.values.ply_type(), p.name);
    }
    header.push_str("end_header\n");

    let vertex_row = if mesh.normals.is_some() { 24 } else { 12 };
    let face_row: usize =
        13 + mesh.face_props.iter().map(|p| if matches!(p.values, FaceValues::U8(_)) { 1 } else { 4 }).sum::<usize>();
    let mut out = Vec::with_capacity(header.len() + vertex_row * mesh.positions.len() + face_row * n_faces);
    out.extend_from_slice(header.as_bytes());
    for (i, p) in mesh.positions.iter().enumerate() {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = &mesh.normals {
            for c in n[i].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for (f, tri) in mesh.triangles.iter().enumerate() {
        out.push(3);
        for &v in tri {
            // Checked in `validate`: every index is below the vertex count, which fits in an int.
            out.extend_from_slice(&(v as i32).to_le_bytes());
        }
        for p in &mesh.face_props {
            match &p.values {
                FaceValues::F32(v) => out.extend_from_slice(&v[f].to_le_bytes()),
                FaceValues::I32(v) => out.extend_from_slice(&v[f].to_le_bytes()),
                FaceValues::U8(v) => out.push(v[f]),
            }
        }
    }
    Ok(out)
}

fn validate(path: &Path, mesh: &PlyMesh) -> Result<(), IngestError> {
    let n_vertices = mesh.positions.len();
    if n_vertices > i32::MAX as usize {
        return Err(IngestError::format(path, "cannot write PLY: more vertices than an int index can address"));
    }
    if let Some(n) = &mesh.normals
        && n.len() != n_vertices
    {
        return Err(IngestError::format(
            path,
            format!("cannot write PLY: {} normals for {n_vertices} vertices", n.len()),
        ));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(IngestError::element(path, "vertex", i, "cannot write PLY: position is not finite"));
    }
    for (f, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v as usize >= n_vertices) {
            return Err(IngestError::element(
                path,
                "face",
                f,
                format!("cannot write PLY: vertex index {v} out of range ({n_vertices} vertices)"),
            ));
        }
    }
    for (k, p) in mesh.face_props.iter().enumerate() {
        let bad_name = p.name.is_empty()
            || p.name.chars().any(|c| c.is_whitespace() || !c.is_ascii())
            || p.name == "vertex_indices"
            || mesh.face_props[..k].iter().any(|q| q.name == p.name);
        if bad_name {
            return Err(IngestError::format(
                path,
                format!("cannot write PLY: bad or duplicate face property name {:?}", p.name),
            ));
        }
        if p.values.len() != mesh.triangles.len() {
            return Err(IngestError::format(
                path,
                format!(
                    "cannot write PLY: face property {:?} has {} values for {} faces",
                    p.name,
                    p.values.len(),
                    mesh.triangles.len()
                ),
            ));
        }
    }
    Ok(())
}
