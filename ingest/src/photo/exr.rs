//! The one EXR writer of the workspace: linear RGB images as 32-bit float, lossless, single-part files in
//! memory (callers write the bytes with [`crate::write_atomic`]). [`encode_rgb`] writes R, G, B (renders,
//! synthetic photos, the albedo atlas); [`encode_rgb_mask`] adds the validity mask of a prepared view (the
//! photo cache). Reading is [`super::image_io`]'s.

use std::io::Cursor;

use ::exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SpecificChannels, Vec2,
    WritableImage,
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

/// An EXR with channels R, G, B and `mask` (1 where `mask` is non-zero, else 0), fast lossless compression.
/// `rgb` is interleaved (3 values per pixel), `mask` one value per pixel; both row-major, sizes checked by
/// the caller.
pub fn encode_rgb_mask(width: u32, height: u32, rgb: &[f32], mask: &[u8]) -> Result<Vec<u8>, ExrError> {
    let channel = |c: usize| rgb.iter().skip(c).step_by(3).copied().collect::<Vec<f32>>();
    let mask: Vec<f32> = mask.iter().map(|&m| if m != 0 { 1.0 } else { 0.0 }).collect();
    let channels = AnyChannels::sort(
        vec![
            AnyChannel::new("R", FlatSamples::F32(channel(0))),
            AnyChannel::new("G", FlatSamples::F32(channel(1))),
            AnyChannel::new("B", FlatSamples::F32(channel(2))),
            AnyChannel::new("mask", FlatSamples::F32(mask)),
        ]
        .into(),
    );
    let size = (width as usize, height as usize);
    let image = Image::from_layer(Layer::new(size, LayerAttributes::default(), Encoding::FAST_LOSSLESS, channels));
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
