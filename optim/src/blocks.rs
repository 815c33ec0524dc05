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
    for (i, block) in pixels.chunks(RENDER_BLOCK).enumerate() {
        check_stop(progress)?;
        let (v, stats) = renderer.render_pixels(cameras, block, spp, seed, key)?;
        values.extend(v);
        work.add(&stats);
        progress.set_position(i as u64 + 1);
    }
    Ok((values, work))
}
