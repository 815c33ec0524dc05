//! Whether a calibration earns its parameters: the calibrated model (gains, vignetting) against one exposure
//! for every photo, on observations it was not fitted to.
//!
//! Per-photo gains and vignetting fit any set of observations better than one exposure does, noise included:
//! on a house rendered at 16 paths per pixel (one exposure, log noise of ~0.9 per observation, a few dozen
//! shared points per photo) the gains came out between 0.11 and 108 (docs/photo/self-calibration.md, "When the
//! photos do not call for gains"). So the scene points are split in two halves, the model is fitted to each
//! half and scored on the other, and it is kept only when it predicts the held-out observations better than one
//! exposure does, significantly: a paired t-statistic over the held-out points of the reduction of their
//! absolute log residuals above [`T_KEEP`]. The residuals are taken about each point's median (over the
//! photos that see it), so one outlying photo of a point does not move its other residuals.
//!
//! Only for a known response: an estimated response needs the gains to be observable at all.

use super::model::usable;
use super::{CalibrateError, Calibration, CalibrationOptions, Observation, SplitMix64};

/// The t-statistic a calibration must reach over one exposure: one-sided p ≈ 0.1 %, as the object stage's
/// model selection (a spurious set of gains would bias every photo it touches).
pub const T_KEEP: f64 = 3.0;

/// The held-out comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldOutCheck {
    /// Held-out (point, channel) groups scored: seen by at least two photos that the other half's fit solved.
    pub groups: usize,
    /// Mean over those groups of the reduction of the summed absolute log residual, calibrated against one
    /// exposure (positive: the calibration predicts better), in natural-log units.
    pub gain: f64,
    /// Its paired t-statistic.
    pub t: f64,
}

impl HeldOutCheck {
    /// Whether the calibration predicts held-out observations significantly better than one exposure.
    #[must_use]
    pub fn supports(&self) -> bool {
        self.t > T_KEEP && self.gain > 0.0
    }
}

/// The half of the points that point `p` belongs to (seeded).
fn half(seed: u64, p: u32) -> bool {
    SplitMix64(seed ^ u64::from(p).wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64() >> 63 == 1
}

/// Fits the calibration to each half of the points and scores it on the other ([`calibrate_on`] is the fit);
/// returns `None` when neither half can be fitted or scored (too few links in a half).
pub(super) fn held_out(
    photo_groups: &[u32],
    observations: &[Observation],
    opts: &CalibrationOptions,
    calibrate_on: impl Fn(&[Observation]) -> Result<Calibration, CalibrateError>,
) -> Result<Option<HeldOutCheck>, CalibrateError> {
    let mut d = Vec::new();
    for fit_half in [false, true] {
        let (fit, test): (Vec<Observation>, Vec<Observation>) =
            observations.iter().partition(|o| half(opts.seed, o.point) == fit_half);
        let cal = match calibrate_on(&fit) {
            Ok(cal) => cal,
            Err(CalibrateError::TooFewLinked { .. } | CalibrateError::NoObservations) => continue,
            Err(e) => return Err(e),
        };
        d.extend(differences(photo_groups, &test, opts, &cal));
    }
    if d.len() < 2 {
        return Ok(None);
    }
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    let t = if se > 0.0 {
        mean / se
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    Ok(Some(HeldOutCheck { groups: d.len(), gain: mean, t }))
}

/// Per held-out (point, channel) group seen by ≥ 2 photos that `cal` solved: Σ|residual| with one exposure minus
/// Σ|residual| with `cal`'s gains and vignetting, residuals about the group's median.
fn differences(photo_groups: &[u32], test: &[Observation], opts: &CalibrationOptions, cal: &Calibration) -> Vec<f64> {
    // (point, channel) → [(ln value, calibrated offset)]
    let mut cells: std::collections::BTreeMap<(u32, usize), Vec<(f64, f64)>> = std::collections::BTreeMap::new();
    for o in test {
        let Some(gain) = cal.gains[o.photo as usize] else { continue };
        let v = cal.vignetting.get(photo_groups[o.photo as usize] as usize).map_or(1.0, |v| v.factor(f64::from(o.r2)));
        for c in 0..3 {
            if let Some((y, _)) = usable(o.value[c], opts.response) {
                cells.entry((o.point, c)).or_default().push((y, gain[c].ln() + v.ln()));
            }
        }
    }
    cells
        .values()
        .filter(|rows| rows.len() >= 2)
        .map(|rows| {
            let spread = |shift: &dyn Fn(&(f64, f64)) -> f64| {
                let mut r: Vec<f64> = rows.iter().map(shift).collect();
                let centre = median(&mut r);
                r.iter().map(|v| (v - centre).abs()).sum::<f64>()
            };
            spread(&|&(y, _)| y) - spread(&|&(y, off)| y - off)
        })
        .collect()
}

/// The median of `v` (reordered); the mean of the two middle values for an even count.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photo::calibrate::ResponseMode;

    /// Points seen by every photo, linear values `L_i · g_p` times log-normal noise `noise`.
    fn observations(gains: &[f64], noise: f64) -> Vec<Observation> {
        let mut rng = SplitMix64(7);
        let mut u = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let mut out = Vec::new();
        for point in 0..400u32 {
            let radiance = 0.05 + u();
            for (photo, g) in gains.iter().enumerate() {
                // A sum of uniforms: a near-normal deviate of standard deviation `noise`.
                let e = noise * ((0..12).map(|_| u()).sum::<f64>() - 6.0);
                let v = (radiance * g * e.exp()) as f32;
                out.push(Observation { point, photo: photo as u32, r2: 0.3, value: [v; 3] });
            }
        }
        out
    }

    fn check(gains: &[f64], noise: f64) -> HeldOutCheck {
        let opts = CalibrationOptions { response: ResponseMode::Linear, ..CalibrationOptions::default() };
        let groups = vec![0; gains.len()];
        let obs = observations(gains, noise);
        held_out(&groups, &obs, &opts, |o| super::super::model::run(&groups, o, &opts))
            .expect("the fits run")
            .expect("both halves score")
    }

    #[test]
    fn different_exposures_are_supported() {
        let c = check(&[1.0, 2.0, 0.5, 1.3], 0.05);
        assert!(c.supports(), "{c:?}");
    }

    #[test]
    fn one_exposure_under_noise_is_not_supported() {
        let c = check(&[1.0, 1.0, 1.0, 1.0], 0.5);
        assert!(!c.supports(), "{c:?}");
    }
}
