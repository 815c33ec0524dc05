//! Integer area downscaling in linear space, with intrinsics scaled consistently.

use super::{LinearImage, OpError};
use crate::camera::{Camera, Intrinsics};

/// Intrinsics of an image downscaled by `factor` (s). With pixel centres at integer coordinates, source pixel
/// u covers [u - 0.5, u + 0.5]; output pixel u' covers source [s·u' - 0.5, s·u' + s - 0.5], whose centre is
/// s·u' + (s - 1)/2. Inverting: u' = (u + 0.5)/s - 0.5, so c' = (c + 0.5)/s - 0.5 and f' = f/s.
#[must_use]
pub fn scale_intrinsics(k: &Intrinsics, factor: u32) -> Intrinsics {
    let s = f64::from(factor);
    Intrinsics { fx: k.fx / s, fy: k.fy / s, cx: (k.cx + 0.5) / s - 0.5, cy: (k.cy + 0.5) / s - 0.5 }
}

/// [`downscale_image`] with the camera updated to match: size and intrinsics ([`scale_intrinsics`]); its
/// distortion (which acts on normalised coordinates) and pose are kept.
pub fn downscale(image: &LinearImage, camera: &Camera, factor: u32) -> Result<(Camera, LinearImage), OpError> {
    let image = downscale_image(image, factor)?;
    let camera = Camera {
        width: image.width,
        height: image.height,
        intrinsics: scale_intrinsics(&camera.intrinsics, factor),
        ..*camera
    };
    Ok((camera, image))
}

/// Averages `factor × factor` blocks. The output is `floor(W/s) × floor(H/s)`: a partial block at the right or
/// bottom edge is dropped (cropping there does not move the origin, so the intrinsics formula still holds).
/// A block is valid only if all of its source pixels are valid.
pub fn downscale_image(image: &LinearImage, factor: u32) -> Result<LinearImage, OpError> {
    if factor == 0 {
        return Err(OpError::Invalid("downscale factor must be at least 1".into()));
    }
    let (w, h) = (image.width / factor, image.height / factor);
    if w == 0 || h == 0 {
        return Err(OpError::Invalid(format!(
            "downscale factor {factor} is larger than the image ({}x{})",
            image.width, image.height
        )));
    }
    let s = factor as usize;
    let src_w = image.width as usize;
    let inv_area = 1.0 / (s * s) as f64;
    let mut rgb = Vec::with_capacity(3 * w as usize * h as usize);
    let mut mask = Vec::with_capacity(w as usize * h as usize);
    for by in 0..h as usize {
        for bx in 0..w as usize {
            // Sum in f64: blocks can be large and radiance spans many orders of magnitude.
            let mut sum = [0.0f64; 3];
            let mut valid = true;
            for y in by * s..(by + 1) * s {
                for x in bx * s..(bx + 1) * s {
                    let i = y * src_w + x;
                    valid &= image.mask[i] != 0;
                    for c in 0..3 {
                        sum[c] += f64::from(image.rgb[3 * i + c]);
                    }
                }
            }
            rgb.extend(sum.iter().map(|v| (v * inv_area) as f32));
            mask.push(u8::from(valid));
        }
    }
    LinearImage::new(w, h, rgb, mask)
}
