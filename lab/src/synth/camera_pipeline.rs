//! A consumer camera pipeline for synthetic photos: what turns a rendered linear photo into the 8-bit JPEG a real
//! scan holds, so that the pipeline's photo handling (exposure, white balance, vignetting and response
//! recovery) can be tested against known truth.
//!
//! Photo k with linear radiance L at pixel p, taken by physical camera c = k mod n, becomes the code
//! `round(255 · f(g_k · w_k · v_c(r²(p)) · L))` per channel, then a JPEG:
//! - g_k, the exposure gain, is drawn log-uniformly in `exposure` (auto exposure);
//! - w_k, the white-balance factor, per channel uniformly in [1 − x, 1 + x];
//! - v_c(r²) = (1 + a_c·r²)^(−2), the falloff of camera c, with a_c solved from v_c(1) = corner_c; r² is the
//!   squared distance from the principal point divided by that of the farthest image corner (pixel edges);
//!   the shape is a smooth cos⁴-like form, deliberately not the even polynomial in r that the estimators fit;
//! - f, the display curve: Hable's filmic curve (Uncharted 2) h(bias·x)/h(W), then the display gamma 1/2.2,
//!   clipped at 1 (saturated lamps and windows become 255). It is S-shaped and is not sRGB.
//!
//! The draws are the lab's counter-based random numbers ([`optim::streams::uniform`]) keyed by the
//! description's seed, a stream of this module and the photo index, so a description gives the same JPEGs
//! every time. [`truth_json`] records everything needed to invert the pipeline (`ipt-camera-truth/1`).

use super::desc::{CameraPipelineSpec, ToneCurveName};

/// Stream of [`optim::streams::uniform`] for the exposure draw ("ex"); lab's own, apart from the bench's 1.
const EXPOSURE_STREAM: u64 = 0x6578;
/// Stream of [`optim::streams::uniform`] for the white-balance draws ("wb").
const WHITE_BALANCE_STREAM: u64 = 0x7762;

/// Hable's filmic parameters as published for Uncharted 2: shoulder strength, linear strength, linear angle,
/// toe strength, toe numerator, toe denominator, linear white point and exposure bias.
const HABLE_A: f64 = 0.15;
const HABLE_B: f64 = 0.50;
const HABLE_C: f64 = 0.10;
const HABLE_D: f64 = 0.20;
const HABLE_E: f64 = 0.02;
const HABLE_F: f64 = 0.30;
const HABLE_W: f64 = 11.2;
const HABLE_BIAS: f64 = 2.0;
/// Display gamma applied after the filmic curve (the usual 2.2 of a display, not the sRGB piecewise curve).
const DISPLAY_GAMMA: f64 = 2.2;
/// Samples of the vignetting written to the truth: r² = 0, 1/16, …, 1.
const VIGNETTING_SAMPLES: usize = 17;

/// Hable's rational curve h(x) = (x(Ax + CB) + DE) / (x(Ax + B) + DF) − E/F (h(0) = 0, increasing).
fn hable(x: f64) -> f64 {
    (x * (HABLE_A * x + HABLE_C * HABLE_B) + HABLE_D * HABLE_E) / (x * (HABLE_A * x + HABLE_B) + HABLE_D * HABLE_F)
        - HABLE_E / HABLE_F
}

/// The display curve: linear value (after gain and vignetting) → display value in [0, 1], clipped at 1.
#[must_use]
pub fn tone_curve(x: f64) -> f64 {
    let y = hable(HABLE_BIAS * x.max(0.0)) / hable(HABLE_W);
    y.clamp(0.0, 1.0).powf(1.0 / DISPLAY_GAMMA)
}

/// The inverse of [`tone_curve`] on [0, 1]: the smallest linear value that displays as `y` (1 → the clip point
/// W / bias; larger values display as 1 too).
#[must_use]
pub fn tone_curve_inverse(y: f64) -> f64 {
    // h(x) + E/F = s is the quadratic A(1 − s)x² + B(C − s)x + D(E − sF) = 0 with a > 0 and c ≤ 0: one root ≥ 0,
    // taken in the cancellation-free form (q = −(b + sign(b)·√disc)/2; roots q/a and c/q).
    let s = y.clamp(0.0, 1.0).powf(DISPLAY_GAMMA) * hable(HABLE_W) + HABLE_E / HABLE_F;
    let (a, b, c) = (HABLE_A * (1.0 - s), HABLE_B * (HABLE_C - s), HABLE_D * (HABLE_E - s * HABLE_F));
    let disc = (b * b - 4.0 * a * c).max(0.0);
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let x = if b >= 0.0 { if q == 0.0 { 0.0 } else { c / q } } else { q / a };
    (x / HABLE_BIAS).max(0.0)
}

/// [`tone_curve_inverse`] at code/255 for the 256 8-bit codes.
#[must_use]
pub fn inverse_table() -> Vec<f64> {
    (0..256).map(|code| tone_curve_inverse(f64::from(code) / 255.0)).collect()
}

/// The falloff parameter a of a camera whose vignetting at the image corner is `corner`: (1 + a)^(−2) = corner.
#[must_use]
pub fn vignetting_a(corner: f64) -> f64 {
    corner.powf(-0.5) - 1.0
}

/// Vignetting v(r²) = (1 + a·r²)^(−2) of a camera whose corner value is `corner` (v(0) = 1, v(1) = corner).
#[must_use]
pub fn vignetting(corner: f64, r2: f64) -> f64 {
    (1.0 + vignetting_a(corner) * r2).powi(-2)
}

/// r² of pixel (x, y) of `cam`: `ingest::photo::calibrate::normalised_r2`, the workspace's one definition
/// (squared distance from the principal point over that of the farthest outer image corner).
#[must_use]
pub fn normalised_r2(cam: &tracer::Camera, x: u32, y: u32) -> f64 {
    ingest::photo::calibrate::normalised_r2(
        f64::from(x),
        f64::from(y),
        f64::from(cam.cx),
        f64::from(cam.cy),
        cam.width,
        cam.height,
    )
}

/// What the pipeline drew for one photo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotoDraw {
    /// The physical camera (index into `vignetting_corner`).
    pub camera: usize,
    pub exposure: f64,
    pub white_balance: [f64; 3],
}

impl PhotoDraw {
    /// Per-channel gain = exposure × white balance.
    #[must_use]
    pub fn gain(&self) -> [f64; 3] {
        self.white_balance.map(|w| self.exposure * w)
    }
}

/// The draws of photo `k` of a description with `seed`.
#[must_use]
pub fn draw(spec: &CameraPipelineSpec, seed: u64, k: usize) -> PhotoDraw {
    let [lo, hi] = spec.exposure;
    let u = optim::streams::uniform(seed, EXPOSURE_STREAM, k as u64, 0);
    let white_balance = std::array::from_fn(|c| {
        let u = optim::streams::uniform(seed, WHITE_BALANCE_STREAM, k as u64, c as u64);
        1.0 - spec.white_balance + 2.0 * spec.white_balance * u
    });
    PhotoDraw { camera: k % spec.vignetting_corner.len(), exposure: lo * (hi / lo).powf(u), white_balance }
}

/// The 8-bit codes (interleaved RGB) of a linear photo `rgb` taken by `cam` with the draws `d`.
#[must_use]
pub fn to_codes(spec: &CameraPipelineSpec, d: &PhotoDraw, cam: &tracer::Camera, rgb: &[f32]) -> Vec<u8> {
    let curve = match spec.tone_curve {
        ToneCurveName::Filmic => tone_curve,
    };
    let corner = spec.vignetting_corner[d.camera];
    let gain = d.gain();
    let mut codes = Vec::with_capacity(rgb.len());
    for y in 0..cam.height {
        for x in 0..cam.width {
            let v = vignetting(corner, normalised_r2(cam, x, y));
            let i = 3 * (y as usize * cam.width as usize + x as usize);
            for c in 0..3 {
                let display = curve(gain[c] * v * f64::from(rgb[i + c]));
                codes.push(ingest::srgb::to_u8(display as f32));
            }
        }
    }
    codes
}

/// A JPEG file of 8-bit RGB `codes` at `quality` (the `image` crate's baseline encoder, 4:4:4).
pub fn jpeg_bytes(codes: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, image::ImageError> {
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality).encode(
        codes,
        width,
        height,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out)
}

/// Why a description's `[camera_pipeline]` is refused, in one line.
pub fn validate(spec: &CameraPipelineSpec) -> Result<(), String> {
    let [lo, hi] = spec.exposure;
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
        return Err(format!("camera_pipeline.exposure = [{lo}, {hi}] must satisfy 0 < lo ≤ hi (finite)"));
    }
    if !(0.0..1.0).contains(&spec.white_balance) {
        return Err(format!("camera_pipeline.white_balance = {} must lie in [0, 1)", spec.white_balance));
    }
    if spec.vignetting_corner.is_empty() {
        return Err("camera_pipeline.vignetting_corner needs one value per physical camera (at least one)".into());
    }
    if let Some(c) = spec.vignetting_corner.iter().find(|&&c| !(c > 0.0 && c < 1.0)) {
        return Err(format!("camera_pipeline.vignetting_corner value {c} must lie in (0, 1)"));
    }
    if !(1..=100).contains(&spec.jpeg_quality) {
        return Err(format!("camera_pipeline.jpeg_quality = {} must lie in 1–100", spec.jpeg_quality));
    }
    Ok(())
}

/// `ground_truth_camera.json` (schema `ipt-camera-truth/1`): every photo's draws by file stem, every physical
/// camera's vignetting, and the tone curve with its parameters and its inverse at the 256 codes.
#[must_use]
pub fn truth_json(spec: &CameraPipelineSpec, photos: &[(String, PhotoDraw)]) -> serde_json::Value {
    let photos: serde_json::Map<_, _> = photos
        .iter()
        .map(|(stem, d)| {
            let v = serde_json::json!({
                "camera": d.camera, "exposure": d.exposure, "white_balance": d.white_balance, "gain": d.gain(),
            });
            (stem.clone(), v)
        })
        .collect();
    let r2: Vec<f64> = (0..VIGNETTING_SAMPLES).map(|i| i as f64 / (VIGNETTING_SAMPLES - 1) as f64).collect();
    let cameras: Vec<_> = spec
        .vignetting_corner
        .iter()
        .map(|&corner| {
            serde_json::json!({
                "corner": corner, "a": vignetting_a(corner), "r2": r2,
                "v": r2.iter().map(|&r| vignetting(corner, r)).collect::<Vec<_>>(),
            })
        })
        .collect();
    let name = match spec.tone_curve {
        ToneCurveName::Filmic => "filmic",
    };
    serde_json::json!({
        "format": "ipt-camera-truth/1",
        "pipeline": "code = round(255 * f(gain[c] * v(r2) * L[c])), then JPEG",
        "jpeg_quality": spec.jpeg_quality,
        "photos": photos,
        "vignetting": {
            "shape": "v(r2) = (1 + a * r2)^-2",
            "r2": "squared distance from the principal point over that of the farthest image corner",
            "cameras": cameras,
        },
        "tone_curve": {
            "name": name,
            "formula": "f(x) = min(1, hable(bias * x) / hable(W))^(1 / gamma), \
                        hable(x) = (x(Ax + CB) + DE) / (x(Ax + B) + DF) - E/F",
            "parameters": {
                "A": HABLE_A, "B": HABLE_B, "C": HABLE_C, "D": HABLE_D, "E": HABLE_E, "F": HABLE_F,
                "W": HABLE_W, "bias": HABLE_BIAS, "gamma": DISPLAY_GAMMA,
            },
            "inverse": inverse_table(),
        },
    })
}
