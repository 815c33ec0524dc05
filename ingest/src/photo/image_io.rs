//! Decoding photo files: OpenEXR (exr crate) and Radiance `.hdr` (image crate) as linear radiance; PNG/JPEG
//! (8 or 16 bit, grey or RGB, optional alpha) as display-referred code values.

use std::io::Cursor;
use std::path::Path;

use image::DynamicImage;

use super::{LinearImage, PhotoError};

/// First four bytes of every OpenEXR file.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Display-referred code values (not yet linear), as stored in a PNG/JPEG.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayImage {
    pub width: u32,
    pub height: u32,
    /// 255 for 8-bit files, 65535 for 16-bit files.
    pub max_code: u16,
    /// Interleaved RGB code values in `0..=max_code` (grey files repeat the grey value).
    pub codes: Vec<u16>,
    /// 1 = valid. Pixels with alpha 0 are invalid; everything else starts valid.
    pub mask: Vec<u8>,
}

/// A decoded photo: either already linear radiance or display-referred code values.
#[derive(Debug, Clone, PartialEq)]
pub enum DecodedImage {
    Linear(LinearImage),
    Display(DisplayImage),
}

impl DecodedImage {
    /// (width, height) in pixels.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        match self {
            Self::Linear(i) => (i.width, i.height),
            Self::Display(i) => (i.width, i.height),
        }
    }
}

/// Reads and decodes one photo. EXR is recognised by its magic number, everything else by the image crate's
/// format sniffing (PNG, JPEG, Radiance HDR).
pub fn read_image(path: &Path) -> Result<DecodedImage, PhotoError> {
    let bytes = std::fs::read(path).map_err(|source| PhotoError::Read { path: path.to_path_buf(), source })?;
    if bytes.starts_with(&EXR_MAGIC) {
        return read_exr_bytes(path, bytes).map(DecodedImage::Linear);
    }
    let img = image::load_from_memory(&bytes)
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: e.to_string() })?;
    let (width, height) = (img.width(), img.height());
    match img {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => {
            let mut rgb = img.to_rgb32f().into_raw();
            let mask = linear_validity(&mut rgb, None);
            Ok(DecodedImage::Linear(LinearImage { width, height, rgb, mask }))
        }
        DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageRgb8(_)
        | DynamicImage::ImageRgba8(_) => {
            let rgba = img.to_rgba8().into_raw();
            Ok(DecodedImage::Display(display_from_rgba(width, height, 255, rgba.into_iter().map(u16::from))))
        }
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA16(_)
        | DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_) => {
            let rgba = img.to_rgba16().into_raw();
            Ok(DecodedImage::Display(display_from_rgba(width, height, u16::MAX, rgba.into_iter())))
        }
        other => Err(PhotoError::Unsupported {
            path: path.to_path_buf(),
            message: format!("pixel type {:?} is neither 8/16-bit nor float", other.color()),
        }),
    }
}

fn display_from_rgba(width: u32, height: u32, max_code: u16, rgba: impl Iterator<Item = u16>) -> DisplayImage {
    let n = width as usize * height as usize;
    let mut codes = Vec::with_capacity(3 * n);
    let mut mask = Vec::with_capacity(n);
    let rgba: Vec<u16> = rgba.collect();
    for px in rgba.chunks_exact(4) {
        codes.extend_from_slice(&px[..3]);
        mask.push(u8::from(px[3] != 0));
    }
    DisplayImage { width, height, max_code, codes, mask }
}

/// Linear pixels are valid when every channel is finite and non-negative (negative radiance is meaningless),
/// and, if a mask channel is given, its value is at least 0.5 (it is written as exactly 0 or 1). Non-finite or
/// negative values are replaced by 0 so that no NaN reaches a later `mask * value` product.
fn linear_validity(rgb: &mut [f32], mask_channel: Option<&[f32]>) -> Vec<u8> {
    rgb.chunks_exact_mut(3)
        .enumerate()
        .map(|(i, c)| {
            let finite = c.iter().all(|v| v.is_finite() && *v >= 0.0);
            if !finite {
                c.iter_mut().filter(|v| !(v.is_finite() && **v >= 0.0)).for_each(|v| *v = 0.0);
            }
            let flagged = mask_channel.is_none_or(|m| m[i] >= 0.5);
            u8::from(finite && flagged)
        })
        .collect()
}

/// Decodes an OpenEXR file's first layer: channels R, G, B (or a single Y, replicated) plus an optional
/// `mask` channel (our cache files).
fn read_exr_bytes(path: &Path, bytes: Vec<u8>) -> Result<LinearImage, PhotoError> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: e.to_string() })?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.x(), layer.size.y());
    let width = u32::try_from(w)
        .map_err(|_| PhotoError::Unsupported { path: path.to_path_buf(), message: format!("width {w} too large") })?;
    let height = u32::try_from(h)
        .map_err(|_| PhotoError::Unsupported { path: path.to_path_buf(), message: format!("height {h} too large") })?;
    let channel = |name: &str| -> Option<Vec<f32>> {
        layer.channel_data.list.iter().find(|c| c.name.eq(name)).map(|c| c.sample_data.values_as_f32().collect())
    };
    let (r, g, b) = match (channel("R"), channel("G"), channel("B"), channel("Y")) {
        (Some(r), Some(g), Some(b), _) => (r, g, b),
        (_, _, _, Some(y)) => (y.clone(), y.clone(), y),
        _ => {
            let names: Vec<String> = layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
            return Err(PhotoError::Unsupported {
                path: path.to_path_buf(),
                message: format!("no R, G, B or Y channel (channels: {})", names.join(", ")),
            });
        }
    };
    let n = w * h;
    if r.len() != n || g.len() != n || b.len() != n {
        return Err(PhotoError::Decode { path: path.to_path_buf(), message: "channel sizes differ".into() });
    }
    let mut rgb = Vec::with_capacity(3 * n);
    for i in 0..n {
        rgb.extend_from_slice(&[r[i], g[i], b[i]]);
    }
    let mask_channel = channel("mask");
    let mask = linear_validity(&mut rgb, mask_channel.as_deref());
    Ok(LinearImage { width, height, rgb, mask })
}
