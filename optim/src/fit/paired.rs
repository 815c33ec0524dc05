//! What model selection's paired held-out comparisons share (`super::select`'s lobe and emission tests,
//! `super::horizon`'s split test): the thresholds a term must pass, and the two renders of the same pixels with
//! common random numbers that each test compares.

use super::FitError;
use super::jacobian::Ctx;
use super::pixels::Sample;
use crate::blocks::RENDER_BLOCK;
use crate::progress::check_stop;
use tracer::PixelRef;

/// A term is kept when the paired t-statistic of its held-out improvement exceeds 3 (one-sided p ≈ 0.1 %:
/// with tens of objects, a spurious acceptance is unlikely)…
pub(super) const T_KEEP: f64 = 3.0;
/// …and the improvement is at least 0.5 % of the mean held-out |target| (a statistically clear but practically
/// invisible gain does not justify extra parameters; on the glossy fixture the floor's lobe gains 4.2 % and
/// the box's 12 %, while on it and on the default scene every diffuse wall's best lobe made the residual worse).
pub(super) const MIN_GAIN: f64 = 0.005;

/// Two renders of the same pixels with the same random numbers (`key`), in blocks of [`RENDER_BLOCK`]
/// pixels (a house's lobe test renders ~3·10⁵ pixels at `holdout_spp`, minutes per render), one progress step per block and arm in a phase `phase`. Random numbers are keyed by the pixel, so
/// the blocks give exactly the values of one render of all the pixels.
pub(super) fn paired_renders(
    ctx: &Ctx<'_>,
    (a, b): (&tracer::Params, &tracer::Params),
    pixels: &[PixelRef],
    spp: u32,
    key: u64,
    progress: &dyn crate::Progress,
    phase: &str,
) -> Result<(Vec<glam::Vec3>, Vec<glam::Vec3>), FitError> {
    let blocks = pixels.len().div_ceil(RENDER_BLOCK);
    progress.phase(phase, 2 * blocks as u64, 0);
    let (mut out_a, mut out_b) = (Vec::with_capacity(pixels.len()), Vec::with_capacity(pixels.len()));
    for (i, block) in pixels.chunks(RENDER_BLOCK).enumerate() {
        check_stop(progress)?;
        out_a.extend(ctx.render(a, block, spp, key)?);
        progress.set_position(2 * i as u64 + 1);
        out_b.extend(ctx.render(b, block, spp, key)?);
        progress.set_position(2 * i as u64 + 2);
    }
    Ok((out_a, out_b))
}

/// The L1 distance of two RGB values (summed over the channels).
pub(super) fn l1(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).sum()
}

/// A sample's photo value as f64 RGB.
pub(super) fn target(s: &Sample) -> [f64; 3] {
    [f64::from(s.target.x), f64::from(s.target.y), f64::from(s.target.z)]
}
