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
//!
//! # Layout with sub-triangle detail
//! When triangles carry texel grids (`optim::triangle::detail`), each triangle gets a square cell of its own
//! power-of-two side ([`AtlasLayout::with_detail`]): a triangle with an n-cell grid gets the smallest side
//! ≥ n + 2 and a 1-texel margin (its patch's legs span side − 2 texels, so every grid cell covers at least one
//! texel; bilinear taps inside the patch stay inside the cell at full resolution, mip levels may bleed), the
//! others the plain `cell` with its `cell / 4` margin. Cells are sorted by side, largest first (then by
//! triangle), and placed in Morton (Z) order inside a `W × W` square, `W` the smallest power of two holding
//! their area and the largest cell: squares of power-of-two sides in decreasing order tile a Z-order without
//! gaps, each aligned to its own side. `H` is the smallest power of two holding the rows used. A texel of a
//! detailed patch takes the grid cell under its centre's barycentrics; the texels of the margin, the cell
//! beyond the diagonal included, take the nearest grid cell.

use std::path::Path;

use glam::{Vec2, Vec3};

use ingest::srgb;
use optim::triangle::detail::{TexelGrid, into_triangle};

use super::ExportError;

/// Where each triangle's cell lies in the atlas.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AtlasLayout {
    pub width: u32,
    pub height: u32,
    /// Cell side in texels (a power of two ≥ 4); with detail, the side of the triangles without a grid.
    pub cell: u32,
    pub columns: u32,
    pub triangles: u32,
    /// With detail: per triangle its cell (top-left x, y, side, margin); `None`: the uniform row-major grid.
    pub cells: Option<Vec<[u32; 4]>>,
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
                    cells: None,
                });
            }
            if cell / 2 < MIN_CELL {
                return Err(ExportError::AtlasTooLarge { triangles, max_size });
            }
            cell /= 2;
        }
    }

    /// The layout for triangles of which some carry a texel grid (`detail[t]`; module docs, "Layout with
    /// sub-triangle detail"); `cell` is the side of the others.
    pub fn with_detail(detail: &[Option<TexelGrid>], cell: u32, max_size: u32) -> Result<Self, ExportError> {
        let plain = Self::new(detail.len(), cell, max_size)?;
        let side_margin: Vec<(u32, u32)> = detail
            .iter()
            .map(|g| match g {
                Some(g) if g.n >= 2 => ((g.n + 2).next_power_of_two(), 1),
                _ => (plain.cell, plain.cell / 4),
            })
            .collect();
        let mut order: Vec<u32> = (0..detail.len() as u32).collect();
        order.sort_by_key(|&t| (std::cmp::Reverse(side_margin[t as usize].0), t));
        let area: u64 = side_margin.iter().map(|&(s, _)| u64::from(s) * u64::from(s)).sum();
        let largest = side_margin.iter().map(|&(s, _)| s).max().unwrap_or(plain.cell);
        let mut width = u64::from(largest).max(area.isqrt().next_power_of_two());
        while width * width < area {
            width *= 2;
        }
        if width > u64::from(max_size) {
            return Err(ExportError::AtlasTooLarge { triangles: detail.len(), max_size });
        }
        let mut cells = vec![[0u32; 4]; detail.len()];
        let mut offset = 0u64; // texel area placed so far: a multiple of every later cell's area
        let mut bottom = 0u64;
        for &t in &order {
            let (side, margin) = side_margin[t as usize];
            let s = u64::from(side);
            let (cx, cy) = morton_decode(offset / (s * s));
            let (x, y) = (cx * s, cy * s);
            cells[t as usize] = [x as u32, y as u32, side, margin];
            bottom = bottom.max(y + s);
            offset += s * s;
        }
        let height = bottom.next_power_of_two();
        Ok(Self {
            width: width as u32,
            height: height as u32,
            cell: plain.cell,
            columns: (width / u64::from(plain.cell)) as u32,
            triangles: detail.len() as u32,
            cells: Some(cells),
        })
    }

    /// Triangle `t`'s cell: top-left texel, side and margin.
    #[must_use]
    pub fn cell_of(&self, t: u32) -> [u32; 4] {
        match &self.cells {
            Some(c) => c[t as usize],
            None => [(t % self.columns) * self.cell, (t / self.columns) * self.cell, self.cell, self.cell / 4],
        }
    }

    /// glTF UVs (v down) of triangle `t`'s three corners, in corner order.
    #[must_use]
    pub fn corner_uvs(&self, t: u32) -> [Vec2; 3] {
        let [x0, y0, c, m] = self.cell_of(t);
        let texel = [(x0 + m, y0 + m), (x0 + c - m, y0 + m), (x0 + m, y0 + c - m)];
        texel.map(|(x, y)| Vec2::new(x as f32 / self.width as f32, y as f32 / self.height as f32))
    }

    /// Barycentrics (u, v) of the centre of texel (x, y) of triangle `t`'s cell (offsets inside the cell),
    /// clamped into the triangle: the patch maps corner 1 along x and corner 2 along y.
    #[must_use]
    pub fn texel_bary(&self, t: u32, x: u32, y: u32) -> Vec2 {
        let [_, _, c, m] = self.cell_of(t);
        let leg = (c - 2 * m) as f32;
        into_triangle(Vec2::new((x as f32 + 0.5 - m as f32) / leg, (y as f32 + 0.5 - m as f32) / leg))
    }

    /// Row-major texel values, `value(t, x, y)` for texel (x, y) of triangle t's cell, `empty` elsewhere.
    fn fill<T: Copy>(&self, empty: T, value: impl Fn(u32, u32, u32) -> T) -> Vec<T> {
        let mut out = vec![empty; self.width as usize * self.height as usize];
        for t in 0..self.triangles {
            let [x0, y0, c, _] = self.cell_of(t);
            for y in 0..c {
                let row = (y0 + y) as usize * self.width as usize + x0 as usize;
                for (x, px) in out[row..row + c as usize].iter_mut().enumerate() {
                    *px = value(t, x as u32, y);
                }
            }
        }
        out
    }

    /// An 8-bit RGB image from per-texel values, texels of unused cells black.
    fn rgb8(&self, value: impl Fn(u32, u32, u32) -> [u8; 3]) -> Vec<u8> {
        self.fill([0u8; 3], value).into_iter().flatten().collect()
    }
}

/// (x, y) of Morton index `m` (x from the even bits, y from the odd bits).
fn morton_decode(m: u64) -> (u64, u64) {
    let compact = |mut v: u64| {
        v &= 0x5555_5555_5555_5555;
        v = (v | (v >> 1)) & 0x3333_3333_3333_3333;
        v = (v | (v >> 2)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v >> 4)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v >> 8)) & 0x0000_ffff_0000_ffff;
        (v | (v >> 16)) & 0x0000_0000_ffff_ffff
    };
    (compact(m), compact(m >> 1))
}

/// Linear albedo per texel: the triangle's grid value under the texel when it has one, else its base colour.
#[must_use]
pub fn albedo_texels(layout: &AtlasLayout, albedo: &[Vec3], detail: Option<&[Option<TexelGrid>]>) -> Vec<Vec3> {
    layout.fill(Vec3::ZERO, |t, x, y| match detail.and_then(|d| d[t as usize].as_ref()) {
        Some(g) => g.at(layout.texel_bary(t, x, y)),
        None => albedo[t as usize],
    })
}

fn encode_png(path: &Path, layout: &AtlasLayout, rgb: &[u8]) -> Result<Vec<u8>, ExportError> {
    crate::display::encode_rgb8_png(layout.width, layout.height, rgb)
        .map_err(|e| ExportError::Encode { path: path.to_path_buf(), message: e.to_string() })
}

/// `albedo.png`: the albedo texels ([`albedo_texels`]), sRGB-encoded 8-bit (values clamped to [0, 1]).
pub fn albedo_png(path: &Path, layout: &AtlasLayout, texels: &[Vec3]) -> Result<Vec<u8>, ExportError> {
    let rgb: Vec<u8> = texels.iter().flat_map(|v| v.to_array().map(srgb::linear_to_srgb8)).collect();
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
    let rgb = layout.rgb8(|t, _, _| [255, srgb::to_u8(roughness[t as usize]), srgb::to_u8(metallic[t as usize])]);
    encode_png(path, layout, &rgb)
}

/// `albedo.exr`: the linear albedo texels ([`albedo_texels`]), 32-bit float R, G, B (unclamped,
/// ZIP-compressed), unused cells 0.
pub fn albedo_exr(path: &Path, layout: &AtlasLayout, texels: &[Vec3]) -> Result<Vec<u8>, ExportError> {
    let w = layout.width as usize;
    // Small (ZIP): constant cells compress to a small fraction of the raw 12 bytes per texel; lossless.
    ingest::photo::exr::encode_rgb(layout.width, layout.height, ingest::photo::exr::Compression::Small, |x, y| {
        texels[y * w + x].to_array()
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
    fn detail_cells_tile_without_overlap_and_texels_read_their_grid() {
        // Grids of sides 2, 30 and 7 among plain triangles; grid value = (i, j, triangle) so a texel says
        // which cell it read.
        let grid = |t: usize, n: u32| TexelGrid {
            n,
            texels: (0..n * n).map(|k| Vec3::new((k / n) as f32, (k % n) as f32, t as f32)).collect(),
        };
        let detail: Vec<Option<TexelGrid>> = (0..40)
            .map(|t| match t {
                3 => Some(grid(t, 2)),
                11 => Some(grid(t, 30)),
                12 => Some(grid(t, 7)),
                _ => None,
            })
            .collect();
        let l = AtlasLayout::with_detail(&detail, 8, 4096).unwrap();
        // Sides: 30 + 2 → 32, 7 + 2 → 16, 2 + 2 → 4; the plain cells keep 8.
        assert_eq!(l.cell_of(11)[2..], [32, 1]);
        assert_eq!(l.cell_of(12)[2..], [16, 1]);
        assert_eq!(l.cell_of(3)[2..], [4, 1]);
        assert_eq!(l.cell_of(0)[2..], [8, 2]);
        let mut owner = vec![u32::MAX; (l.width * l.height) as usize];
        for t in 0..40 {
            let [x0, y0, c, _] = l.cell_of(t);
            assert!(x0 + c <= l.width && y0 + c <= l.height && x0 % c == 0 && y0 % c == 0);
            for y in y0..y0 + c {
                for x in x0..x0 + c {
                    let o = &mut owner[(y * l.width + x) as usize];
                    assert_eq!(*o, u32::MAX, "texel ({x}, {y}) of {t} already belongs to {o}");
                    *o = t;
                }
            }
        }
        // A point of triangle 11 at barycentrics (u, v) lands, through its corner UVs, on a texel that reads the
        // grid cell holding (u, v).
        let albedo = vec![Vec3::splat(0.5); 40];
        let texels = albedo_texels(&l, &albedo, Some(&detail));
        let uv = l.corner_uvs(11);
        for &(u, v) in &[(0.1f32, 0.1f32), (0.52, 0.3), (0.05, 0.9), (0.33, 0.33)] {
            let p = uv[0] * (1.0 - u - v) + uv[1] * u + uv[2] * v;
            let (x, y) = ((p.x * l.width as f32) as u32, (p.y * l.height as f32) as u32);
            let got = texels[(y * l.width + x) as usize];
            let (i, j) = (u * 30.0, v * 30.0);
            assert_eq!(got.z, 11.0);
            // Within one grid cell: an atlas texel (30 cells on 30 texels here) can straddle two cells.
            assert!((got.x - i).abs() <= 1.0 && (got.y - j).abs() <= 1.0, "({u}, {v}): {got}");
        }
        // A plain triangle's texels hold its base colour.
        let [x0, y0, _, _] = l.cell_of(0);
        assert_eq!(texels[(y0 * l.width + x0) as usize], Vec3::splat(0.5));
    }

    #[test]
    fn patches_stay_inside_their_cells_with_margin() {
        let l = AtlasLayout::new(37, 8, 4096).unwrap();
        // The owner of every texel, as the images are filled.
        let owner = l.fill(None, |t, _, _| Some(t));
        let at = |x: u32, y: u32| owner[(y * l.width + x) as usize];
        for t in 0..37 {
            let [x0, y0, _, m] = l.cell_of(t);
            assert_eq!(m, l.cell / 4);
            for uv in l.corner_uvs(t) {
                let (x, y) = (uv.x * l.width as f32, uv.y * l.height as f32);
                let m = m as f32;
                assert!(x >= x0 as f32 + m && x <= (x0 + l.cell) as f32 - m);
                assert!(y >= y0 as f32 + m && y <= (y0 + l.cell) as f32 - m);
            }
            assert_eq!(at(x0, y0), Some(t));
            assert_eq!(at(x0 + l.cell - 1, y0 + l.cell - 1), Some(t));
        }
        assert_eq!(at(l.width - 1, l.height - 1), None);
    }
}
