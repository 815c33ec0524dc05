//! The `preprocess` stage's artefacts (`crate::stages::preprocess` writes them) and their reader, [`Prepared`].
//!
//! In `output.path/preprocess/`: `<view>.exr` + `<view>.json` per view (ingest's photo cache: R, G, B, mask
//! and the prepared pinhole camera) and `views.json` = `{"format": "ipt-views/1", "views": [names in order]}`,
//! the order every later stage uses for view indices; when the photos were calibrated, `calibration.json`
//! ([`CalibrationFile`]).

use std::path::Path;

use ingest::photo::LinearImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ingest::photo::calibrate::{Calibration, CalibrationOptions, ResponseChannels, ResponseMode};

use crate::stage_contract::StageError;

/// The photometric calibration's file name.
pub const CALIBRATION_FILE: &str = "calibration.json";
/// Format tag of `calibration.json`.
pub const CALIBRATION_FORMAT: &str = "ipt-calibration/2";

/// `calibration.json`: what the photos' overlap said about each photo and camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    pub format: String,
    /// `"linear"` (linear photos), `"srgb"` (display photos, sRGB curve) or `"estimate"` (response estimated).
    pub response_mode: String,
    /// With an estimated response: one curve for the three channels (`"shared"`) or one each
    /// (`"per_channel"`); `None` otherwise.
    pub response_channels: Option<ResponseChannels>,
    pub exposure: bool,
    pub white_balance: bool,
    pub vignetting: bool,
    /// Surface points sampled, observations of them in the photos, and observations the robust solve kept.
    pub points: usize,
    pub observations: usize,
    pub used_observations: usize,
    /// RMS of the kept observations' log residuals.
    pub residual_rms: f64,
    pub views: Vec<CalibratedView>,
    /// Sets of views linked by shared points; each set's gains have a geometric mean of 1 on their own, since
    /// nothing relates the exposures of views that see no common point.
    pub linked_sets: usize,
    pub cameras: Vec<CameraVignetting>,
    /// The estimated response, 256 RGB entries (code → relative exposure), each channel scaled to 1 at code
    /// 128; `None` unless estimated.
    pub response: Option<Vec<[f32; 3]>>,
    /// How the response's exponent was fixed (`Given`, `ExposureLattice`, `ShapePrior`), and whether the photos
    /// alone fixed it reliably; when not, the object stage measures it against its renders.
    pub exponent_source: String,
    pub exponent_reliable: bool,
}

/// One view's estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibratedView {
    pub name: String,
    pub camera: u32,
    /// RGB gain (exposure × white balance; geometric mean 1 over the kept views); `None` = left out.
    pub gain: Option<[f64; 3]>,
    pub left_out: Option<String>,
}

/// One physical camera's vignetting: its coefficients and v(r) at r = 0, 0.1, …, 1 (r the distance from the
/// principal point over the corner's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraVignetting {
    pub camera: u32,
    pub beta: [f64; 3],
    pub corner: f64,
    pub profile: Vec<f64>,
}

impl CalibrationFile {
    /// The record of a calibration of the views `names` (camera group of each in `groups`).
    #[must_use]
    pub fn new(
        names: &[String],
        groups: &[u32],
        opts: &CalibrationOptions,
        points: usize,
        observations: usize,
        cal: &Calibration,
    ) -> Self {
        let why = |p: usize| cal.unconstrained.iter().find(|(i, _)| *i as usize == p).map(|(_, w)| w.clone());
        let views = names
            .iter()
            .enumerate()
            .map(|(p, name)| CalibratedView {
                name: name.clone(),
                camera: groups[p],
                gain: cal.gains.get(p).copied().flatten(),
                left_out: why(p),
            })
            .collect();
        let cameras = cal
            .vignetting
            .iter()
            .enumerate()
            .map(|(g, v)| CameraVignetting {
                camera: g as u32,
                beta: v.beta,
                corner: v.factor(1.0),
                profile: (0..=10).map(|k| v.factor((f64::from(k) / 10.0).powi(2))).collect(),
            })
            .collect();
        let response = cal.response.as_ref().map(|r| r.values().to_vec());
        Self {
            format: CALIBRATION_FORMAT.into(),
            response_mode: match opts.response {
                ResponseMode::Linear => "linear",
                ResponseMode::Srgb => "srgb",
                ResponseMode::Estimate => "estimate",
            }
            .into(),
            response_channels: (opts.response == ResponseMode::Estimate).then_some(opts.response_channels),
            exposure: opts.exposure,
            white_balance: opts.white_balance,
            vignetting: opts.vignetting,
            points,
            observations,
            used_observations: cal.used_observations,
            residual_rms: cal.residual_rms,
            views,
            linked_sets: cal.linked_sets,
            cameras,
            response,
            exponent_source: format!("{:?}", cal.gamma_source),
            exponent_reliable: cal.gamma_reliable,
        }
    }

    /// The estimates in the units of photos raised to `exponent` (what the object stage applies when the
    /// photos alone left the tone curve's exponent open): gains, vignetting and response all raised to it.
    #[must_use]
    pub fn raised(&self, exponent: f64) -> Self {
        let mut out = self.clone();
        for v in &mut out.views {
            v.gain = v.gain.map(|g| g.map(|x| x.powf(exponent)));
        }
        for c in &mut out.cameras {
            c.beta = c.beta.map(|b| b * exponent);
            c.corner = c.corner.powf(exponent);
            c.profile = c.profile.iter().map(|v| v.powf(exponent)).collect();
        }
        let e = exponent as f32;
        out.response = out.response.map(|r| r.into_iter().map(|v| v.map(|x| x.powf(e))).collect());
        out
    }

    /// One line for the run log: what was estimated and its range.
    #[must_use]
    pub fn summary(&self) -> String {
        let gains: Vec<f64> = self.views.iter().filter_map(|v| v.gain).flat_map(|g| g.into_iter()).collect();
        let (lo, hi) = gains.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &g| (lo.min(g), hi.max(g)));
        let kept = self.views.iter().filter(|v| v.gain.is_some()).count();
        let corners: Vec<String> = self.cameras.iter().map(|c| format!("{:.3}", c.corner)).collect();
        format!(
            "calibrated {kept} of {} views from {} of {} observations of {} points (log residual rms {:.4}): gains \
             {lo:.3}–{hi:.3}, vignetting at the corner {}, response {}",
            self.views.len(),
            self.used_observations,
            self.observations,
            self.points,
            self.residual_rms,
            if corners.is_empty() { "none".to_owned() } else { corners.join(" / ") },
            self.response_mode
        ) + &if self.linked_sets > 1 {
            format!(
                " (in {} sets of views that share no point; each set's gains have a geometric mean of 1)",
                self.linked_sets
            )
        } else {
            String::new()
        } + if self.exponent_reliable {
            ""
        } else {
            " (its exponent is not fixed by the photos alone: the object stage measures it against its renders)"
        }
    }

    /// Reads `run_dir/preprocess/calibration.json`; `None` when the run did not calibrate.
    pub fn read(run_dir: &Path) -> Result<Option<Self>, StageError> {
        let path = run_dir.join("preprocess").join(CALIBRATION_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|source| StageError::Io { path: path.clone(), source })?;
        let file: Self = serde_json::from_str(&text)
            .map_err(|e| StageError::Artefact { path: path.clone(), message: e.to_string() })?;
        if file.format != CALIBRATION_FORMAT {
            return Err(StageError::OldFormat {
                path,
                found: file.format,
                expected: CALIBRATION_FORMAT,
                stage: "preprocess",
            });
        }
        Ok(Some(file))
    }
}

/// The view list's file name.
pub const VIEWS_FILE: &str = "views.json";
/// Format tag of `views.json`.
pub const VIEWS_FORMAT: &str = "ipt-views/1";

/// `views.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewList {
    pub format: String,
    pub views: Vec<String>,
}

/// The prepared views as later stages read them.
#[derive(Debug, Clone, PartialEq)]
pub struct Prepared {
    pub names: Vec<String>,
    pub cameras: Vec<ingest::camera::Camera>,
    pub images: Vec<LinearImage>,
}

impl Prepared {
    /// Reads `run_dir/preprocess/`.
    pub fn read(run_dir: &Path) -> Result<Self, StageError> {
        let dir = run_dir.join("preprocess");
        let list_path = dir.join(VIEWS_FILE);
        let text =
            std::fs::read_to_string(&list_path).map_err(|source| StageError::Io { path: list_path.clone(), source })?;
        let list: ViewList = serde_json::from_str(&text)
            .map_err(|e| StageError::Artefact { path: list_path.clone(), message: e.to_string() })?;
        if list.format != VIEWS_FORMAT {
            return Err(StageError::OldFormat {
                path: list_path,
                found: list.format,
                expected: VIEWS_FORMAT,
                stage: "preprocess",
            });
        }
        let loaded: Vec<(ingest::camera::Camera, LinearImage)> = list
            .views
            .par_iter()
            .map(|name| ingest::photo::read_cached(&dir, name).map_err(StageError::from))
            .collect::<Result<_, _>>()?;
        let (cameras, images) = loaded.into_iter().unzip();
        Ok(Self { names: list.views, cameras, images })
    }

    /// Raises every photo's linear values to `exponent[c]` per channel ([`raise_to_exponent`]).
    pub fn apply_exponent(&mut self, exponent: [f64; 3]) {
        raise_to_exponent(&mut self.images, exponent);
    }

    /// The prepared cameras as the tracer's.
    #[must_use]
    pub fn tracer_cameras(&self) -> Vec<tracer::Camera> {
        self.cameras.iter().map(super::ingest::tracer_camera).collect()
    }
}

/// Raises every image's linear values to `exponent[c]` per channel (non-positive values untouched): the
/// correction of a tone curve known only up to a power.
pub fn raise_to_exponent(images: &mut [LinearImage], exponent: [f64; 3]) {
    if exponent == [1.0; 3] {
        return;
    }
    let e = exponent.map(|x| x as f32);
    images.par_iter_mut().for_each(|img| {
        for px in img.rgb.chunks_exact_mut(3) {
            for (v, e) in px.iter_mut().zip(e) {
                *v = ingest::photo::calibrate::raise_linear(*v, e);
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_older_format_names_the_file_and_the_stage_to_rerun() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("preprocess")).unwrap();
        std::fs::write(dir.path().join("preprocess").join(VIEWS_FILE), r#"{"format": "ipt-views/0", "views": []}"#)
            .unwrap();
        let Err(err) = Prepared::read(dir.path()) else { panic!("an older format is refused") };
        let err = err.to_string();
        assert!(err.contains("views.json") && err.contains("`ipt-views/0`"), "{err}");
        assert!(err.contains("--from preprocess"), "{err}");
    }
}
