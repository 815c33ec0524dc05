//! Display-referred code values → linear radiance: the sRGB transfer curve ([`crate::srgb`], default) or a recovered camera
//! response curve, divided by the exposure time when known; saturated pixels are masked.

use super::image_io::DisplayImage;
use super::mask::is_saturated;
use super::response::ResponseCurve;
use super::{LinearImage, OpError};
use crate::srgb::decode as srgb_to_linear;

/// Linearises a display-referred image. With `response`, code value z of channel c becomes `response(c, z)`
/// (16-bit codes are mapped onto the curve's 0..255 axis and interpolated); without, the sRGB curve. Values
/// are then divided by `exposure_time` (seconds) when given. Saturated pixels (see [`super::mask`]) and
/// pixels invalid in the input are masked.
pub fn linearise(
    img: &DisplayImage,
    response: Option<&ResponseCurve>,
    exposure_time: Option<f64>,
) -> Result<LinearImage, OpError> {
    let scale = match exposure_time {
        None => 1.0,
        Some(t) if t.is_finite() && t > 0.0 => (1.0 / t) as f32,
        Some(t) => return Err(OpError::Invalid(format!("exposure time must be positive and finite, got {t}"))),
    };
    if img.max_code == 0 {
        return Err(OpError::Invalid("maximum code value is 0".into()));
    }
    let max = f32::from(img.max_code);
    // Per-channel lookup table over every possible code: 256 or 65536 entries, cheaper than per-pixel powf.
    let lut: Vec<[f32; 3]> = (0..=img.max_code)
        .map(|z| {
            let n = f32::from(z) / max;
            match response {
                Some(curve) => std::array::from_fn(|c| curve.eval(c, n * 255.0) * scale),
                None => [srgb_to_linear(n) * scale; 3],
            }
        })
        .collect();
    let n = img.width as usize * img.height as usize;
    let mut rgb = Vec::with_capacity(3 * n);
    let mut mask = Vec::with_capacity(n);
    for (px, &m) in img.codes.chunks_exact(3).zip(&img.mask) {
        let codes = [px[0], px[1], px[2]];
        for (c, &z) in codes.iter().enumerate() {
            rgb.push(lut[usize::from(z.min(img.max_code))][c]);
        }
        mask.push(u8::from(m != 0 && !is_saturated(codes, img.max_code)));
    }
    LinearImage::new(img.width, img.height, rgb, mask)
}
