//! Photos: decoding, linearisation to radiance, validity masks, OpenCV undistortion, area downscaling and the
//! on-disk cache of prepared views.
//!
//! Pipeline of [`prepare_view`] (order matters: every resampling happens on **linear** values):
//! 1. decode ([`image_io`]): EXR and Radiance `.hdr` are already linear radiance; 8/16-bit PNG/JPEG are
//!    display-referred code values;
//! 2. linearise display-referred images ([`linearise`]) with the sRGB curve or a camera response curve
//!    ([`response`], OpenCV `CalibrateDebevec`), divide by the exposure time when known, and mask saturated
//!    pixels ([`mask`]);
//! 3. undistort ([`undistort`]) with OpenCV to a pinhole camera whose intrinsics replace the original ones,
//!    masking pixels outside the undistorted field of view;
//! 4. optionally area-downscale by an integer factor ([`downscale`]);
//! 5. callers cache the result ([`cache`]): `<name>.exr` (R, G, B, mask; written by [`exr`], the workspace's one
//!    EXR writer) + `<name>.json` (camera).
//!
//! Radiometric self-calibration ([`calibrate`]) recovers per-photo gains (exposure, white balance), per-camera
//! vignetting and, for LDR photos, the response from observations of the same points in several photos;
//! [`PhotoOptions::gain`] and [`PhotoOptions::vignetting`] apply its result in step 2.
//!
//! Pixel convention: as in [`crate::camera`], pixel centres at integer coordinates.

pub mod cache;
pub mod calibrate;
pub mod downscale;
pub mod exr;
pub mod image_io;
pub mod linearise;
pub mod mask;
mod mat;
pub mod response;
pub mod undistort;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::camera::Camera;

pub use cache::{read_cached, write_cached, write_exr};
pub use image_io::{DecodedImage, DisplayImage, PixelReport, decode_image, read_image, read_image_checked};
pub use response::{ResponseCurve, merge_bracket, recover_response, recover_response_sampled};

/// A problem with one photo file (or with the processing of the image read from it). Every variant names the
/// file it concerns.
#[derive(Debug, thiserror::Error)]
pub enum PhotoError {
    #[error("{path}: cannot read file: {source}", path = path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot decode image: {message}", path = path.display())]
    Decode { path: PathBuf, message: String },
    #[error("{path}: unsupported image: {message}", path = path.display())]
    Unsupported { path: PathBuf, message: String },
    #[error(
        "{path}: image is {}x{} pixels but its camera expects {}x{}",
        found.0, found.1, expected.0, expected.1, path = path.display()
    )]
    WrongSize { path: PathBuf, expected: (u32, u32), found: (u32, u32) },
    #[error("{path}: {source}", path = path.display())]
    Process {
        path: PathBuf,
        #[source]
        source: OpError,
    },
    #[error("{path}: cannot write: {source}", path = path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: crate::error::IngestError,
    },
    #[error("{path}: bad cache manifest: {message}", path = path.display())]
    Manifest { path: PathBuf, message: String },
}

/// A failure of an in-memory image operation (no file involved yet); [`PhotoError::Process`] attaches the file.
#[derive(Debug, thiserror::Error)]
pub enum OpError {
    #[error("OpenCV {operation} failed: {source}")]
    OpenCv {
        operation: &'static str,
        #[source]
        source: opencv::Error,
    },
    #[error("{0}")]
    Invalid(String),
}

impl OpError {
    /// Wraps an OpenCV error with the name of the operation that failed.
    pub(crate) fn cv(operation: &'static str) -> impl FnOnce(opencv::Error) -> Self {
        move |source| Self::OpenCv { operation, source }
    }
}

/// Attaches a file path to an [`OpError`].
pub(crate) trait AtPath<T> {
    fn at(self, path: &Path) -> Result<T, PhotoError>;
}

impl<T> AtPath<T> for Result<T, OpError> {
    fn at(self, path: &Path) -> Result<T, PhotoError> {
        self.map_err(|source| PhotoError::Process { path: path.to_path_buf(), source })
    }
}

/// A linear-radiance RGB image with a per-pixel validity mask. Row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearImage {
    pub width: u32,
    pub height: u32,
    /// Interleaved RGB, linear radiance (arbitrary but consistent units), `3 * width * height` values.
    pub rgb: Vec<f32>,
    /// 1 = valid, 0 = masked out of every loss (saturated, outside the field of view, ...). `width * height`.
    pub mask: Vec<u8>,
}

impl LinearImage {
    /// Builds an image, checking that the buffer lengths match the size.
    pub fn new(width: u32, height: u32, rgb: Vec<f32>, mask: Vec<u8>) -> Result<Self, OpError> {
        let n = width as usize * height as usize;
        if rgb.len() != 3 * n || mask.len() != n {
            return Err(OpError::Invalid(format!(
                "image {width}x{height} needs {} RGB values and {n} mask values, got {} and {}",
                3 * n,
                rgb.len(),
                mask.len()
            )));
        }
        Ok(Self { width, height, rgb, mask })
    }

    /// Number of pixels.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Number of valid pixels.
    #[must_use]
    pub fn valid_count(&self) -> usize {
        self.mask.iter().filter(|&&m| m != 0).count()
    }

    /// RGB of pixel (x, y). Panics when out of range (a caller bug, not bad input).
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Whether pixel (x, y) is valid. Panics when out of range.
    #[must_use]
    pub fn is_valid(&self, x: u32, y: u32) -> bool {
        self.mask[y as usize * self.width as usize + x as usize] != 0
    }
}

/// How to turn a photo into a linear, undistorted view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PhotoOptions {
    /// Camera response curve for 8/16-bit images; `None` = the sRGB curve. Ignored for EXR/HDR input.
    pub response: Option<ResponseCurve>,
    /// Exposure time in seconds; display-referred values are divided by it. Ignored for EXR/HDR input, which
    /// is taken to be radiance already.
    pub exposure_time: Option<f64>,
    /// Integer downscale factor (1 = full resolution), area-averaged in linear space.
    pub downscale: u32,
    /// Per-channel gain of this photo ([`calibrate::Calibration::gains`]); linear values are divided by it.
    pub gain: Option<[f32; 3]>,
    /// Vignetting of this photo's camera ([`calibrate::Calibration::vignetting`]); linear values are divided by
    /// `v(r²)` at each pixel of the original image (before undistortion), `r²` from [`calibrate::normalised_r2`].
    pub vignetting: Option<calibrate::Vignetting>,
}

impl Default for PhotoOptions {
    fn default() -> Self {
        Self { response: None, exposure_time: None, downscale: 1, gain: None, vignetting: None }
    }
}

/// Divides a linear image of the original (distorted) camera by the calibrated gain and vignetting.
fn apply_calibration(mut img: LinearImage, camera: &Camera, opts: &PhotoOptions) -> Result<LinearImage, OpError> {
    let gain = opts.gain.unwrap_or([1.0; 3]);
    if gain.iter().any(|g| !(g.is_finite() && *g > 0.0)) {
        return Err(OpError::Invalid(format!("gain must be positive and finite, got {gain:?}")));
    }
    if let Some(v) = &opts.vignetting
        && v.beta.iter().any(|b| !b.is_finite())
    {
        return Err(OpError::Invalid(format!("vignetting coefficients must be finite, got {:?}", v.beta)));
    }
    if opts.gain.is_none() && opts.vignetting.is_none() {
        return Ok(img);
    }
    let (w, h) = (img.width, img.height);
    let (cx, cy) = (camera.intrinsics.cx, camera.intrinsics.cy);
    for y in 0..h {
        for x in 0..w {
            let v =
                opts.vignetting.map_or(1.0, |v| v.factor(calibrate::normalised_r2(x.into(), y.into(), cx, cy, w, h)));
            let i = 3 * (y as usize * w as usize + x as usize);
            for c in 0..3 {
                img.rgb[i + c] = (f64::from(img.rgb[i + c]) / (f64::from(gain[c]) * v)) as f32;
            }
        }
    }
    Ok(img)
}

/// Reads, linearises, masks, undistorts and optionally downscales one photo taken by `camera`.
///
/// Returns the camera of the returned image: same pose, pinhole intrinsics (zero distortion) of the
/// undistorted and downscaled image. Errors name `image_path`: missing/undecodable file, a size different from
/// `camera.width × camera.height`, invalid options.
pub fn prepare_view(
    image_path: &Path,
    camera: &Camera,
    opts: &PhotoOptions,
) -> Result<(Camera, LinearImage), PhotoError> {
    prepare_view_counted(image_path, camera, opts).map(|(camera, image, _)| (camera, image))
}

/// [`prepare_view`], also returning the pixels masked on decoding because their value is not a radiance (NaN,
/// infinite or negative values in a linear file), for the caller to report.
pub fn prepare_view_counted(
    image_path: &Path,
    camera: &Camera,
    opts: &PhotoOptions,
) -> Result<(Camera, LinearImage, PixelReport), PhotoError> {
    if opts.downscale == 0 {
        return Err(PhotoError::Process {
            path: image_path.to_path_buf(),
            source: OpError::Invalid("downscale factor must be at least 1".into()),
        });
    }
    // The size is checked against the camera from the header, before any pixel is decoded.
    let (decoded, report) = read_image_checked(image_path, Some((camera.width, camera.height)))?;
    let linear = match decoded {
        DecodedImage::Linear(img) => img,
        DecodedImage::Display(img) => {
            linearise::linearise(&img, opts.response.as_ref(), opts.exposure_time).at(image_path)?
        }
    };
    // Gain and vignetting act on the sensor's pixels, so before undistortion moves them.
    let linear = apply_calibration(linear, camera, opts).at(image_path)?;
    let (camera, linear) = undistort::undistort(&linear, camera).at(image_path)?;
    let (camera, linear) = if opts.downscale > 1 {
        downscale::downscale(&linear, &camera, opts.downscale).at(image_path)?
    } else {
        (camera, linear)
    };
    Ok((camera, linear, report))
}
