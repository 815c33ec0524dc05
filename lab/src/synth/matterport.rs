//! Writes a synthetic scan in the Matterport3D layout (see shared/notes/formats.md): the segmented mesh, the
//! segment labels, the camera file and the photos (linear EXR, or JPEG through the camera pipeline).

use super::SynthError;
use super::desc::SceneDesc;
use super::mesh::SynthMesh;
use glam::{Affine3A, Vec3};
use std::fmt::Write as _;
use std::path::Path;

/// Writes `bytes` to `path` atomically (the workspace's one writer, [`ingest::atomic::write_atomic`]), so a
/// reader never sees a half-written file.
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), SynthError> {
    ingest::atomic::write_atomic(path, bytes).map_err(|e| SynthError::Write { path: path.to_path_buf(), source: e })
}

/// Binary little-endian PLY with exactly the Matterport header: vertex `x y z nx ny nz tx ty red green blue`,
/// face `vertex_indices material_id segment_id category_id`. `material_id` (the over-segment) equals the
/// segment id: every synthetic object is one over-segment.
#[must_use]
pub fn ply_bytes(desc: &SceneDesc, mesh: &SynthMesh) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment synthetic scan written by lab::synth\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n\
         property float ny\nproperty float nz\nproperty float tx\nproperty float ty\nproperty uchar red\n\
         property uchar green\nproperty uchar blue\nelement face {}\nproperty list uchar int vertex_indices\n\
         property int material_id\nproperty int segment_id\nproperty int category_id\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
    .into_bytes();
    // Vertex colours: the object's base colour in 8-bit (only for viewing the mesh; the pipeline ignores it).
    let mut colour_of_vertex = vec![[128u8; 3]; mesh.positions.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let c = desc.objects[mesh.object_of_tri[t] as usize].base_color;
        for &v in tri {
            colour_of_vertex[v as usize] = c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    for (i, (p, n)) in mesh.positions.iter().zip(&mesh.normals).enumerate() {
        for x in [p.x, p.y, p.z, n.x, n.y, n.z, 0.0, 0.0] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out.extend_from_slice(&colour_of_vertex[i]);
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        out.push(3);
        for &v in tri {
            out.extend_from_slice(&(v as i32).to_le_bytes());
        }
        let o = &desc.objects[mesh.object_of_tri[t] as usize];
        for x in [o.id, o.id, o.category_id] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// `.semseg.json`: one segment group per object, its over-segment list holding its own id.
#[must_use]
pub fn semseg_json(desc: &SceneDesc) -> serde_json::Value {
    let groups: Vec<_> = desc
        .objects
        .iter()
        .map(|o| serde_json::json!({"id": o.id, "objectId": o.id, "label": o.label, "segments": [o.id]}))
        .collect();
    serde_json::json!({"sceneId": desc.house_id, "segGroups": groups})
}

/// `.fsegs.json`: the over-segment id of every face, in face order.
#[must_use]
pub fn fsegs_json(desc: &SceneDesc, mesh: &SynthMesh) -> serde_json::Value {
    let ids: Vec<i32> = mesh.object_of_tri.iter().map(|&o| desc.objects[o as usize].id).collect();
    serde_json::json!({"sceneId": desc.house_id, "segIndices": ids})
}

/// Colour and depth file names of view `k`, in Matterport's `<uuid>_i<camera>_<yaw>` pattern: linear EXR from
/// camera 0, or with a `[camera_pipeline]` a JPEG from physical camera `k % vignetting_corner.len()`.
#[must_use]
pub fn image_names(desc: &SceneDesc, k: usize) -> (String, String) {
    let id = &desc.house_id;
    match &desc.camera_pipeline {
        None => (format!("{id}_i0_{k}.exr"), format!("{id}_d0_{k}.png")),
        Some(p) => {
            let c = k % p.vignetting_corner.len().max(1);
            (format!("{id}_i{c}_{k}.jpg"), format!("{id}_d{c}_{k}.png"))
        }
    }
}

/// The `.conf` camera file: one `intrinsics_matrix` line (all views share the intrinsics) and one `scan` line
/// per view with the camera-to-world matrix, row-major.
#[must_use]
pub fn conf_text(desc: &SceneDesc, cameras: &[tracer::Camera]) -> String {
    let mut s = format!(
        "dataset matterport\nn_images {}\ndepth_directory undistorted_depth_images\n\
         color_directory undistorted_color_images\n",
        cameras.len()
    );
    if let Some(c) = cameras.first() {
        let _ = writeln!(s, "intrinsics_matrix {} 0 {}  0 {} {} 0 0 1", c.fx, c.cx, c.fy, c.cy);
    }
    for (k, c) in cameras.iter().enumerate() {
        let (color, depth) = image_names(desc, k);
        let m = glam::Mat4::from(c.cam_to_world);
        let _ = write!(s, "scan {depth} {color}");
        for row in 0..4 {
            for v in m.row(row).to_array() {
                let _ = write!(s, " {v}");
            }
        }
        s.push('\n');
    }
    s
}

/// Camera-to-world transform of a look-at camera in the OpenGL convention (looks along −z, +y up).
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Option<Affine3A> {
    let f = (target - eye).try_normalize()?;
    let r = f.cross(up).try_normalize()?;
    let u = r.cross(f);
    Some(Affine3A::from_cols(r.into(), u.into(), (-f).into(), eye.into()))
}

/// A linear RGB image as a single-part 32-bit float EXR file in memory.
pub fn exr_bytes(path: &Path, width: u32, height: u32, rgb: &[f32]) -> Result<Vec<u8>, SynthError> {
    ingest::photo::exr::encode_rgb_interleaved(width, height, ingest::photo::exr::Compression::Fast, rgb)
        .map_err(|e| SynthError::Exr { path: path.to_path_buf(), message: e.to_string() })
}
