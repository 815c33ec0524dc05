//! `scene.glb`: glTF 2.0 binary with PBR metallic-roughness materials.
//!
//! # Structure
//! - One node + mesh per segment (`segment_<id>`), so importers (Blender, three.js, engines) give one object
//!   per segment. Its triangles are grouped into one primitive per distinct emitted radiance (normally one:
//!   emission is per object), each with its own material, because glTF emission is a material factor.
//! - Primitives are non-indexed triangle lists (mode 4): three vertices per triangle, since every corner
//!   has its own atlas UV. Attributes `POSITION` (with the exact min/max the spec requires) and `TEXCOORD_0`.
//!   No `NORMAL`: the spec makes viewers use flat face normals, which is what the fitted mesh means.
//! - Materials: `baseColorTexture` = the albedo atlas (sRGB PNG, the same image as `albedo.png`),
//!   `metallicRoughnessTexture` = an atlas in the same layout with roughness in G and metallic in B (linear),
//!   both factors 1, so roughness and metallic are per triangle; `doubleSided` (scan meshes do not have
//!   consistent winding). Emitters: `emissiveFactor = L / max(L)` (≤ 1, as the spec requires) and
//!   `KHR_materials_emissive_strength.emissiveStrength = max(L)` (listed in `extensionsUsed`, not required:
//!   a viewer without it still shows the emitter's colour).
//! - The sampler filters linearly without mipmaps (minFilter LINEAR) and clamps to edge: with the atlas's
//!   cell margin, no triangle's colour bleeds into another's (see [`super::atlas`]).
//! - Coordinates are the scene's world frame in its units. glTF's up axis is +Y; with
//!   [`super::ExportOptions::z_up`] a root node rotates a Z-up scene by −90° about X.
//!
//! # Binary layout
//! 12-byte header (`glTF`, version 2, total length), a JSON chunk padded with spaces and a BIN chunk padded
//! with zeros, each to a multiple of 4 bytes. BIN holds, in order: all corner positions (f32×3, grouped by
//! primitive), all corner UVs (f32×2, same order), the albedo PNG, the metallic-roughness PNG; every buffer
//! view starts at a multiple of 4.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use serde_json::{Value, json};

use super::atlas::AtlasLayout;
use super::obj_atlas::segment_name;
use super::{ExportError, ExportInput};

/// glTF component type FLOAT.
const FLOAT: u32 = 5126;
/// glTF buffer view target ARRAY_BUFFER.
const ARRAY_BUFFER: u32 = 34962;
/// Sampler filter LINEAR.
const LINEAR: u32 = 9729;
/// Sampler wrap CLAMP_TO_EDGE.
const CLAMP_TO_EDGE: u32 = 33071;
/// GLB magic "glTF", chunk types "JSON" and "BIN\0" (little-endian u32).
const GLB_MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// One primitive: the triangles of one segment with one emitted radiance.
#[derive(Debug, Clone)]
struct Group {
    segment: i32,
    emission: Vec3,
    triangles: Vec<u32>,
}

/// Groups by (segment, emission bits), in ascending segment order then first appearance.
fn groups(input: &ExportInput<'_>) -> Vec<Group> {
    let mut map: BTreeMap<(i32, usize), Group> = BTreeMap::new();
    let mut order: BTreeMap<(i32, [u32; 3]), usize> = BTreeMap::new();
    for (t, &segment) in input.segment_id.iter().enumerate() {
        let e = input.emission[t];
        let next = order.len();
        let k = *order.entry((segment, e.to_array().map(f32::to_bits))).or_insert(next);
        map.entry((segment, k))
            .or_insert_with(|| Group { segment, emission: e, triangles: Vec::new() })
            .triangles
            .push(t as u32);
    }
    map.into_values().collect()
}

fn pad4(bytes: &mut Vec<u8>, fill: u8) {
    while bytes.len() % 4 != 0 {
        bytes.push(fill);
    }
}

/// What [`glb`] built, for the report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GlbSummary {
    pub meshes: usize,
    pub primitives: usize,
    pub emissive_materials: usize,
}

/// The `.glb` bytes. `albedo_png` / `mr_png` are the atlas images in `layout`; `path` names the file in
/// errors (GLB lengths are u32, so the file must stay below 4 GiB).
pub fn glb(
    path: &Path,
    input: &ExportInput<'_>,
    layout: &AtlasLayout,
    albedo_png: &[u8],
    mr_png: &[u8],
    z_up: bool,
) -> Result<(Vec<u8>, GlbSummary), ExportError> {
    let groups = groups(input);
    let corners: usize = groups.iter().map(|g| 3 * g.triangles.len()).sum();
    let mut pos_bytes = Vec::with_capacity(12 * corners);
    let mut uv_bytes = Vec::with_capacity(8 * corners);
    let mut accessors = Vec::new();
    let mut materials = Vec::new();
    let mut meshes: Vec<(i32, Vec<Value>)> = Vec::new();
    let mut emissive_materials = 0;
    for g in &groups {
        let first_corner = pos_bytes.len() / 12;
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &t in &g.triangles {
            let tri = input.triangles[t as usize];
            for (k, uv) in layout.corner_uvs(t).into_iter().enumerate() {
                let p = input.positions[tri[k] as usize];
                (lo, hi) = (lo.min(p), hi.max(p));
                p.to_array().iter().for_each(|c| pos_bytes.extend_from_slice(&c.to_le_bytes()));
                uv.to_array().iter().for_each(|c| uv_bytes.extend_from_slice(&c.to_le_bytes()));
            }
        }
        let count = 3 * g.triangles.len();
        let position = accessors.len();
        accessors.push(json!({
            "bufferView": 0, "byteOffset": 12 * first_corner, "componentType": FLOAT, "count": count,
            "type": "VEC3", "min": lo.to_array(), "max": hi.to_array(),
        }));
        accessors.push(json!({
            "bufferView": 1, "byteOffset": 8 * first_corner, "componentType": FLOAT, "count": count, "type": "VEC2",
        }));
        let mut material = json!({
            "name": segment_name(g.segment),
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicRoughnessTexture": {"index": 1},
                "metallicFactor": 1.0,
                "roughnessFactor": 1.0,
            },
            "doubleSided": true,
        });
        let strength = g.emission.max_element();
        if strength > 0.0 {
            emissive_materials += 1;
            material["name"] = json!(format!("{}_emitter", segment_name(g.segment)));
            // Division by the largest component puts every factor in [0, 1] (validated non-negative); the
            // largest is exactly 1.
            material["emissiveFactor"] = json!((g.emission / strength).to_array());
            material["extensions"] = json!({"KHR_materials_emissive_strength": {"emissiveStrength": strength}});
        }
        let primitive = json!({
            "attributes": {"POSITION": position, "TEXCOORD_0": position + 1},
            "material": materials.len(),
            "mode": 4,
        });
        materials.push(material);
        match meshes.last_mut() {
            Some((s, prims)) if *s == g.segment => prims.push(primitive),
            _ => meshes.push((g.segment, vec![primitive])),
        }
    }

    let mut bin = Vec::with_capacity(pos_bytes.len() + uv_bytes.len() + albedo_png.len() + mr_png.len() + 12);
    let mut views = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, data: &[u8], stride: Option<usize>| {
        pad4(bin, 0);
        let mut v = json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
            v["target"] = json!(ARRAY_BUFFER);
        }
        bin.extend_from_slice(data);
        views.push(v);
    };
    push_view(&mut bin, &pos_bytes, Some(12));
    push_view(&mut bin, &uv_bytes, Some(8));
    push_view(&mut bin, albedo_png, None);
    push_view(&mut bin, mr_png, None);
    pad4(&mut bin, 0);

    let segment_nodes: Vec<Value> =
        meshes.iter().enumerate().map(|(i, (segment, _))| json!({"name": segment_name(*segment), "mesh": i})).collect();
    let n_meshes = meshes.len();
    let mesh_json: Vec<Value> = meshes
        .into_iter()
        .map(|(segment, prims)| json!({"name": segment_name(segment), "primitives": prims}))
        .collect();
    let (nodes, roots) = if z_up {
        let mut nodes = segment_nodes;
        let root = nodes.len();
        // −90° about X maps +Z (scene up) to +Y (glTF up): quaternion (sin(−45°), 0, 0, cos(45°)).
        let h = std::f32::consts::FRAC_1_SQRT_2;
        nodes.push(
            json!({"name": "world_z_up", "rotation": [-h, 0.0, 0.0, h], "children": (0..n_meshes).collect::<Vec<_>>()}),
        );
        (nodes, vec![root])
    } else {
        (segment_nodes, (0..n_meshes).collect())
    };
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "ipt pipeline export"},
        "scene": 0,
        "scenes": [{"name": "ipt", "nodes": roots}],
        "nodes": nodes,
        "meshes": mesh_json,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
        "images": [
            {"name": "albedo", "bufferView": 2, "mimeType": "image/png"},
            {"name": "metallic_roughness", "bufferView": 3, "mimeType": "image/png"},
        ],
        "samplers": [{"magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE}],
        "textures": [{"sampler": 0, "source": 0}, {"sampler": 0, "source": 1}],
    });
    if emissive_materials > 0 {
        doc["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    }
    let mut json_bytes = doc.to_string().into_bytes();
    pad4(&mut json_bytes, b' ');

    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    if u32::try_from(total).is_err() {
        return Err(ExportError::Encode {
            path: path.to_path_buf(),
            message: format!("{total} bytes exceed the 4 GiB a GLB length field can hold"),
        });
    }
    let mut out = Vec::with_capacity(total);
    for word in [GLB_MAGIC, 2, total as u32, json_bytes.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json_bytes);
    for word in [bin.len() as u32, CHUNK_BIN] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&bin);
    let summary = GlbSummary { meshes: n_meshes, primitives: groups.len(), emissive_materials };
    Ok((out, summary))
}
