//! `mesh.ply`: the final mesh with every per-triangle parameter as a face column, written with ingest's PLY
//! writer (binary little-endian).
//!
//! Face columns, in order: `float albedo_r albedo_g albedo_b` (linear), `float roughness metallic specular`,
//! `float emission_r emission_g emission_b` (radiance, linear, unclamped), `int segment_id`, and
//! `uchar red green blue` (sRGB-encoded albedo, clamped to [0, 1], for viewers such as MeshLab).

use ingest::ply::{FaceProperty, FaceValues, PlyMesh};

use ingest::srgb;

use super::ExportInput;

/// Names of the face columns after `vertex_indices`, in file order.
pub const FACE_COLUMNS: [&str; 13] = [
    "albedo_r",
    "albedo_g",
    "albedo_b",
    "roughness",
    "metallic",
    "specular",
    "emission_r",
    "emission_g",
    "emission_b",
    "segment_id",
    "red",
    "green",
    "blue",
];

/// The PLY mesh of an export (vertices as given, one face per triangle in input order).
#[must_use]
pub fn mesh(input: &ExportInput<'_>) -> PlyMesh {
    let f32_col = |name: &str, f: &dyn Fn(usize) -> f32| FaceProperty {
        name: name.to_owned(),
        values: FaceValues::F32((0..input.triangles.len()).map(f).collect()),
    };
    let u8_col = |name: &str, c: usize| FaceProperty {
        name: name.to_owned(),
        values: FaceValues::U8(input.materials.iter().map(|m| srgb::linear_to_srgb8(m.base_color[c])).collect()),
    };
    let m = input.materials;
    let e = input.emission;
    let face_props = vec![
        f32_col("albedo_r", &|t| m[t].base_color.x),
        f32_col("albedo_g", &|t| m[t].base_color.y),
        f32_col("albedo_b", &|t| m[t].base_color.z),
        f32_col("roughness", &|t| m[t].roughness),
        f32_col("metallic", &|t| m[t].metallic),
        f32_col("specular", &|t| m[t].specular),
        f32_col("emission_r", &|t| e[t].x),
        f32_col("emission_g", &|t| e[t].y),
        f32_col("emission_b", &|t| e[t].z),
        FaceProperty { name: "segment_id".to_owned(), values: FaceValues::I32(input.segment_id.to_vec()) },
        u8_col("red", 0),
        u8_col("green", 1),
        u8_col("blue", 2),
    ];
    PlyMesh { positions: input.positions.to_vec(), normals: None, triangles: input.triangles.to_vec(), face_props }
}
