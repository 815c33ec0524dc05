//! Decoding photo files: OpenEXR (exr crate) and Radiance `.hdr` (image crate) as linear radiance; PNG/JPEG
//! (8 or 16 bit, grey or RGB, optional alpha) as display-referred code values.

use std::io::Cursor;
use std::path::Path;

use image::DynamicImage;

use super::{LinearImage, PhotoError};
use crate::error::one_line;

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

/// Pixels of a linear photo masked on decoding because their value is not a radiance. They are set to 0 and
/// marked invalid in the mask, so no loss sees them; the counts let the caller report them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PixelReport {
    /// Pixels with a NaN or infinite channel.
    pub non_finite: usize,
    /// Pixels whose channels are finite but at least one is negative.
    pub negative: usize,
}

impl PixelReport {
    /// Total number of pixels masked on decoding.
    #[must_use]
    pub fn masked(&self) -> usize {
        self.non_finite + self.negative
    }
}

/// Reads and decodes one photo. EXR is recognised by its magic number, everything else by the image crate's
/// format sniffing (PNG, JPEG, Radiance HDR).
pub fn read_image(path: &Path) -> Result<DecodedImage, PhotoError> {
    read_image_checked(path, None).map(|(image, _)| image)
}

/// [`read_image`] with the pixels masked on decoding counted. With `expected` = (width, height), a file whose
/// header declares another size is refused before any pixel buffer is allocated, so the memory a file can
/// make the decoder take is bounded by its calibration, not by its own header.
pub fn read_image_checked(
    path: &Path,
    expected: Option<(u32, u32)>,
) -> Result<(DecodedImage, PixelReport), PhotoError> {
    let bytes = std::fs::read(path).map_err(|source| PhotoError::Read { path: path.to_path_buf(), source })?;
    decode_image(path, &bytes, expected)
}

/// [`read_image_checked`] on a file's bytes already in memory; `path` is used only in error messages.
pub fn decode_image(
    path: &Path,
    bytes: &[u8],
    expected: Option<(u32, u32)>,
) -> Result<(DecodedImage, PixelReport), PhotoError> {
    if let Some((ew, eh)) = expected {
        let found = crate::image_header::image_dimensions_bytes(path, bytes)
            .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: header_message(&e) })?;
        if found != (ew, eh) {
            return Err(PhotoError::WrongSize { path: path.to_path_buf(), expected: (ew, eh), found });
        }
    }
    let (image, report) = if bytes.starts_with(&crate::image_header::EXR_MAGIC) {
        let (img, report) = read_exr_bytes(path, bytes)?;
        (DecodedImage::Linear(img), report)
    } else {
        decode_other(path, bytes)?
    };
    if let Some((ew, eh)) = expected
        && image.size() != (ew, eh)
    {
        return Err(PhotoError::WrongSize { path: path.to_path_buf(), expected: (ew, eh), found: image.size() });
    }
    Ok((image, report))
}

/// The message of a header error without its leading path (the photo error adds it again).
fn header_message(e: &crate::IngestError) -> String {
    match e {
        crate::IngestError::Format { message, .. } => message.clone(),
        other => other.to_string(),
    }
}

fn decode_other(path: &Path, bytes: &[u8]) -> Result<(DecodedImage, PixelReport), PhotoError> {
    let img = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: one_line(e) })?
        .decode()
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: one_line(e) })?;
    let (width, height) = (img.width(), img.height());
    Ok(match img {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => {
            let mut rgb = img.to_rgb32f().into_raw();
            let (mask, report) = linear_validity(&mut rgb, None);
            (DecodedImage::Linear(LinearImage { width, height, rgb, mask }), report)
        }
        DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageRgb8(_)
        | DynamicImage::ImageRgba8(_) => {
            let rgba = img.to_rgba8().into_raw();
            let display = display_from_rgba(width, height, 255, rgba.into_iter().map(u16::from));
            (DecodedImage::Display(display), PixelReport::default())
        }
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA16(_)
        | DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_) => {
            let rgba = img.to_rgba16().into_raw();
            (
                DecodedImage::Display(display_from_rgba(width, height, u16::MAX, rgba.into_iter())),
                PixelReport::default(),
            )
        }
        other => {
            return Err(PhotoError::Unsupported {
                path: path.to_path_buf(),
                message: format!("pixel type {:?} is neither 8/16-bit nor float", other.color()),
            });
        }
    })
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
/// Returns the mask and the counts of pixels masked for a non-finite or a negative value.
fn linear_validity(rgb: &mut [f32], mask_channel: Option<&[f32]>) -> (Vec<u8>, PixelReport) {
    let mut report = PixelReport::default();
    let mask = rgb
        .chunks_exact_mut(3)
        .enumerate()
        .map(|(i, c)| {
            let radiance = c.iter().all(|v| v.is_finite() && *v >= 0.0);
            if !radiance {
                if c.iter().all(|v| v.is_finite()) {
                    report.negative += 1;
                } else {
                    report.non_finite += 1;
                }
                c.iter_mut().filter(|v| !(v.is_finite() && **v >= 0.0)).for_each(|v| *v = 0.0);
            }
            let flagged = mask_channel.is_none_or(|m| m.get(i).is_some_and(|&m| m >= 0.5));
            u8::from(radiance && flagged)
        })
        .collect();
    (mask, report)
}

/// Decodes an OpenEXR file's first layer: channels R, G, B (or a single Y, replicated) plus an optional
/// `mask` channel (our cache files).
/// Pixels a single EXR tile may hold even when the image is smaller: OpenEXR's default tile is 64 × 64.
const EXR_TILE_PIXELS_MIN: usize = 64 * 64;

/// Most scan lines in one EXR block (DWAB compression; the others use 1 to 32).
const EXR_MAX_LINES_PER_BLOCK: usize = 256;

/// Bytes per pixel the block bound allows: four 32-bit channels (R, G, B and our cache's mask).
const EXR_BLOCK_BYTES_PER_PIXEL: usize = 16;

/// Refuses EXR headers whose parts are larger than the first part (the image read), or whose blocks hold more
/// bytes than the larger of that image, a full-width block of [`EXR_MAX_LINES_PER_BLOCK`] lines and a tile of
/// [`EXR_TILE_PIXELS_MIN`] pixels, at [`EXR_BLOCK_BYTES_PER_PIXEL`]. The `exr` crate
/// reserves a whole block's bytes, as the header declares it, before reading it; without this check a few
/// hundred bytes of header claim gigabytes.
fn check_exr_geometry(path: &Path, bytes: &[u8]) -> Result<(), PhotoError> {
    let unsupported = |message: String| PhotoError::Unsupported { path: path.to_path_buf(), message };
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: one_line(e) })?;
    let first = meta.headers.first().ok_or_else(|| unsupported("EXR has no layers".into()))?;
    let image_pixels = first.layer_size.area();
    let limit = image_pixels
        .max(first.layer_size.0.saturating_mul(EXR_MAX_LINES_PER_BLOCK))
        .max(EXR_TILE_PIXELS_MIN)
        .saturating_mul(EXR_BLOCK_BYTES_PER_PIXEL);
    for (i, h) in meta.headers.iter().enumerate() {
        if h.layer_size.area() > image_pixels {
            return Err(unsupported(format!(
                "EXR part {i} ({}x{}) is larger than the image of part 0 ({}x{})",
                h.layer_size.0, h.layer_size.1, first.layer_size.0, first.layer_size.1
            )));
        }
        let block = match h.blocks {
            exr::meta::BlockDescription::Tiles(t) => t.tile_size.0.checked_mul(t.tile_size.1),
            exr::meta::BlockDescription::ScanLines => h.layer_size.0.checked_mul(h.compression.scan_lines_per_block()),
        };
        let block_bytes = block.and_then(|b| b.checked_mul(h.channels.bytes_per_pixel));
        if block_bytes.is_none_or(|b| b > limit) {
            return Err(unsupported(format!(
                "EXR part {i} declares blocks of {} bytes, more than the {limit} an image of {}x{} needs",
                block_bytes.map_or("more than 2^64".to_string(), |b| b.to_string()),
                first.layer_size.0,
                first.layer_size.1
            )));
        }
    }
    Ok(())
}

fn read_exr_bytes(path: &Path, bytes: &[u8]) -> Result<(LinearImage, PixelReport), PhotoError> {
    use exr::prelude::*;
    check_exr_geometry(path, bytes)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| PhotoError::Decode { path: path.to_path_buf(), message: one_line(e) })?;
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
            let names: Vec<String> =
                layer.channel_data.list.iter().map(|c| format!("{:?}", c.name.to_string())).collect();
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
    if mask_channel.as_ref().is_some_and(|m| m.len() != n) {
        return Err(PhotoError::Decode { path: path.to_path_buf(), message: "channel sizes differ".into() });
    }
    let (mask, report) = linear_validity(&mut rgb, mask_channel.as_deref());
    Ok((LinearImage { width, height, rgb, mask }, report))
}
