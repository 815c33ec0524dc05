//! Photometric calibration of the photos from their overlap, before they are prepared: which exposure and
//! white balance each photo was taken with, how each physical camera's lens darkens its corners, and (for
//! display-referred photos, when asked) the camera's tone curve.
//!
//! The scan's geometry says which photos see the same surface point: points are sampled area-uniformly on the
//! mesh (a fixed budget, `images.calibration_points`, so the cost does not grow with the photos' resolution),
//! each is projected into every photo through that photo's own (distorted) camera, and kept where nothing
//! occludes it and the surface faces the camera. The photo's value at the nearest pixel, with the pixel's
//! normalised squared radius, is one observation; `ingest::photo::calibrate` solves for the response, gains
//! and vignetting that make the observations of each point agree (robustly: highlights on glossy surfaces,
//! texture and silhouettes break the agreement for some observations). Photos are decoded one per worker
//! thread at a time and only the observations are kept, so memory is bounded by the point budget.

use glam::{DVec3, Vec3};
use ingest::View;
use ingest::photo::calibrate::{
    CalibrateError, Calibration, CalibrationOptions, Observation, ResponseMode, normalised_r2,
};
use ingest::photo::{DecodedImage, read_image};
use optim::streams::{draw, uniform};
use rayon::prelude::*;

use crate::artefacts::ingest::Ingested;
use crate::config::{ImagesConfig, PerPhoto, ResponseChoice, VignettingChoice};
use crate::stage_contract::StageError;

/// A point is observed only where the surface faces the camera at least this much (cos 80°): at grazing
/// angles a pixel's footprint stretches across the surface, so neighbouring radiances mix into it.
const MIN_COS_VIEW: f64 = 0.17;
/// The occlusion test stops this fraction of the distance short of the point, so that the point's own
/// triangle (hit at the full distance, up to float rounding of ~1e-6 relative) never counts as an occluder.
const OCCLUSION_SHORTFALL: f64 = 1e-3;

/// A surface sample: position and unit geometric normal.
#[derive(Debug, Clone, Copy)]
struct SurfaceSample {
    p: Vec3,
    n: Vec3,
}

/// The observations of the scene's sample points in the photos, and the options that tell the estimator how
/// to read their values.
#[derive(Debug)]
pub struct Overlap {
    pub observations: Vec<Observation>,
    pub mode: ResponseMode,
    pub points: usize,
}

/// Area-uniform points on the mesh, keyed by (seed, point index) so they do not depend on thread count.
fn sample_points(scene: &Ingested, n: usize, seed: u64) -> Vec<SurfaceSample> {
    let corners = |t: &[u32; 3]| t.map(|i| scene.positions[i as usize]);
    let mut cdf = Vec::with_capacity(scene.triangles.len());
    let mut total = 0.0f64;
    for t in &scene.triangles {
        let [a, b, c] = corners(t);
        total += f64::from((b - a).cross(c - a).length()) * 0.5;
        cdf.push(total);
    }
    if total <= 0.0 {
        return Vec::new();
    }
    (0..n as u64)
        .map(|k| {
            let u = uniform(seed, draw::CALIBRATION_POINTS, k, 0) * total;
            let tri = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
            let [a, b, c] = corners(&scene.triangles[tri]);
            // Uniform on the triangle: fold the unit square onto it.
            let (mut s, mut t) = (
                uniform(seed, draw::CALIBRATION_POINTS, k, 1) as f32,
                uniform(seed, draw::CALIBRATION_POINTS, k, 2) as f32,
            );
            if s + t > 1.0 {
                (s, t) = (1.0 - s, 1.0 - t);
            }
            let p = a + (b - a) * s + (c - a) * t;
            SurfaceSample { p, n: (b - a).cross(c - a).normalize_or_zero() }
        })
        .filter(|s| s.n != Vec3::ZERO)
        .collect()
}

/// The observations of `points` in one photo: visible, facing the camera, inside the image, at a valid pixel.
fn observe(
    view_index: usize,
    view: &View,
    image: &DecodedImage,
    points: &[SurfaceSample],
    scene: &tracer::Scene,
) -> Vec<Observation> {
    let cam = &view.camera;
    let centre = cam.cam_to_world.w_axis.truncate();
    let mut out = Vec::new();
    for (k, s) in points.iter().enumerate() {
        let p = s.p.as_dvec3();
        let to_cam = centre - p;
        let dist = to_cam.length();
        if dist <= 0.0 || f64::from(s.n.dot(to_cam.as_vec3())) / dist < MIN_COS_VIEW {
            continue;
        }
        let Some(px) = cam.project_world(p) else { continue };
        let (x, y) = (px.x.round(), px.y.round());
        if x < 0.0 || y < 0.0 || x > f64::from(cam.width - 1) || y > f64::from(cam.height - 1) {
            continue;
        }
        let dir: DVec3 = -to_cam / dist;
        if scene.occluded(centre.as_vec3(), dir.as_vec3(), (dist * (1.0 - OCCLUSION_SHORTFALL)) as f32) {
            continue;
        }
        let (x, y) = (x as u32, y as u32);
        let i = (y * cam.width + x) as usize;
        let value = match image {
            DecodedImage::Linear(img) => {
                if img.mask[i] == 0 {
                    continue;
                }
                [img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]]
            }
            DecodedImage::Display(img) => {
                if img.mask[i] == 0 {
                    continue;
                }
                let m = f32::from(img.max_code);
                [0, 1, 2].map(|c| f32::from(img.codes[3 * i + c]) / m)
            }
        };
        let ki = &cam.intrinsics;
        let r2 = normalised_r2(f64::from(x), f64::from(y), ki.cx, ki.cy, cam.width, cam.height) as f32;
        out.push(Observation { point: k as u32, photo: view_index as u32, r2, value });
    }
    out
}

/// Samples the scene's points and observes them in every chosen photo (decoded in parallel, one per worker at
/// a time). Errors name a photo that cannot be read, or a scan mixing linear and display-referred photos.
pub fn observe_overlap(
    scene_data: &Ingested,
    views: &[&View],
    cfg: &ImagesConfig,
    seed: u64,
    progress: &dyn optim::Progress,
) -> Result<Overlap, StageError> {
    let scene = tracer::Scene::new(scene_data.scene_input())?;
    let points = sample_points(scene_data, cfg.calibration_points as usize, seed);
    let per_view: Vec<(Vec<Observation>, bool)> = views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            if progress.stop_requested() {
                return Err(StageError::Interrupted);
            }
            let image = read_image(&v.image_path)?;
            let linear = matches!(image, DecodedImage::Linear(_));
            let obs = observe(i, v, &image, &points, &scene);
            progress.inc(1);
            Ok((obs, linear))
        })
        .collect::<Result<_, StageError>>()?;
    let linear = per_view.iter().filter(|(_, l)| *l).count();
    if linear != 0 && linear != per_view.len() {
        let path = views[per_view.iter().position(|(_, l)| !*l).unwrap_or(0)].image_path.clone();
        return Err(StageError::Artefact {
            path,
            message: format!(
                "display-referred photo in a scan whose other {linear} photos are linear: one calibration cannot \
                 serve both"
            ),
        });
    }
    let mode = if linear > 0 {
        ResponseMode::Linear
    } else if cfg.response == ResponseChoice::Estimate {
        ResponseMode::Estimate
    } else {
        ResponseMode::Srgb
    };
    Ok(Overlap { observations: per_view.into_iter().flat_map(|(o, _)| o).collect(), mode, points: points.len() })
}

/// The estimator's options from the config and the photos' kind.
#[must_use]
pub fn options(cfg: &ImagesConfig, mode: ResponseMode, seed: u64) -> CalibrationOptions {
    CalibrationOptions {
        response: mode,
        response_channels: cfg.response_channels,
        exposure: cfg.exposure == PerPhoto::PerPhoto,
        white_balance: cfg.white_balance == PerPhoto::PerPhoto,
        vignetting: cfg.vignetting == VignettingChoice::Estimate,
        seed,
    }
}

/// Each view's physical camera: Matterport's `_i<c>_` file-name index when every view has one, else one group
/// per distinct set of intrinsics and image size (different lenses have different intrinsics).
#[must_use]
pub fn camera_groups(views: &[&View]) -> Vec<u32> {
    let named: Option<Vec<u32>> = views.iter().map(|v| ingest::matterport::physical_camera(&v.name)).collect();
    if let Some(groups) = named {
        return groups;
    }
    let mut seen: Vec<[u64; 6]> = Vec::new();
    views
        .iter()
        .map(|v| {
            let c = &v.camera;
            let k = &c.intrinsics;
            let key = [
                u64::from(c.width),
                u64::from(c.height),
                k.fx.to_bits(),
                k.fy.to_bits(),
                k.cx.to_bits(),
                k.cy.to_bits(),
            ];
            let g = seen.iter().position(|s| *s == key).unwrap_or_else(|| {
                seen.push(key);
                seen.len() - 1
            });
            g as u32
        })
        .collect()
}

/// Runs the estimator on the observations.
pub fn solve(overlap: &Overlap, groups: &[u32], opts: &CalibrationOptions) -> Result<Calibration, CalibrateError> {
    ingest::photo::calibrate::calibrate(groups, &overlap.observations, opts)
}
