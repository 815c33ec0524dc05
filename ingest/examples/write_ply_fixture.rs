//! Writes a PLY with per-face ids (for the Python cross-checks in tests/validation/test_ply_readers.py), reads it
//! back with our reader and prints what we read as JSON on stdout.
//!
//! Usage: `cargo run -p ingest --example write_ply_fixture -- OUT.ply`

use std::path::PathBuf;

use glam::Vec3;
use ingest::ply::{FaceProperty, FaceValues, PlyMesh, read_ply, write_ply};

/// A deterministic grid of `n x n` quads (2 triangles each) with ids that vary per face.
fn fixture(n: u32) -> PlyMesh {
    let mut m = PlyMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            m.positions.push(Vec3::new(i as f32 * 0.1, j as f32 * 0.1, ((i * 7 + j * 3) % 5) as f32 * 0.01));
        }
    }
    m.normals = Some(vec![Vec3::Z; m.positions.len()]);
    let (mut seg, mut cat, mut mat, mut alb, mut red) = (vec![], vec![], vec![], vec![], vec![]);
    for j in 0..n {
        for i in 0..n {
            let v = j * (n + 1) + i;
            for (k, tri) in [[v, v + 1, v + n + 2], [v, v + n + 2, v + n + 1]].into_iter().enumerate() {
                let f = m.triangles.len() as i32;
                m.triangles.push(tri);
                seg.push((i / 3 + 10 * (j / 3)) as i32 - 1);
                cat.push((f * 7919) % 41);
                mat.push(f * 3 + k as i32 - 100_000);
                alb.push((f % 17) as f32 / 16.0);
                red.push((f * 37 % 256) as u8);
            }
        }
    }
    m.face_props = vec![
        FaceProperty { name: "material_id".into(), values: FaceValues::I32(mat) },
        FaceProperty { name: "segment_id".into(), values: FaceValues::I32(seg) },
        FaceProperty { name: "category_id".into(), values: FaceValues::I32(cat) },
        FaceProperty { name: "albedo_r".into(), values: FaceValues::F32(alb) },
        FaceProperty { name: "red".into(), values: FaceValues::U8(red) },
    ];
    m
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out: PathBuf = std::env::args_os().nth(1).ok_or("usage: write_ply_fixture OUT.ply")?.into();
    write_ply(&out, &fixture(20))?;
    let read = read_ply(&out)?;
    println!("{}", ingest_summary::to_json(&read));
    Ok(())
}

#[path = "common/ingest_summary.rs"]
mod ingest_summary;
