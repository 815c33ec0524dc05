//! Renders of many pixels in blocks, one progress step per block: a render of millions of pixels (the
//! per-triangle stage's ratio steps, the export's detail shading) takes minutes, and without steps inside it
//! the log has no ETA for them. Random numbers are keyed by the pixel, so the blocks give exactly the values of
//! one render of all the pixels.

use glam::Vec3;
use tracer::{Camera, PixelRef, TraceStats, TracerError};

use crate::progress::{Stopped, check_stop};

/// Why a render in blocks ended early.
#[derive(Debug, thiserror::Error)]
pub enum BlockError {
    #[error(transparent)]
    Tracer(#[from] TracerError),
    /// The caller asked to stop; checked before every block.
    #[error(transparent)]
    Stopped(#[from] Stopped),
}

/// Pixels per block: small enough that a house's largest renders (millions of pixels) report every few
/// seconds, large enough that each block keeps both cores busy.
pub const RENDER_BLOCK: usize = 8192;

/// `renderer.render_pixels` of `pixels` in blocks of [`RENDER_BLOCK`], in a progress phase `phase` of one step
/// per block; the values are those of a single render, the work summed over the blocks. Stops before any block
/// once `progress` asks it to ([`BlockError::Stopped`]).
#[allow(clippy::too_many_arguments)]
pub fn render_blocks(
    renderer: &tracer::Renderer<'_>,
    cameras: &[Camera],
    pixels: &[PixelRef],
    spp: u32,
    seed: u64,
    key: u64,
    progress: &dyn crate::Progress,
    phase: &str,
) -> Result<(Vec<Vec3>, TraceStats), BlockError> {
    progress.phase(phase, pixels.len().div_ceil(RENDER_BLOCK) as u64, 0);
    let mut values = Vec::with_capacity(pixels.len());
    let mut work = TraceStats::default();
    let at = Blocks { renderer, cameras, seed, key, progress };
    at.render(pixels, spp, RENDER_BLOCK, &mut 0, &mut values, &mut work)?;
    Ok((values, work))
}

/// [`render_blocks`] with its own path count per pixel, `spp[i]` for `pixels[i]`: each pixel's value is the one a
/// render of it alone at that count gives (its paths are keyed by the pixel and the path's index). The pixels
/// of one count render together, in blocks of about `RENDER_BLOCK · max(spp)` paths, so that every block costs
/// about the same and the phase's ETA holds; with one count for all, this is [`render_blocks`].
#[allow(clippy::too_many_arguments)]
pub fn render_blocks_each(
    renderer: &tracer::Renderer<'_>,
    cameras: &[Camera],
    pixels: &[PixelRef],
    spp: &[u32],
    seed: u64,
    key: u64,
    progress: &dyn crate::Progress,
    phase: &str,
) -> Result<(Vec<Vec3>, TraceStats), BlockError> {
    debug_assert_eq!(pixels.len(), spp.len());
    let first = spp.first().copied().unwrap_or(1);
    if spp.iter().all(|&n| n == first) {
        return render_blocks(renderer, cameras, pixels, first, seed, key, progress, phase);
    }
    let most = spp.iter().copied().max().unwrap_or(1).max(1);
    // The pixels of each path count, in their order, the largest count first.
    let mut by_count: std::collections::BTreeMap<std::cmp::Reverse<u32>, Vec<usize>> = Default::default();
    for (i, &n) in spp.iter().enumerate() {
        by_count.entry(std::cmp::Reverse(n)).or_default().push(i);
    }
    let block_of = |n: u32| RENDER_BLOCK * (most / n.max(1)).max(1) as usize;
    let blocks: usize = by_count.iter().map(|(n, at)| at.len().div_ceil(block_of(n.0))).sum();
    progress.phase(phase, blocks as u64, 0);
    let mut values = vec![Vec3::ZERO; pixels.len()];
    let mut work = TraceStats::default();
    let mut done = 0;
    let at = Blocks { renderer, cameras, seed, key, progress };
    for (n, indices) in &by_count {
        let these: Vec<PixelRef> = indices.iter().map(|&i| pixels[i]).collect();
        let mut got = Vec::with_capacity(these.len());
        at.render(&these, n.0, block_of(n.0), &mut done, &mut got, &mut work)?;
        for (&i, v) in indices.iter().zip(got) {
            values[i] = v;
        }
    }
    Ok((values, work))
}

/// What every block of a render shares.
struct Blocks<'a, 'r> {
    renderer: &'a tracer::Renderer<'r>,
    cameras: &'a [Camera],
    seed: u64,
    key: u64,
    progress: &'a dyn crate::Progress,
}

impl Blocks<'_, '_> {
    /// `pixels` at `spp` paths each, in blocks of `block` pixels, their values appended to `values`; the
    /// phase's position counts on from `done`, one step per block, and a stop is checked before every block.
    fn render(
        &self,
        pixels: &[PixelRef],
        spp: u32,
        block: usize,
        done: &mut u64,
        values: &mut Vec<Vec3>,
        work: &mut TraceStats,
    ) -> Result<(), BlockError> {
        for chunk in pixels.chunks(block) {
            check_stop(self.progress)?;
            let (v, stats) = self.renderer.render_pixels(self.cameras, chunk, spp, self.seed, self.key)?;
            values.extend(v);
            work.add(&stats);
            *done += 1;
            self.progress.set_position(*done);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Vec3};
    use tracer::{Camera, Material, Params, PixelRef, Renderer, Scene, SceneInput, TracerSettings};

    use super::{render_blocks, render_blocks_each};
    use crate::progress::NoProgress;

    /// A floor of two triangles (material 0) under a downward-facing light quad (emitter 1), seen from above.
    fn lit_floor() -> (Scene, Params, Camera) {
        let v = Vec3::new;
        let positions = vec![
            v(-1.0, 0.0, -1.0),
            v(-1.0, 0.0, 1.0),
            v(1.0, 0.0, 1.0),
            v(1.0, 0.0, -1.0),
            v(-0.3, 1.0, -0.3),
            v(0.3, 1.0, -0.3),
            v(0.3, 1.0, 0.3),
            v(-0.3, 1.0, 0.3),
        ];
        let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let input = SceneInput {
            positions,
            triangles,
            normals: None,
            material_of_tri: vec![0, 0, 1, 1],
            emitter_of_tri: vec![0, 0, 1, 1],
        };
        let params = Params {
            materials: vec![Material { base_color: Vec3::splat(0.6), ..Material::default() }; 2],
            emission: vec![Vec3::ZERO, Vec3::splat(4.0)],
            horizon: Default::default(),
        };
        let view = glam::Mat4::look_at_rh(v(0.0, 0.9, 1.6), Vec3::ZERO, Vec3::Y);
        let cam = Camera::from_fov_y(8, 8, 1.2, Affine3A::from_mat4(view.inverse()));
        (Scene::new(input).expect("scene"), params, cam)
    }

    #[test]
    fn each_pixel_renders_as_alone_at_its_own_path_count() {
        let (scene, params, cam) = lit_floor();
        let settings = TracerSettings { max_depth: 4, rr_depth: 2, ..Default::default() };
        let renderer = Renderer::new(&scene, &params, &settings).expect("renderer");
        let pixels: Vec<PixelRef> = (0..8).flat_map(|y| (0..8).map(move |x| PixelRef { view: 0, x, y })).collect();
        let spp: Vec<u32> = (0..pixels.len()).map(|i| [5, 1, 3, 5, 2][i % 5]).collect();
        let (values, work) =
            render_blocks_each(&renderer, &[cam], &pixels, &spp, 7, 3, &NoProgress, "test").expect("render");
        for ((p, &n), v) in pixels.iter().zip(&spp).zip(&values) {
            let (alone, _) = renderer.render_pixels(&[cam], &[*p], n, 7, 3).expect("render");
            assert_eq!(v.to_array().map(f32::to_bits), alone[0].to_array().map(f32::to_bits), "pixel {p:?}");
        }
        assert_eq!(work.paths, spp.iter().map(|&n| u64::from(n)).sum::<u64>());
        assert!(values.iter().any(|v| v.max_element() > 0.0), "the floor is lit");
        // One count for all is the plain render of all the pixels.
        let (uniform, _) = render_blocks(&renderer, &[cam], &pixels, 4, 7, 3, &NoProgress, "test").expect("render");
        let (whole, _) = renderer.render_pixels(&[cam], &pixels, 4, 7, 3).expect("render");
        assert_eq!(uniform, whole);
    }
}
