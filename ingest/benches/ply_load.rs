//! Loading a 1 M-face binary PLY in the Matterport house_segmentations layout (target: under 2 s).
//!
//! `cargo bench -p ingest --bench ply_load`

use std::hint::black_box;
use std::io::Write;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

const FACES: usize = 1_000_000;
const VERTICES: usize = 500_000;

/// Writes a Matterport-style binary PLY: vertex `float x y z nx ny nz tx ty, uchar red green blue`, face
/// `list uchar int vertex_indices, int material_id segment_id category_id`. Deterministic contents.
fn write_matterport_ply(path: &Path) {
    let mut out = Vec::with_capacity(VERTICES * 35 + FACES * 25 + 512);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {VERTICES}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float tx\n\
         property float ty\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {FACES}\n\
         property list uchar int vertex_indices\nproperty int material_id\nproperty int segment_id\n\
         property int category_id\nend_header\n"
    )
    .unwrap();
    for v in 0..VERTICES {
        let f = v as f32;
        for c in [f * 1e-3, (f * 0.37).sin(), (f * 0.11).cos(), 0.0, 0.0, 1.0, 0.5, 0.5] {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&[(v % 256) as u8, 128, 64]);
    }
    for f in 0..FACES {
        out.push(3);
        let a = (f * 7919) % VERTICES;
        for i in [a, (a + 1) % VERTICES, (a + 2) % VERTICES] {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
        for id in [(f / 50) as i32, (f / 1000) as i32, (f % 41) as i32] {
            out.extend_from_slice(&id.to_le_bytes());
        }
    }
    std::fs::write(path, out).unwrap();
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("house.ply");
    write_matterport_ply(&path);
    let mut g = c.benchmark_group("ply_load");
    g.sample_size(10);
    g.bench_function("matterport_1M_faces_binary", |b| {
        b.iter(|| {
            let r = ingest::ply::read_ply(black_box(&path)).unwrap();
            assert_eq!(r.mesh.triangles.len(), FACES);
            r
        });
    });
    g.bench_function("matterport_1M_faces_binary_as_mesh", |b| {
        b.iter(|| ingest::matterport::mesh_from_ply(black_box(&path), None).unwrap());
    });
    // Reference point: the generic ply-rs-bw parser (buffered), which builds a map per element and keeps
    // every property.
    g.bench_function("ply_rs_bw_generic_same_file", |b| {
        b.iter(|| {
            let f = std::fs::File::open(black_box(&path)).unwrap();
            let mut r = std::io::BufReader::new(f);
            let p = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
            p.read_ply(&mut r).unwrap()
        });
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
