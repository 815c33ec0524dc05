//! The `preprocess` stage: turns each selected view's photo into linear radiance with a validity mask
//! (undistorted, optionally downscaled; `ingest::photo::prepare_view`) and caches it. The downscale factor is
//! `images.downscale`, raised until all prepared photos together fit the pixel budget `images.max_pixels`
//! ([`crate::config::ImagesConfig::effective_downscale`]); the stage notes when it raises it.
//!
//! When `[images]` asks for any photometric estimate (per-photo exposure or white balance, vignetting, an
//! estimated response), the photos' overlap calibrates them first ([`calibration`]) and each photo is then
//! linearised with the estimated response and divided by its gains and its camera's vignetting; photos whose
//! gain the overlap cannot constrain are reported and left out. When the photos cannot be compared at all
//! (fewer than two share enough surface: a single photo, or photos of disjoint parts of a scan), or the
//! estimates predict held-out observations no better than one exposure (`CalibrateError::NotSupported`), and
//! the response is not to be estimated, the stage says so and prepares every photo with one exposure and white
//! balance, as `"fixed"` does; an estimated response has no such fallback and is an error.
//!
//! Artefacts in `output.path/preprocess/` ([`crate::artefacts::preprocess`] reads them back): `<view>.exr` +
//! `<view>.json` per view (ingest's photo cache: R, G, B, mask and the prepared pinhole camera), `views.json` =
//! `{"format": "ipt-views/1", "views": [names in order]}`, the order every later stage uses for view indices,
//! and, when calibrated, `calibration.json` (`ipt-calibration/2`: per-view gains, vignetting per camera,
//! the response beside sRGB).

pub mod calibration;

use std::path::{Path, PathBuf};

use ingest::View;
use ingest::photo::PhotoOptions;
use ingest::photo::calibrate::{CalibrateError, ResponseMode};
use rayon::prelude::*;

use crate::artefacts::ingest::Ingested;
use crate::artefacts::preprocess::{CALIBRATION_FILE, CalibrationFile, VIEWS_FILE, VIEWS_FORMAT, ViewList};
use crate::atomic_file::write_json_atomic;
use crate::config::ImagesConfig;
use crate::stage_contract::{StageContext, StageError, remove_if_present};

/// The views `images.cameras` and `images.every` select, in scan order. Errors name a listed camera the scan
/// does not have.
pub fn select_views<'a>(views: &'a [View], cfg: &ImagesConfig) -> Result<Vec<&'a View>, String> {
    for want in &cfg.cameras {
        if !views.iter().any(|v| &v.name == want) {
            return Err(format!("images.cameras: the scan has no view named `{want}`"));
        }
    }
    let chosen: Vec<&View> = views.iter().filter(|v| cfg.cameras.is_empty() || cfg.cameras.contains(&v.name)).collect();
    Ok(chosen.into_iter().step_by(cfg.every.max(1) as usize).collect())
}

/// Runs the stage.
pub fn run(ctx: &StageContext<'_>) -> Result<Vec<PathBuf>, StageError> {
    let scene = Ingested::read(&ctx.plan.output)?;
    let chosen = select_views(&scene.views, &ctx.plan.images)
        .map_err(|message| StageError::Artefact { path: ctx.plan.config_path.clone(), message })?;
    if chosen.is_empty() {
        return Err(StageError::Artefact { path: ctx.plan.config_path.clone(), message: "no view selected".into() });
    }
    let sizes: Vec<(u32, u32)> = chosen.iter().map(|v| (v.camera.width, v.camera.height)).collect();
    let downscale = ctx.plan.images.effective_downscale(&sizes);
    if downscale != ctx.plan.images.downscale {
        let full: u64 = sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum();
        ctx.note(&format!(
            "downscale {downscale} instead of {}: the {} views' {full} pixels exceed images.max_pixels = {}",
            ctx.plan.images.downscale,
            sizes.len(),
            ctx.plan.images.max_pixels
        ));
    }
    let base = PhotoOptions { downscale, ..PhotoOptions::default() };
    let mut outputs_extra = Vec::new();
    let calibrated = if ctx.plan.images.calibrates() { calibrate(ctx, &scene, &chosen, &base)? } else { None };
    let (chosen, per_view): (Vec<&View>, Vec<PhotoOptions>) = if let Some((kept, file)) = calibrated {
        write_json_atomic(&ctx.dir.join(CALIBRATION_FILE), &file)?;
        outputs_extra.push(PathBuf::from("preprocess").join(CALIBRATION_FILE));
        kept.into_iter().unzip()
    } else {
        // A calibration of an earlier run with other settings must not reach the later stages.
        remove_if_present(ctx.dir.join(CALIBRATION_FILE))?;
        let n = chosen.len();
        (chosen, vec![base; n])
    };
    if chosen.is_empty() {
        return Err(StageError::Artefact {
            path: ctx.plan.config_path.clone(),
            message: "no view is left after the photometric calibration".into(),
        });
    }
    let bar = ctx.progress("preparing photos", chosen.len() as u64);
    let written: Vec<(Vec<PathBuf>, usize)> = chosen
        .par_iter()
        .zip(&per_view)
        .map(|(v, opts)| {
            if bar.stop_requested() {
                return Err(StageError::Interrupted);
            }
            let (camera, img, report) = ingest::photo::prepare_view_counted(&v.image_path, &v.camera, opts)?;
            ingest::photo::write_cached(&ctx.dir, &v.name, &camera, &img)?;
            bar.inc(1);
            let (exr, json) = ingest::photo::cache::cached_paths(Path::new("preprocess"), &v.name);
            Ok((vec![exr, json], report.masked()))
        })
        .collect::<Result<_, StageError>>()?;
    drop(bar);
    let list = ViewList { format: VIEWS_FORMAT.into(), views: chosen.iter().map(|v| v.name.clone()).collect() };
    write_json_atomic(&ctx.dir.join(VIEWS_FILE), &list)?;
    ctx.note(&format!("{} views prepared (downscale {downscale})", chosen.len()));
    let masked: usize = written.iter().map(|(_, m)| m).sum();
    if masked > 0 {
        ctx.note(&format!("{masked} photo pixels with a NaN, infinite or negative value masked"));
    }
    let mut outputs: Vec<PathBuf> = written.into_iter().flat_map(|(files, _)| files).collect();
    outputs.push(PathBuf::from("preprocess").join(VIEWS_FILE));
    outputs.extend(outputs_extra);
    Ok(outputs)
}

/// The photometric calibration: observes the chosen views' overlap, solves, reports, and returns the views
/// kept with the options that prepare each, and the `calibration.json` record; `None` when the photos cannot
/// be compared and nothing requires the comparison (see the module docs).
#[allow(clippy::type_complexity)]
fn calibrate<'a>(
    ctx: &StageContext<'_>,
    scene: &Ingested,
    chosen: &[&'a View],
    base: &PhotoOptions,
) -> Result<Option<(Vec<(&'a View, PhotoOptions)>, CalibrationFile)>, StageError> {
    let cfg = &ctx.plan.images;
    let seed = ctx.plan.object.seed;
    let overlap = {
        let bar = ctx.progress("comparing overlapping photos", chosen.len() as u64);
        calibration::observe_overlap(scene, chosen, cfg, seed, bar.as_ref())?
    };
    let groups = calibration::camera_groups(chosen);
    let opts = calibration::options(cfg, overlap.mode, seed);
    let cal = match calibration::solve(&overlap, &groups, &opts) {
        Ok(cal) => cal,
        Err(
            e
            @ (CalibrateError::TooFewLinked { .. } | CalibrateError::NoObservations | CalibrateError::NotSupported(_)),
        ) if opts.response != ResponseMode::Estimate => {
            ctx.note(&format!(
                "photometric calibration skipped: {e}; every photo keeps one exposure and white balance and no \
                 vignetting"
            ));
            return Ok(None);
        }
        Err(e) => return Err(StageError::Artefact { path: ctx.plan.config_path.clone(), message: e.to_string() }),
    };
    let names: Vec<String> = chosen.iter().map(|v| v.name.clone()).collect();
    let file = CalibrationFile::new(&names, &groups, &opts, overlap.points, overlap.observations.len(), &cal);
    ctx.note(&file.summary());
    for (p, why) in &cal.unconstrained {
        ctx.note(&format!("view {} left out: {why}", names[*p as usize]));
    }
    let kept = chosen
        .iter()
        .zip(&groups)
        .enumerate()
        .filter_map(|(p, (v, &g))| {
            let gain = cal.gains.get(p).copied().flatten()?;
            let opts = PhotoOptions {
                response: cal.response.clone(),
                gain: Some(gain.map(|x| x as f32)),
                vignetting: cal.vignetting.get(g as usize).cloned(),
                ..base.clone()
            };
            Some((*v, opts))
        })
        .collect();
    Ok(Some((kept, file)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(name: &str) -> View {
        View {
            name: name.into(),
            image_path: PathBuf::from(format!("{name}.exr")),
            camera: ingest::camera::Camera {
                width: 1,
                height: 1,
                intrinsics: ingest::camera::Intrinsics { fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 },
                distortion: ingest::camera::Distortion::default(),
                cam_to_world: glam::DMat4::IDENTITY,
            },
        }
    }

    #[test]
    fn selection_by_name_then_stride_keeps_scan_order() {
        let views: Vec<View> = ["a", "b", "c", "d", "e"].map(view).into();
        let names = |cfg: &ImagesConfig| -> Vec<String> {
            select_views(&views, cfg).unwrap().iter().map(|v| v.name.clone()).collect()
        };
        assert_eq!(names(&ImagesConfig::default()), ["a", "b", "c", "d", "e"]);
        assert_eq!(names(&ImagesConfig { every: 2, ..ImagesConfig::default() }), ["a", "c", "e"]);
        let cfg =
            ImagesConfig { cameras: vec!["e".into(), "b".into(), "d".into()], every: 2, ..ImagesConfig::default() };
        assert_eq!(names(&cfg), ["b", "e"]);
        let bad = ImagesConfig { cameras: vec!["zz".into()], ..ImagesConfig::default() };
        assert!(select_views(&views, &bad).unwrap_err().contains("`zz`"));
    }
}
