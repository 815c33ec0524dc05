//! The one EXR writer of the workspace: linear RGB images, single-part files in memory (callers write the
//! bytes with [`crate::write_atomic`]). [`encode_rgb`] writes R, G, B as 32-bit float, losslessly (renders,
//! synthetic photos, the albedo atlas); [`encode_rgb_mask`] writes a prepared view of the photo cache: R, G, B
//! as 16-bit half float when the image's range allows it ([`half_keeps`]), else 32-bit, and the validity
//! mask, ZIP-compressed. Reading is [`super::image_io`]'s, which takes either sample type.

use std::io::Cursor;

use ::exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SpecificChannels, Vec2,
    WritableImage, f16,
};

/// An EXR the encoder could not write (only on allocation failure or an image larger than the format allows).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub struct ExrError(#[from] ::exr::error::Error);

/// Lossless compression of the written file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    /// Fast to write (RLE/ZIP1-class; `exr`'s `FAST_LOSSLESS`): photos, renders.
    #[default]
    Fast,
    /// Smaller files (ZIP over 16 lines; `exr`'s `SMALL_LOSSLESS`): piecewise-constant images such as the
    /// albedo atlas compress to a fraction of the raw 12 bytes per pixel.
    Small,
}

impl Compression {
    fn encoding(self) -> Encoding {
        match self {
            Compression::Fast => Encoding::FAST_LOSSLESS,
            Compression::Small => Encoding::SMALL_LOSSLESS,
        }
    }
}

/// A `width`×`height` RGB EXR whose pixel (x, y) is `pixel(x, y)` (row 0 at the top).
pub fn encode_rgb(
    width: u32,
    height: u32,
    compression: Compression,
    pixel: impl Fn(usize, usize) -> [f32; 3] + Sync,
) -> Result<Vec<u8>, ExrError> {
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let [r, g, b] = pixel(p.x(), p.y());
        (r, g, b)
    });
    let image = Image::from_encoded_channels((width as usize, height as usize), compression.encoding(), channels);
    let mut out = Cursor::new(Vec::new());
    // Sequential compression: the parallel writer stores blocks in the order they finish, so the same image
    // would give different bytes from run to run, and every artefact is hashed into its stage's manifest.
    image.write().non_parallel().to_buffered(&mut out)?;
    Ok(out.into_inner())
}

/// An RGB EXR of interleaved `rgb` (3 values per pixel, row-major).
pub fn encode_rgb_interleaved(
    width: u32,
    height: u32,
    compression: Compression,
    rgb: &[f32],
) -> Result<Vec<u8>, ExrError> {
    let w = width as usize;
    encode_rgb(width, height, compression, |x, y| {
        let i = 3 * (y * w + x);
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    })
}

/// Largest value of an image that the cache writes as half float: half's largest finite value.
const HALF_MAX: f32 = 65504.0;
/// Smallest image maximum that the cache writes as half float: half's smallest normal number (2⁻¹⁴). With
/// the maximum M at or above it, every value is kept within 2⁻¹¹ of itself (normal numbers) or within 2⁻²⁵
/// absolute (subnormals), and 2⁻²⁵ ≤ 2⁻¹¹·M: no value moves by more than 2⁻¹¹ (0.05 %) of the image's
/// maximum.
const HALF_MIN_MAX: f32 = 1.0 / 16384.0;

/// Whether half float keeps `rgb` to within 2⁻¹¹ of its largest value: every value finite and the largest in
/// half's normal range. A photo's own quantisation is coarser: one step of an 8-bit sRGB code is at least
/// 1/(255·12.92) ≈ 3·10⁻⁴ of the white point (docs/scale/README.md, "The run's disk cache", measures what the
/// cache's half float changes in the fitted materials).
#[must_use]
pub fn half_keeps(rgb: &[f32]) -> bool {
    let mut max = 0.0_f32;
    for &v in rgb {
        if !v.is_finite() {
            return false;
        }
        max = max.max(v.abs());
    }
    (HALF_MIN_MAX..=HALF_MAX).contains(&max)
}

/// An EXR with channels R, G, B and `mask` (1 where `mask` is non-zero, else 0), ZIP-compressed
/// (lossless). R, G, B are half float when [`half_keeps`] says so, else 32-bit float;
/// the mask is half float (0 and 1 are exact). `rgb` is interleaved (3 values per pixel), `mask` one value per
/// pixel; both row-major, sizes checked by the caller.
pub fn encode_rgb_mask(width: u32, height: u32, rgb: &[f32], mask: &[u8]) -> Result<Vec<u8>, ExrError> {
    let half = half_keeps(rgb);
    let channel = |c: usize| {
        let values = rgb.iter().skip(c).step_by(3).copied();
        if half { FlatSamples::F16(values.map(f16::from_f32).collect()) } else { FlatSamples::F32(values.collect()) }
    };
    let mask: Vec<f16> = mask.iter().map(|&m| if m != 0 { f16::ONE } else { f16::ZERO }).collect();
    let channels = AnyChannels::sort(
        vec![
            AnyChannel::new("R", channel(0)),
            AnyChannel::new("G", channel(1)),
            AnyChannel::new("B", channel(2)),
            AnyChannel::new("mask", FlatSamples::F16(mask)),
        ]
        .into(),
    );
    let size = (width as usize, height as usize);
    // ZIP over 16 scan lines: 9 % smaller than PIZ on the house's half-float photos (112 vs 126 kB of 20 480
    // pixels); scan-line blocks, which image_io's reader bounds by the image's width.
    let encoding = Encoding {
        compression: ::exr::compression::Compression::ZIP16,
        blocks: ::exr::image::Blocks::ScanLines,
        line_order: ::exr::meta::attribute::LineOrder::Increasing,
    };
    let image = Image::from_layer(Layer::new(size, LayerAttributes::default(), encoding, channels));
    let mut out = Cursor::new(Vec::new());
    image.write().non_parallel().to_buffered(&mut out)?;
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_image_always_encodes_to_the_same_bytes() {
        // 512 rows: dozens of compressed blocks, which a parallel writer would reorder.
        let pixel = |x: usize, y: usize| [(x * y % 97) as f32 / 97.0, (x + y) as f32 / 1024.0, ((x ^ y) % 13) as f32];
        let first = encode_rgb(512, 512, Compression::Fast, pixel).unwrap();
        for _ in 0..4 {
            assert!(encode_rgb(512, 512, Compression::Fast, pixel).unwrap() == first);
        }
    }
}
