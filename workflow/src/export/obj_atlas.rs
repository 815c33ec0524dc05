//! `textured.obj` + `textured.mtl`: the mesh with per-corner UVs into the albedo atlas.
//!
//! - `v`: the input vertices, in order (shared; OBJ indexes positions and UVs separately, so positions are not
//!   duplicated). `vt`: three per triangle, triangle t's corners are `vt` 3t+1, 3t+2, 3t+3, in OBJ's `v`-up
//!   convention (`1 − v` of the glTF UVs, see [`super::atlas`]).
//! - Faces in input order (face i of the file is triangle i). Each run of triangles of one segment is
//!   preceded by `g segment_<id>` and `usemtl segment_<id>`, so importers make one object/material per
//!   segment; runs repeat when segments interleave in the input.
//! - One material per segment: `map_Kd albedo.png` with `Kd 1 1 1` (the texture is the albedo), `Ks 0 0 0`,
//!   the PBR extension keys `Pr` / `Pm` with the segment's mean roughness / metallic, and `Ke` with its mean
//!   emitted radiance (linear, may exceed 1). Per-triangle roughness/metallic are exact in `mesh.ply` and
//!   `scene.glb`; OBJ has no per-texel slot for them that importers agree on.
//! - No `vn`: normals are the faces' own (importers compute them).
//!
//! Numbers are written with Rust's shortest round-trip formatting, so a reader recovers the f32 bits.

use std::fmt::Write as _;

use super::atlas::AtlasLayout;
use super::{ExportInput, SegmentSummary};

/// Name of the material/group of a segment.
#[must_use]
pub fn segment_name(id: i32) -> String {
    format!("segment_{id}")
}

/// The `.mtl` text; `texture` is the atlas file name relative to the `.mtl`.
#[must_use]
pub fn mtl(segments: &[SegmentSummary], texture: &str) -> String {
    let mut s = String::from("# written by ipt pipeline export: one material per segment, albedo from the atlas\n");
    for seg in segments {
        let e = seg.mean_emission;
        let _ = write!(
            s,
            "\nnewmtl {}\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nKe {} {} {}\nPr {}\nPm {}\nd 1\nillum 1\nmap_Kd {texture}\n",
            segment_name(seg.id),
            e.x,
            e.y,
            e.z,
            seg.mean_roughness,
            seg.mean_metallic
        );
    }
    s
}

/// The `.obj` text; `mtl_name` is the material library file name relative to the `.obj`.
#[must_use]
pub fn obj(input: &ExportInput<'_>, layout: &AtlasLayout, mtl_name: &str) -> String {
    let n = input.triangles.len();
    let mut s = String::with_capacity(64 * (input.positions.len() + 4 * n));
    let _ = writeln!(
        s,
        "# written by ipt pipeline export: {n} triangles, per-triangle albedo in a {}x{} atlas ({}-texel cells)",
        layout.width, layout.height, layout.cell
    );
    let _ = writeln!(s, "mtllib {mtl_name}");
    for p in input.positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for t in 0..n {
        for uv in layout.corner_uvs(t as u32) {
            // 1 − v is exact: v is a multiple of 1/H with H a power of two.
            let _ = writeln!(s, "vt {} {}", uv.x, 1.0 - uv.y);
        }
    }
    let mut current: Option<i32> = None;
    for (t, tri) in input.triangles.iter().enumerate() {
        let seg = input.segment_id[t];
        if current != Some(seg) {
            let name = segment_name(seg);
            let _ = writeln!(s, "g {name}\nusemtl {name}");
            current = Some(seg);
        }
        let vt = 3 * t + 1;
        let _ = writeln!(s, "f {}/{} {}/{} {}/{}", tri[0] + 1, vt, tri[1] + 1, vt + 1, tri[2] + 1, vt + 2);
    }
    s
}
