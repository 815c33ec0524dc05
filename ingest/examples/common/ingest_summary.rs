//! JSON summary of what our PLY reader read (shared by the PLY examples).

use ingest::ply::{FaceValues, PlyRead};

/// `{"vertices": n, "faces": n, "triangles": n, "positions": [...], "face_props": {name: [...]}}` where
/// `faces` counts file faces and props are per triangle.
pub fn to_json(r: &PlyRead) -> String {
    let mut props = serde_json::Map::new();
    for p in &r.mesh.face_props {
        let v = match &p.values {
            FaceValues::F32(v) => serde_json::json!(v),
            FaceValues::I32(v) => serde_json::json!(v),
            FaceValues::U8(v) => serde_json::json!(v),
        };
        props.insert(p.name.clone(), v);
    }
    let positions: Vec<[f32; 3]> = r.mesh.positions.iter().map(|p| p.to_array()).collect();
    serde_json::json!({
        "vertices": r.mesh.positions.len(),
        "faces": r.face_count,
        "triangles": r.mesh.triangles,
        "source_face": r.source_face,
        "positions": positions,
        "has_normals": r.mesh.normals.is_some(),
        "face_props": props,
    })
    .to_string()
}
