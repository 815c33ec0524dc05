//! The per-triangle texture atlas: layout rule, per-corner UVs, and the images (albedo sRGB PNG, albedo linear
//! EXR, glTF metallic-roughness PNG).
//!
//! # Layout rule
//! Triangle `t` owns the square cell `t` of `cell × cell` texels, cells in row-major order, `columns` per row.
//! The whole cell holds the triangle's constant value. The triangle's patch is the right triangle with
//! corners at texel offsets `(m, m)`, `(cell − m, m)`, `(m, cell − m)` inside the cell, margin `m = cell / 4`
//! (≥ 1 texel): a bilinear tap at any point of the patch reads texels whose centres lie within ½ texel of
//! it, all inside the cell, so full-resolution bilinear filtering never bleeds between triangles (and, cells
//! being power-of-two aligned, mip level ℓ stays clean while 2^ℓ ≤ m).
//!
//! Size: the width `W` is the smallest power of two with `(W / cell)² ≥ n` (a near-square grid of `W / cell`
//! columns); the height `H` is the smallest power of two holding `⌈n / columns⌉` rows of cells. With the
//! default `cell = 8`, an atlas wider than `max_size` (default 4096, a limit every desktop and mobile
//! renderer supports) falls back to `cell = 4`; if that is still too wide the export fails with
//! [`ExportError::AtlasTooLarge`] (4096 px holds 1 048 576 triangles at `cell = 4`).
//!
//! UVs follow glTF: `u` to the right, `v` down from the first image row, both normalised by `W` and `H`
//! (exact in f32: powers of two). OBJ's `vt` uses `v` up, so the OBJ writer stores `1 − v`.

use std::path::Path;

use glam::{Vec2, Vec3};

use ingest::srgb;

use super::ExportError;

/// Where each triangle's cell lies in the atlas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AtlasLayout {
    pub width: u32,
    pub height: u32,
    /// Cell side in texels (a power of two ≥ 4).
    pub cell: u32,
    pub columns: u32,
    pub triangles: u32,
}

/// Smallest cell the layout falls back to: with the `cell / 4` margin it leaves a 1-texel border and a
/// 2-texel patch, the least that keeps bilinear taps inside the cell.
pub const MIN_CELL: u32 = 4;

impl AtlasLayout {
    /// The layout for `triangles` triangles (see the module docs for the rule). `cell` must be a power of two
    /// ≥ [`MIN_CELL`]; `max_size` caps the width and height.
    pub fn new(triangles: usize, cell: u32, max_size: u32) -> Result<Self, ExportError> {
        if !cell.is_power_of_two() || cell < MIN_CELL {
            return Err(ExportError::Input {
                message: format!("atlas cell must be a power of two >= {MIN_CELL} texels, got {cell}"),
            });
        }
        let n = u64::try_from(triangles).unwrap_or(u64::MAX);
        if n == 0 || n > u64::from(u32::MAX) {
            return Err(ExportError::Input { message: format!("cannot lay out an atlas for {triangles} triangles") });
        }
        let mut cell = cell;
        loop {
            let cols_needed = n.isqrt() + u64::from(n.isqrt() * n.isqrt() < n); // ⌈√n⌉
            let width = (cols_needed * u64::from(cell)).next_power_of_two();
            let columns = width / u64::from(cell);
            let rows = n.div_ceil(columns);
            let height = (rows * u64::from(cell)).next_power_of_two();
            if width <= u64::from(max_size) && height <= u64::from(max_size) {
                // Both fit in u32: they are at most max_size.
                return Ok(Self {
                    width: width as u32,
                    height: height as u32,
                    cell,
                    columns: columns as u32,
                    triangles: n as u32,
                });
            }
            if cell / 2 < MIN_CELL {
                return Err(ExportError::AtlasTooLarge { triangles, max_size });
            }
            cell /= 2;
        }
    }

    /// Margin between the patch and the cell border, in texels.
    #[must_use]
    pub fn margin(&self) -> u32 {
        self.cell / 4
    }

    /// Top-left texel of triangle `t`'s cell.
    #[must_use]
    pub fn cell_origin(&self, t: u32) -> (u32, u32) {
        ((t % self.columns) * self.cell, (t / self.columns) * self.cell)
    }

    /// The triangle owning texel (x, y), if any.
    #[must_use]
    pub fn triangle_at(&self, x: u32, y: u32) -> Option<u32> {
        let t = (y / self.cell) * self.columns + x / self.cell;
        (x / self.cell < self.columns && t < self.triangles).then_some(t)
    }

    /// glTF UVs (v down) of triangle `t`'s three corners, in corner order.
    #[must_use]
    pub fn corner_uvs(&self, t: u32) -> [Vec2; 3] {
        let (x0, y0) = self.cell_origin(t);
        let (m, c) = (self.margin(), self.cell);
        let texel = [(x0 + m, y0 + m), (x0 + c - m, y0 + m), (x0 + m, y0 + c - m)];
        texel.map(|(x, y)| Vec2::new(x as f32 / self.width as f32, y as f32 / self.height as f32))
    }

    /// An 8-bit RGB image, every texel of cell t = `value(t)`, texels of unused cells black.
    fn rgb8(&self, value: impl Fn(u32) -> [u8; 3]) -> Vec<u8> {
        let mut out = vec![0u8; self.width as usize * self.height as usize * 3];
        for t in 0..self.triangles {
            let v = value(t);
            let (x0, y0) = self.cell_origin(t);
            for y in y0..y0 + self.cell {
                let row = (y as usize * self.width as usize + x0 as usize) * 3;
                for px in out[row..row + self.cell as usize * 3].chunks_exact_mut(3) {
                    px.copy_from_slice(&v);
                }
            }
        }
        out
    }
}

fn encode_png(path: &Path, layout: &AtlasLayout, rgb: &[u8]) -> Result<Vec<u8>, ExportError> {
    crate::display::encode_rgb8_png(layout.width, layout.height, rgb)
        .map_err(|e| ExportError::Encode { path: path.to_path_buf(), message: e.to_string() })
}

/// `albedo.png`: per-triangle albedo, sRGB-encoded 8-bit (values clamped to [0, 1]).
pub fn albedo_png(path: &Path, layout: &AtlasLayout, albedo: &[Vec3]) -> Result<Vec<u8>, ExportError> {
    let rgb = layout.rgb8(|t| albedo[t as usize].to_array().map(srgb::linear_to_srgb8));
    encode_png(path, layout, &rgb)
}

/// glTF metallic-roughness texture: G = roughness, B = metallic (linear 8-bit, clamped to [0, 1]); R is
/// unused by glTF and written as 255 (what an occlusion map packed there would mean "no occlusion").
pub fn metallic_roughness_png(
    path: &Path,
    layout: &AtlasLayout,
    roughness: &[f32],
    metallic: &[f32],
) -> Result<Vec<u8>, ExportError> {
    let rgb = layout.rgb8(|t| [255, srgb::to_u8(roughness[t as usize]), srgb::to_u8(metallic[t as usize])]);
    encode_png(path, layout, &rgb)
}

/// `albedo.exr`: per-triangle linear albedo, 32-bit float R, G, B (unclamped, ZIP-compressed), unused cells 0.
pub fn albedo_exr(path: &Path, layout: &AtlasLayout, albedo: &[Vec3]) -> Result<Vec<u8>, ExportError> {
    let l = *layout;
    // Small (ZIP): constant cells compress to a small fraction of the raw 12 bytes per texel; lossless.
    ingest::photo::exr::encode_rgb(l.width, l.height, ingest::photo::exr::Compression::Small, |x, y| {
        // Texel coordinates are below width/height, which fit in u32.
        l.triangle_at(x as u32, y as u32).map_or(Vec3::ZERO, |t| albedo[t as usize]).to_array()
    })
    .map_err(|e| ExportError::Encode { path: path.to_path_buf(), message: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_rule_is_smallest_power_of_two_grid() {
        let l = AtlasLayout::new(1, 8, 4096).unwrap();
        assert_eq!((l.width, l.height, l.columns), (8, 8, 1));
        // 5 triangles: ⌈√5⌉ = 3 columns needed → width 32 (4 columns), 2 rows → height 16.
        let l = AtlasLayout::new(5, 8, 4096).unwrap();
        assert_eq!((l.width, l.height, l.columns), (32, 16, 4));
        // 300 000 triangles need 548 columns: 8 texels → 8192 > 4096, so the cell falls back to 4.
        let l = AtlasLayout::new(300_000, 8, 4096).unwrap();
        assert_eq!((l.cell, l.width, l.columns), (4, 4096, 1024));
        assert!(u64::from(l.columns) * u64::from(l.height / l.cell) >= 300_000);
        assert!(matches!(AtlasLayout::new(2_000_000, 8, 4096), Err(ExportError::AtlasTooLarge { .. })));
        assert!(AtlasLayout::new(10, 6, 4096).is_err());
        assert!(AtlasLayout::new(0, 8, 4096).is_err());
    }

    #[test]
    fn patches_stay_inside_their_cells_with_margin() {
        let l = AtlasLayout::new(37, 8, 4096).unwrap();
        for t in 0..37 {
            let (x0, y0) = l.cell_origin(t);
            for uv in l.corner_uvs(t) {
                let (x, y) = (uv.x * l.width as f32, uv.y * l.height as f32);
                let m = l.margin() as f32;
                assert!(x >= x0 as f32 + m && x <= (x0 + l.cell) as f32 - m);
                assert!(y >= y0 as f32 + m && y <= (y0 + l.cell) as f32 - m);
            }
            assert_eq!(l.triangle_at(x0, y0), Some(t));
            assert_eq!(l.triangle_at(x0 + l.cell - 1, y0 + l.cell - 1), Some(t));
        }
        assert_eq!(l.triangle_at(l.width - 1, l.height - 1), None);
    }
}
