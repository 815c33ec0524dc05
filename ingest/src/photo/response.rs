//! Camera response curves recovered from an exposure bracket with OpenCV's `CalibrateDebevec` (Debevec & Malik
//! 1997), and merging a bracket into one radiance image with `MergeDebevec`.
//!
//! The curve is OpenCV's: for 8-bit code z of channel c it gives the exposure `E·t` (radiance times exposure
//! time) in an arbitrary global unit, so `radiance = curve(c, z) / t`. Channels are in our RGB order.
//!
//! **Normalisation.** Debevec & Malik fix each channel's free additive constant of g = ln(curve) with
//! g(128) = 0. OpenCV puts that as one soft row into a float32 least-squares solve, and the result drifts: on
//! the Memorial bracket, Debian's OpenCV 4.6 (which this crate links) returns g(128) = +0.25 (blue) and −0.29
//! (green), cv2 4.11 returns other offsets, while the curve *shapes* agree to 1e-2. A per-channel offset is a
//! white-balance change of every merged radiance, so [`recover_response`] rescales each channel to
//! curve(128) = 1 exactly. With that, both OpenCV versions give identical merges of the Memorial bracket.

use std::path::{Path, PathBuf};

use opencv::core::{CV_32F, Mat, MatTraitConst, Vector};
use opencv::photo::{CalibrateCRFTrait, MergeDebevecTrait};
use serde::{Deserialize, Serialize};

use super::image_io::{DecodedImage, DisplayImage, read_image};
use super::mask::is_saturated;
use super::{AtPath, LinearImage, OpError, PhotoError, mat};

/// Number of entries of an 8-bit response curve.
pub const CURVE_LEN: usize = 256;

/// Debevec's solver samples this many pixel positions (OpenCV's default, 70): with N exposures it gives
/// 70·N equations for 256 unknowns per channel plus smoothness rows, well over-determined for N ≥ 4.
const DEBEVEC_SAMPLES: i32 = 70;
/// Smoothness weight of the curve's second derivative (OpenCV's default 10, as in Debevec & Malik's code).
const DEBEVEC_LAMBDA: f32 = 10.0;

/// A per-channel camera response: 256 positive values per channel, code value → exposure (E·t).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<[f32; 3]>", into = "Vec<[f32; 3]>")]
pub struct ResponseCurve {
    values: Vec<[f32; 3]>,
}

impl TryFrom<Vec<[f32; 3]>> for ResponseCurve {
    type Error = String;
    fn try_from(values: Vec<[f32; 3]>) -> Result<Self, String> {
        Self::from_values(values).map_err(|e| e.to_string())
    }
}

impl From<ResponseCurve> for Vec<[f32; 3]> {
    fn from(c: ResponseCurve) -> Self {
        c.values
    }
}

impl ResponseCurve {
    /// Builds a curve from 256 RGB entries, each finite and positive.
    pub fn from_values(values: Vec<[f32; 3]>) -> Result<Self, OpError> {
        if values.len() != CURVE_LEN {
            return Err(OpError::Invalid(format!("response curve needs {CURVE_LEN} entries, got {}", values.len())));
        }
        if let Some(i) = values.iter().position(|v| v.iter().any(|x| !x.is_finite() || *x <= 0.0)) {
            return Err(OpError::Invalid(format!(
                "response curve entry {i} is not positive and finite: {:?}",
                values[i]
            )));
        }
        Ok(Self { values })
    }

    /// The 256 RGB entries.
    #[must_use]
    pub fn values(&self) -> &[[f32; 3]] {
        &self.values
    }

    /// Exposure for channel `c` at a (possibly fractional) code `z` on the 0..=255 axis, linearly interpolated
    /// and clamped to the ends.
    #[must_use]
    pub fn eval(&self, c: usize, z: f32) -> f32 {
        let z = z.clamp(0.0, (CURVE_LEN - 1) as f32);
        let i = (z.floor() as usize).min(CURVE_LEN - 2);
        let t = z - i as f32;
        self.values[i][c] * (1.0 - t) + self.values[i + 1][c] * t
    }

    fn to_mat(&self) -> Result<Mat, OpError> {
        let flat: Vec<f32> = self.values.iter().flatten().copied().collect();
        mat::rgb_f32_to_mat(1, CURVE_LEN as u32, &flat)
    }
}

/// One exposure of a bracket: the 8-bit image file and its exposure time in seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct Exposure {
    pub path: PathBuf,
    pub time: f64,
}

struct LoadedBracket {
    images: Vec<DisplayImage>,
    mats: Vector<Mat>,
    times: Mat,
}

fn first_path(bracket: &[Exposure]) -> PathBuf {
    bracket.first().map_or_else(PathBuf::new, |e| e.path.clone())
}

fn load_bracket(bracket: &[Exposure]) -> Result<LoadedBracket, PhotoError> {
    let first = first_path(bracket);
    if bracket.len() < 2 {
        return Err(PhotoError::Process {
            path: first,
            source: OpError::Invalid(format!("an exposure bracket needs at least 2 images, got {}", bracket.len())),
        });
    }
    let mut images: Vec<DisplayImage> = Vec::with_capacity(bracket.len());
    let mut mats = Vector::<Mat>::new();
    for e in bracket {
        if !(e.time.is_finite() && e.time > 0.0) {
            return Err(PhotoError::Process {
                path: e.path.clone(),
                source: OpError::Invalid(format!("exposure time must be positive and finite, got {}", e.time)),
            });
        }
        let img = match read_image(&e.path)? {
            DecodedImage::Display(d) if d.max_code == 255 => d,
            _ => {
                return Err(PhotoError::Unsupported {
                    path: e.path.clone(),
                    message: "exposure-bracket images must be 8-bit PNG/JPEG (CalibrateDebevec works on 8-bit)".into(),
                });
            }
        };
        if let Some(f) = images.first()
            && (img.width, img.height) != (f.width, f.height)
        {
            return Err(PhotoError::WrongSize {
                path: e.path.clone(),
                expected: (f.width, f.height),
                found: (img.width, img.height),
            });
        }
        let bytes: Vec<u8> = img.codes.iter().map(|&c| c as u8).collect();
        mats.push(mat::rgb_u8_to_mat(img.width, img.height, &bytes).at(&e.path)?);
        images.push(img);
    }
    let times: Vec<f32> = bracket.iter().map(|e| e.time as f32).collect();
    let times =
        Mat::from_slice(&times).and_then(|m| m.try_clone()).map_err(OpError::cv("Mat from times")).at(&first)?;
    Ok(LoadedBracket { images, mats, times })
}

/// Recovers the camera response from an exposure bracket (≥ 2 aligned 8-bit images of a static scene) with
/// OpenCV's `CalibrateDebevec` (70 samples on a regular grid, λ = 10: OpenCV's defaults, deterministic).
pub fn recover_response(bracket: &[Exposure]) -> Result<ResponseCurve, PhotoError> {
    recover_response_sampled(bracket, DEBEVEC_SAMPLES)
}

/// [`recover_response`] with `samples` pixel positions on OpenCV's regular grid instead of 70. More samples
/// lower the curve's sampling noise (on the Memorial bracket a 70-point curve moves by about 0.05 in median
/// |ln| when only its samples change: docs/photo/self-calibration.md) at the cost of a larger SVD
/// (`16·samples + 257` rows for 16 photos).
pub fn recover_response_sampled(bracket: &[Exposure], samples: i32) -> Result<ResponseCurve, PhotoError> {
    let loaded = load_bracket(bracket)?;
    let first = first_path(bracket);
    if samples < 1 {
        return Err(PhotoError::Process {
            path: first,
            source: OpError::Invalid(format!("CalibrateDebevec needs at least one sample, got {samples}")),
        });
    }
    let mut calibrate = opencv::photo::create_calibrate_debevec(samples, DEBEVEC_LAMBDA, false)
        .map_err(OpError::cv("createCalibrateDebevec"))
        .at(&first)?;
    let mut response = Mat::default();
    calibrate
        .process(&loaded.mats, &mut response, &loaded.times)
        .map_err(OpError::cv("CalibrateDebevec::process"))
        .at(&first)?;
    if response.rows() * response.cols() != CURVE_LEN as i32 || response.channels() != 3 {
        return Err(PhotoError::Process {
            path: first,
            source: OpError::Invalid(format!(
                "CalibrateDebevec returned a {}x{}x{} curve, expected 256x1x3",
                response.rows(),
                response.cols(),
                response.channels()
            )),
        });
    }
    let flat = mat::mat_to_f32(&response, 3 * CURVE_LEN).at(&first)?;
    let values: Vec<[f32; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    // Enforce Debevec's g(128) = 0 exactly per channel (see the module docs).
    let mid = values[CURVE_LEN / 2];
    if mid.iter().any(|m| !m.is_finite() || *m <= 0.0) {
        return Err(PhotoError::Process {
            path: first,
            source: OpError::Invalid(format!("CalibrateDebevec returned a non-positive curve at code 128: {mid:?}")),
        });
    }
    let values = values.iter().map(|v| std::array::from_fn(|c| v[c] / mid[c])).collect();
    ResponseCurve::from_values(values).at(&first)
}

/// Merges an exposure bracket into one radiance image with OpenCV's `MergeDebevec` and the given response.
/// A pixel is valid when at least one exposure has it unsaturated (and not transparent); non-finite merge
/// results are invalid and set to 0.
pub fn merge_bracket(bracket: &[Exposure], curve: &ResponseCurve) -> Result<LinearImage, PhotoError> {
    let loaded = load_bracket(bracket)?;
    let first = first_path(bracket);
    let (w, h) = (loaded.images[0].width, loaded.images[0].height);
    let mut merge = opencv::photo::create_merge_debevec().map_err(OpError::cv("createMergeDebevec")).at(&first)?;
    let response = curve.to_mat().at(&first)?;
    let mut dst = Mat::default();
    merge
        .process_with_response(&loaded.mats, &mut dst, &loaded.times, &response)
        .map_err(OpError::cv("MergeDebevec::process"))
        .at(&first)?;
    if dst.depth() != CV_32F {
        return Err(PhotoError::Process {
            path: first,
            source: OpError::Invalid(format!("MergeDebevec returned depth {}, expected CV_32F", dst.depth())),
        });
    }
    let n = w as usize * h as usize;
    let mut rgb = mat::mat_to_f32(&dst, 3 * n).at(&first)?;
    let mut mask = vec![0u8; n];
    for (i, m) in mask.iter_mut().enumerate() {
        let well_exposed = loaded.images.iter().any(|img| {
            let c = &img.codes[3 * i..3 * i + 3];
            img.mask[i] != 0 && !is_saturated([c[0], c[1], c[2]], img.max_code)
        });
        let px = &mut rgb[3 * i..3 * i + 3];
        let finite = px.iter().all(|v| v.is_finite() && *v >= 0.0);
        if !finite {
            px.fill(0.0);
        }
        *m = u8::from(well_exposed && finite);
    }
    LinearImage::new(w, h, rgb, mask).at(&first)
}

/// Convenience for callers holding paths and times separately.
#[must_use]
pub fn bracket(paths: &[impl AsRef<Path>], times: &[f64]) -> Vec<Exposure> {
    paths.iter().zip(times).map(|(p, &t)| Exposure { path: p.as_ref().to_path_buf(), time: t }).collect()
}
