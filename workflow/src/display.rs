//! Display encodings of linear images for report.html: the exposure that frames an image, 8-bit sRGB PNG
//! (curve: `ingest::srgb`), the error heat map, and base64 for `data:` URIs. Linear values are the physics;
//! these are for viewing only.

use ingest::srgb::linear_to_srgb8 as srgb8;

/// A linear RGB image to show (interleaved, row-major, top row first).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<f32>,
}

/// Standard base64 (RFC 4648 §4, with padding).
#[must_use]
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The exposure scale that maps the 99th percentile of an image's channel values to 1 (so a few bright
/// pixels, e.g. a visible lamp, do not darken the whole picture); 1 for an all-black image.
#[must_use]
pub fn exposure_for(img: &RgbImage) -> f32 {
    let mut v: Vec<f32> = img.rgb.iter().copied().filter(|x| x.is_finite() && *x > 0.0).collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() - 1) as f64 * 0.99) as usize;
    let (_, p, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    1.0 / *p
}

/// PNG bytes of a linear image times `scale`, sRGB-encoded.
#[must_use]
pub fn png_srgb(img: &RgbImage, scale: f32) -> Vec<u8> {
    let buf: Vec<u8> = img.rgb.iter().map(|&x| srgb8(x * scale)).collect();
    encode_png(img.width, img.height, buf)
}

/// PNG of the per-pixel error |render − photo| (mean over channels) times `scale`, as a black → red →
/// yellow → white heat map; masked pixels black.
#[must_use]
pub fn png_error_map(photo: &RgbImage, render: &RgbImage, mask: &[u8], scale: f32) -> Vec<u8> {
    let n = photo.width as usize * photo.height as usize;
    let mut buf = Vec::with_capacity(3 * n);
    for i in 0..n {
        let valid = mask.get(i).is_none_or(|&m| m != 0);
        let e = if valid {
            (0..3).map(|c| (render.rgb[3 * i + c] - photo.rgb[3 * i + c]).abs()).sum::<f32>() / 3.0 * scale
        } else {
            0.0
        };
        let t = e.clamp(0.0, 1.0) * 3.0;
        let rgb = [t.min(1.0), (t - 1.0).clamp(0.0, 1.0), (t - 2.0).clamp(0.0, 1.0)];
        buf.extend(rgb.map(|x| (x * 255.0).round() as u8));
    }
    encode_png(photo.width, photo.height, buf)
}

fn encode_png(width: u32, height: u32, buf: Vec<u8>) -> Vec<u8> {
    encode_rgb8_png(width, height, &buf).expect("PNG encoding of a 3·width·height buffer into memory does not fail")
}

/// The one PNG encoder of the crate: 8-bit RGB rows, top row first, `rgb.len() == 3·width·height`.
pub fn encode_rgb8_png(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, image::ImageError> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out).write_image(rgb, width, height, image::ExtendedColorType::Rgb8)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        // RFC 4648 §10.
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), want);
        }
    }

    #[test]
    fn srgb_curve_hits_its_defining_points() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        // 18 % grey is sRGB code 118 (0.4613 · 255 = 117.6).
        assert_eq!(srgb8(0.18), 118);
        assert_eq!(srgb8(2.0), 255);
    }

    #[test]
    fn png_decodes_back_to_the_encoded_codes() {
        let img = RgbImage { width: 2, height: 1, rgb: vec![0.0, 0.18, 1.0, 0.5, 0.5, 0.5] };
        let png = png_srgb(&img, 1.0);
        let back = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (2, 1));
        assert_eq!(back.as_raw(), &vec![0, 118, 255, srgb8(0.5), srgb8(0.5), srgb8(0.5)]);
    }

    #[test]
    fn exposure_maps_the_99th_percentile_to_one() {
        let mut rgb: Vec<f32> = (1..=300).map(|i| i as f32).collect();
        rgb[299] = 1e6; // one very bright lamp pixel must not set the exposure
        let img = RgbImage { width: 10, height: 10, rgb };
        let s = exposure_for(&img);
        assert!((1.0 / s - 297.0).abs() <= 1.0, "{}", 1.0 / s);
    }
}
