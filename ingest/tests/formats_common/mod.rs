//! Helpers shared by the `formats_*` integration tests: tiny images, hand-made PLY bytes, a small seeded RNG.
#![allow(dead_code)]

use std::path::Path;

/// Writes an 8-bit RGB image (format from the extension: .jpg/.png) of the given size.
pub fn write_image(path: &Path, w: u32, h: u32) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x % 256) as u8, (y % 256) as u8, 128])).save(path).unwrap();
}

/// Writes a linear RGB EXR of the given size.
pub fn write_exr(path: &Path, w: usize, h: usize) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    exr::prelude::write_rgb_file(path, w, h, |x, y| (x as f32 / w as f32, y as f32 / h as f32, 0.5f32)).unwrap();
}

/// Hand-assembled binary little-endian PLY: float x y z vertices, `list uchar int` faces with one int
/// `segment_id` per face. Values are written verbatim (NaN, out-of-range indices, short lists all allowed).
pub fn binary_ply(vertices: &[[f32; 3]], faces: &[(Vec<i32>, i32)]) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nproperty int segment_id\nend_header\n",
        vertices.len(),
        faces.len()
    )
    .into_bytes();
    for v in vertices {
        for c in v {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for (idx, seg) in faces {
        out.push(idx.len() as u8);
        for i in idx {
            out.extend_from_slice(&i.to_le_bytes());
        }
        out.extend_from_slice(&seg.to_le_bytes());
    }
    out
}

/// SplitMix64: a tiny seeded generator so tests are reproducible without extra dependencies (also the
/// fuzzer's, `fuzz_support::mutate`).
#[derive(Debug, Clone)]
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// One of `items` (not empty), uniformly.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Row-major 4x4 as text.
pub fn row_major_text(m: &glam::DMat4) -> String {
    let t = m.transpose().to_cols_array();
    t.iter().map(|v| format!("{v:.17}")).collect::<Vec<_>>().join(" ")
}

/// Asserts that `err`'s message contains every needle.
pub fn assert_mentions(err: &impl std::fmt::Display, needles: &[&str]) {
    let msg = err.to_string();
    for n in needles {
        assert!(msg.contains(n), "error message {msg:?} does not mention {n:?}");
    }
}
