//! Radiometric self-calibration: per-photo gains (exposure × white balance), per-camera vignetting and,
//! optionally, the camera response, recovered from the photos themselves — several observations of the same
//! scene radiance in different photos.
//!
//! Model: photo `p` of camera group `k(p)` records a point of linear radiance `L_c` at normalised squared
//! radius `r²` ([`normalised_r2`]) as `z_c = f_c(g_{p,c} · v_k(r²) · L_c)`, so with `h_c = ln f_c⁻¹`
//! `h_c(z_c) = ln g_{p,c} + ln v_k(r²) + ln L_c` — linear in the log gains, the vignetting coefficients
//! (`ln v = β1 r² + β2 r⁴ + β3 r⁶`, so `v(0) = 1`) and the log radiances, and, when the response is estimated,
//! in the response's knot values too ([`response`]): one set of knots for the three channels
//! ([`ResponseChannels::Shared`], `f_c = f`) or one per channel. `solve` minimises it as robust weighted least squares
//! (IRLS: Huber then Tukey with a known response, Huber only when it is estimated) with every point's log
//! radiance eliminated; `model` builds the rows and decides which photos are linked well enough to be solved.
//!
//! Gauges: the geometric mean of the solved photos' gains is 1 per channel (radiance and gain trade exactly)
//! within each set of photos linked by shared points (with a known response every such set is solved; with an
//! estimated one only the largest);
//! with white balance, `ln g_{p,c} = ln exposure_p + ln wb_{p,c}` with `Σ_c ln wb_{p,c} = 0`. An estimated
//! response is normalised like [`crate::photo::recover_response`]'s: `curve(128) = 1` per channel (a mid
//! code that every photo set observes; code 255 is clipped and carries no data). The exponent of an estimated
//! response is not determined by the photos alone (exponential ambiguity): [`Calibration::gamma_source`] says
//! how it was fixed and [`Calibration::gamma_reliable`] whether that is trustworthy. When the exposures lie on
//! a lattice (⅓ EV, or the bracket's own step), they are snapped to it and the response is refitted with them
//! fixed (`model`). Measurements and the
//! choices they led to: `docs/photo/self-calibration.md`.
//!
//! [`calibrate_bracket`] (`bracket`) is the front end for an aligned exposure bracket.

mod bracket;
mod check;
mod model;
pub mod response;
mod result;
mod solve;

pub use bracket::calibrate_bracket;
pub use check::HeldOutCheck;
pub use response::GammaSource;

use super::response::ResponseCurve;

/// One observation: scene point `point` seen by photo `photo` at normalised squared radius `r2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub point: u32,
    pub photo: u32,
    /// Squared distance from the principal point over the squared corner distance, in [0, 1] ([`normalised_r2`]).
    pub r2: f32,
    /// Display code in [0, 1] for [`ResponseMode::Srgb`] and [`ResponseMode::Estimate`]; linear radiance for
    /// [`ResponseMode::Linear`].
    pub value: [f32; 3],
}

/// How observed values relate to radiance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ResponseMode {
    /// Values are linear radiance (EXR/HDR, or already linearised).
    Linear,
    /// Values are sRGB-encoded codes in [0, 1].
    Srgb,
    /// Values are codes in [0, 1] of an unknown monotone response, estimated too.
    Estimate,
}

/// Whether an estimated response is one curve for the three channels or one per channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResponseChannels {
    /// One curve: a digital camera white-balances its raw channels and then applies one tone curve to each,
    /// so the channels differ only by gains, which the per-photo gains (or the radiances) absorb. Every row
    /// constrains the same knots, so the curve spans the union of the channels' codes instead of each
    /// channel's narrow band, and the channels' exponents cannot drift apart.
    #[default]
    Shared,
    /// One curve per channel: colour film, whose dye layers have their own characteristic curves.
    PerChannel,
}

/// What to estimate.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CalibrationOptions {
    pub response: ResponseMode,
    /// One estimated curve for the channels or one each ([`ResponseMode::Estimate`] only).
    pub response_channels: ResponseChannels,
    /// A per-photo factor common to the channels.
    pub exposure: bool,
    /// A per-photo, per-channel factor with `Σ_c ln wb = 0`.
    pub white_balance: bool,
    /// Per-camera-group vignetting.
    pub vignetting: bool,
    /// Seed of any sampling ([`calibrate_bracket`]'s pixel positions).
    pub seed: u64,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            response: ResponseMode::Srgb,
            response_channels: ResponseChannels::Shared,
            exposure: true,
            white_balance: false,
            vignetting: false,
            seed: 0,
        }
    }
}

/// Radial vignetting: `ln v(r²) = β1 r² + β2 r⁴ + β3 r⁶`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Vignetting {
    pub beta: [f64; 3],
}

impl Vignetting {
    /// No vignetting (v = 1 everywhere).
    #[must_use]
    pub fn none() -> Self {
        Self { beta: [0.0; 3] }
    }

    /// `v(r²)`; `r2` is clamped to [0, 1], the domain over which the polynomial was fitted.
    #[must_use]
    pub fn factor(&self, r2: f64) -> f64 {
        let r2 = if r2.is_nan() { 0.0 } else { r2.clamp(0.0, 1.0) };
        (r2 * (self.beta[0] + r2 * (self.beta[1] + r2 * self.beta[2]))).exp()
    }
}

impl Default for Vignetting {
    fn default() -> Self {
        Self::none()
    }
}

/// The result. Indices are photo indices of the input.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Per photo: `g_{p,c}` (geometric mean 1 per channel over the solved photos of each linked set);
    /// `None` = unconstrained.
    pub gains: Vec<Option<[f64; 3]>>,
    /// Sets of photos linked by shared points, each calibrated with its own gain gauge (1 unless the response
    /// is known and some photos share no point with the others).
    pub linked_sets: usize,
    /// Photos left out and why.
    pub unconstrained: Vec<(u32, String)>,
    /// Per camera group (`max(photo_groups) + 1` entries); [`Vignetting::none`] where not estimated.
    pub vignetting: Vec<Vignetting>,
    /// Per camera group: whether its vignetting was estimated (requested, and points seen at different radii).
    pub vignetting_estimated: Vec<bool>,
    /// The estimated response ([`ResponseMode::Estimate`] only), `curve(128) = 1` per channel.
    pub response: Option<ResponseCurve>,
    /// How the response's exponent (and with it the scale of every log gain and of the vignetting) was fixed.
    pub gamma_source: GammaSource,
    /// False when the shape prior decided the exponent — alone, or by choosing the size in ⅓ EV of a bracket's
    /// step larger than ⅓ EV: gains, vignetting and curve may then all be off by a common power (see
    /// [`response`]).
    pub gamma_reliable: bool,
    /// Lattice misfit at the chosen exponent (0 = exact; NaN when no lattice was used): `1 − |mean phase|`
    /// for [`GammaSource::ExposureLattice`], the largest deviation in steps for [`GammaSource::BracketSteps`].
    pub lattice_misfit: f64,
    /// Root mean square of the residuals of `ln` radiance over rows kept by the robust weights (IRLS weight
    /// > 0), in natural-log units.
    pub residual_rms: f64,
    /// Observations with at least one channel kept by the robust weights.
    pub used_observations: usize,
    /// (Observation, channel) pairs excluded as black, saturated or non-finite.
    pub clipped_channels: usize,
    /// (Observation, channel) pairs that entered the solve but ended with robust weight 0 (outliers).
    pub rejected_channels: usize,
    /// The calibration against one exposure on held-out observations ([`HeldOutCheck`]); `None` when it was
    /// not run (an estimated response, or nothing but the response to calibrate) or the halves could not be
    /// fitted.
    pub held_out: Option<HeldOutCheck>,
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, well-mixed seeded generator (the bracket's pixel positions,
/// the held-out check's halves of the points).
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// Why calibration could not run.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    #[error("no observations")]
    NoObservations,
    #[error("observation {index}: photo {photo} is out of range ({photos} photos)")]
    PhotoOutOfRange { index: usize, photo: u32, photos: usize },
    #[error("observation {index}: r2 = {r2} is not in [0, 1]")]
    RadiusOutOfRange { index: usize, r2: f32 },
    #[error("fewer than 2 photos are linked by shared points ({linked} of {photos})")]
    TooFewLinked { linked: usize, photos: usize },
    #[error("estimating the response needs exposure or white-balance gains (with all gains 1 it is unobservable)")]
    ResponseWithoutGains,
    #[error("the least-squares system is singular")]
    Singular,
    #[error("bracket: {0}")]
    Bracket(String),
    #[error(
        "the calibrated gains and vignetting predict the observations they were not fitted to no better than one \
         exposure (absolute log residual {:+.4} per point and channel, t = {:.1} over {} of them; needs t > {})",
        -.0.gain, .0.t, .0.groups, check::T_KEEP
    )]
    NotSupported(HeldOutCheck),
}

/// A linear value `v` of a photo whose response is known only up to a power, raised to `exponent`: the
/// correction the exponential ambiguity leaves open. Non-positive values (black, or masked) stay as they are.
#[must_use]
pub fn raise_linear(v: f32, exponent: f32) -> f32 {
    if v > 0.0 { v.powf(exponent) } else { v }
}

/// Normalised squared radius of pixel `(x, y)` (pixel centres at integer coordinates) of a `width × height`
/// image with principal point `(cx, cy)`: squared distance over that of the farthest image corner, so 0 at the
/// principal point and 1 at the farthest corner.
#[must_use]
pub fn normalised_r2(x: f64, y: f64, cx: f64, cy: f64, width: u32, height: u32) -> f64 {
    // The image's outer corners are half a pixel beyond the first and last pixel centres.
    let (x0, x1) = (-0.5 - cx, f64::from(width) - 0.5 - cx);
    let (y0, y1) = (-0.5 - cy, f64::from(height) - 0.5 - cy);
    let corner = x0.abs().max(x1.abs()).powi(2) + y0.abs().max(y1.abs()).powi(2);
    if corner > 0.0 { (((x - cx).powi(2) + (y - cy).powi(2)) / corner).clamp(0.0, 1.0) } else { 0.0 }
}

/// Calibrates gains, vignetting and (with [`ResponseMode::Estimate`]) the response from `observations`.
/// `photo_groups[p]` is the camera group of photo `p`.
pub fn calibrate(
    photo_groups: &[u32],
    observations: &[Observation],
    opts: &CalibrationOptions,
) -> Result<Calibration, CalibrateError> {
    if observations.is_empty() {
        return Err(CalibrateError::NoObservations);
    }
    for (index, o) in observations.iter().enumerate() {
        if o.photo as usize >= photo_groups.len() {
            return Err(CalibrateError::PhotoOutOfRange { index, photo: o.photo, photos: photo_groups.len() });
        }
        if !(0.0..=1.0).contains(&o.r2) {
            return Err(CalibrateError::RadiusOutOfRange { index, r2: o.r2 });
        }
    }
    if opts.response == ResponseMode::Estimate && !opts.exposure && !opts.white_balance {
        return Err(CalibrateError::ResponseWithoutGains);
    }
    let mut cal = model::run(photo_groups, observations, opts)?;
    // With a known response, gains and vignetting are kept only where the photos call for them.
    if opts.response != ResponseMode::Estimate && (opts.exposure || opts.white_balance || opts.vignetting) {
        cal.held_out = check::held_out(photo_groups, observations, opts, |o| model::run(photo_groups, o, opts))?;
        if let Some(check) = cal.held_out.filter(|c| !c.supports()) {
            return Err(CalibrateError::NotSupported(check));
        }
    }
    Ok(cal)
}
