//! Writes an export of a small seeded scene into the directory given as the only argument and prints the
//! values it exported as JSON on stdout (for tests/validation/test_export.py).
//!
//! The scene: a 6 × 4-quad floor (segment 3, two objects' worth of random albedo), a wall strip sharing the
//! floor's back edge (segment 8), and an emitting quad (segment 12, radiance above 1). Some floor triangles
//! are refined with [`optim::subdivide`] (children inherit their parent's parameters, then get their own
//! albedo, as the per-triangle stage will), so the export sees a conforming, subdivided mesh.
//!
//! Usage: `export_fixture OUT_DIR`

use std::process::ExitCode;

use glam::Vec3;
use optim::subdivide::{SplitLimits, SubdivideMesh, subdivide};
use tracer::Material;
use workflow::export::{self, ExportInput, ExportOptions};

/// SplitMix64: reproducible values without a rand dependency.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn main() -> ExitCode {
    let Some(dir) = std::env::args_os().nth(1) else {
        eprintln!("usage: export_fixture OUT_DIR");
        return ExitCode::from(2);
    };
    let mut rng = Rng(2024);
    let (nx, ny) = (6u32, 4u32);
    let mut positions: Vec<Vec3> =
        (0..=ny).flat_map(|j| (0..=nx).map(move |i| Vec3::new(i as f32 * 0.5, j as f32 * 0.5, 0.0))).collect();
    let mut triangles = Vec::new();
    let mut segment = Vec::new();
    let v = |i: u32, j: u32| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            segment.extend([3, 3]);
        }
    }
    // Wall: one row of quads standing on the floor's back edge (y = 2), sharing its vertices.
    let top = positions.len() as u32;
    positions.extend((0..=nx).map(|i| Vec3::new(i as f32 * 0.5, 2.0, 1.0)));
    for i in 0..nx {
        triangles.push([v(i, ny), v(i + 1, ny), top + i + 1]);
        triangles.push([v(i, ny), top + i + 1, top + i]);
        segment.extend([8, 8]);
    }
    // Light: a separate quad above the floor.
    let l = positions.len() as u32;
    positions.extend([
        Vec3::new(1.0, 0.5, 2.0),
        Vec3::new(2.0, 0.5, 2.0),
        Vec3::new(2.0, 1.5, 2.0),
        Vec3::new(1.0, 1.5, 2.0),
    ]);
    triangles.extend([[l, l + 2, l + 1], [l, l + 3, l + 2]]);
    segment.extend([12, 12]);

    // Refine every third floor triangle once (closure reaches into the wall along the shared edge).
    let marked: Vec<u32> = (0..2 * nx * ny).step_by(3).collect();
    let mesh = SubdivideMesh { positions: &positions, triangles: &triangles, object_id: &segment };
    let sub = match subdivide(&mesh, &marked, &SplitLimits { min_edge_length: 0.1, min_area: 0.0 }) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("export_fixture: {e}");
            return ExitCode::FAILURE;
        }
    };
    let parent_material: Vec<Material> = segment
        .iter()
        .map(|&s| Material {
            base_color: if s == 8 { Vec3::new(0.8, 0.78, 0.7) } else { Vec3::splat(0.5) },
            roughness: if s == 3 { 0.3 } else { 0.9 },
            metallic: 0.0,
            specular: 0.5,
        })
        .collect();
    // Children inherit their parent's material, then the floor gets a per-triangle texture (as the
    // per-triangle stage would), including the extremes 0 and 1 on triangle 0.
    let mut materials = match sub.inherit(&parent_material) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("export_fixture: {e}");
            return ExitCode::FAILURE;
        }
    };
    for (m, &s) in materials.iter_mut().zip(&sub.object_id) {
        if s == 3 {
            m.base_color = Vec3::new(rng.unit(), rng.unit(), rng.unit());
            m.roughness = rng.unit();
            m.metallic = rng.unit();
        }
    }
    materials[0].base_color = Vec3::new(0.0, 1.0, 0.5);
    let emission: Vec<Vec3> =
        sub.object_id.iter().map(|&s| if s == 12 { Vec3::new(12.0, 10.0, 6.0) } else { Vec3::ZERO }).collect();
    let input = ExportInput {
        positions: &sub.positions,
        triangles: &sub.triangles,
        materials: &materials,
        emission: &emission,
        segment_id: &sub.object_id,
        detail: None,
    };
    let report = match export::write_all(std::path::Path::new(&dir), &input, &ExportOptions::default()) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("export_fixture: {e}");
            return ExitCode::FAILURE;
        }
    };
    let json = serde_json::json!({
        "faces": sub.triangles.len(),
        "vertices": sub.positions.len(),
        "positions": sub.positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        "triangles": sub.triangles,
        "albedo": materials.iter().map(|m| m.base_color.to_array()).collect::<Vec<_>>(),
        "roughness": materials.iter().map(|m| m.roughness).collect::<Vec<_>>(),
        "metallic": materials.iter().map(|m| m.metallic).collect::<Vec<_>>(),
        "emission": emission.iter().map(|e| e.to_array()).collect::<Vec<_>>(),
        "segment_id": sub.object_id,
        "parent": sub.parent_of_new_triangle,
        "refined": sub.refined,
        "closure_cut": sub.closure_cut,
        "atlas": {"width": report.atlas.width, "height": report.atlas.height, "cell": report.atlas.cell},
        "files": report.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
    });
    println!("{json}");
    ExitCode::SUCCESS
}
