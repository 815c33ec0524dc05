//! COLMAP text models (`cameras.txt`, `images.txt`), converted to this crate's conventions: pixel centres at
//! integers (COLMAP's `cx, cy` minus 0.5) and OpenGL camera-to-world poses (COLMAP stores world-to-camera with
//! an OpenCV camera frame: x right, y down, z forward).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DMat4, DQuat, DVec3, DVec4};

use crate::camera::{Camera, Distortion, Intrinsics, View, check_unique_names};
use crate::error::IngestError;
use crate::image_header::{check_image_size, resolve_image};

/// Largest accepted deviation of a quaternion's norm from 1: COLMAP writes unit quaternions with ~16 digits;
/// anything further off is not a rotation written by COLMAP (a scaled or garbled pose).
const QUATERNION_NORM_TOL: f64 = 1e-3;

/// One camera of `cameras.txt`, already in this crate's pixel convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColmapCamera {
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
}

/// The directory holding `cameras.txt` + `images.txt`: `dir`, `dir/sparse/0` or `dir/sparse`.
#[must_use]
pub fn find_model_dir(dir: &Path) -> Option<PathBuf> {
    [dir.to_path_buf(), dir.join("sparse").join("0"), dir.join("sparse")]
        .into_iter()
        .find(|d| d.join("cameras.txt").is_file() && d.join("images.txt").is_file())
}

fn parse_f64(path: &Path, line: usize, t: &str) -> Result<f64, IngestError> {
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(IngestError::line(path, line, format!("{t:?} is not a finite number"))),
    }
}

/// Converts COLMAP camera parameters (`model` with `params` in COLMAP order) to our intrinsics (centres at
/// integers) and distortion. `Err` carries a message.
pub fn camera_from_params(model: &str, p: &[f64]) -> Result<(Intrinsics, Distortion), String> {
    let want = match model {
        "SIMPLE_PINHOLE" => 3,
        "PINHOLE" | "SIMPLE_RADIAL" => 4,
        "RADIAL" => 5,
        "OPENCV" => 8,
        "FULL_OPENCV" => 12,
        other => {
            return Err(format!(
                "unsupported camera model {other:?} (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV)"
            ));
        }
    };
    if p.len() != want {
        return Err(format!("{model} needs {want} parameters, found {}", p.len()));
    }
    let zero = Distortion::default();
    // COLMAP puts pixel centres at +0.5; ours are at integers.
    let k = |fx: f64, fy: f64, cx: f64, cy: f64| Intrinsics { fx, fy, cx: cx - 0.5, cy: cy - 0.5 };
    let (intr, dist) = match model {
        "SIMPLE_PINHOLE" => (k(p[0], p[0], p[1], p[2]), zero),
        "PINHOLE" => (k(p[0], p[1], p[2], p[3]), zero),
        "SIMPLE_RADIAL" => (k(p[0], p[0], p[1], p[2]), Distortion { k1: p[3], ..zero }),
        "RADIAL" => (k(p[0], p[0], p[1], p[2]), Distortion { k1: p[3], k2: p[4], ..zero }),
        "OPENCV" => (k(p[0], p[1], p[2], p[3]), Distortion { k1: p[4], k2: p[5], p1: p[6], p2: p[7], ..zero }),
        _ => (
            k(p[0], p[1], p[2], p[3]),
            Distortion { k1: p[4], k2: p[5], p1: p[6], p2: p[7], k3: p[8], k4: p[9], k5: p[10], k6: p[11] },
        ),
    };
    if intr.fx <= 0.0 || intr.fy <= 0.0 {
        return Err("focal lengths must be positive".into());
    }
    Ok((intr, dist))
}

/// Reads `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...` per line, `#` comments.
pub fn read_cameras(path: &Path) -> Result<BTreeMap<u32, ColmapCamera>, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    parse_cameras(path, &bytes)
}

/// [`read_cameras`] on bytes already in memory; `path` is used only in error messages.
pub fn parse_cameras(path: &Path, bytes: &[u8]) -> Result<BTreeMap<u32, ColmapCamera>, IngestError> {
    let text = crate::error::utf8(path, bytes)?;
    let mut out = BTreeMap::new();
    for (k, line) in text.lines().enumerate() {
        let ln = k + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let t: Vec<&str> = line.split_ascii_whitespace().collect();
        if t.len() < 4 {
            return Err(IngestError::line(
                path,
                ln,
                format!("{} values, expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...", t.len()),
            ));
        }
        let int = |s: &str, what: &str| {
            s.parse::<u32>()
                .map_err(|_| IngestError::line(path, ln, format!("{what} {s:?} is not a non-negative integer")))
        };
        let id = int(t[0], "CAMERA_ID")?;
        let width = int(t[2], "WIDTH")?;
        let height = int(t[3], "HEIGHT")?;
        if width == 0 || height == 0 {
            return Err(IngestError::line(path, ln, format!("image size {width}x{height} has no pixels")));
        }
        let params = t[4..].iter().map(|s| parse_f64(path, ln, s)).collect::<Result<Vec<_>, _>>()?;
        let (intrinsics, distortion) = camera_from_params(t[1], &params).map_err(|m| IngestError::line(path, ln, m))?;
        if out.insert(id, ColmapCamera { width, height, intrinsics, distortion }).is_some() {
            return Err(IngestError::line(path, ln, format!("camera id {id} defined twice")));
        }
    }
    Ok(out)
}

/// Converts a COLMAP world-to-camera pose (unit quaternion `qw qx qy qz`, translation) to our OpenGL
/// camera-to-world matrix.
pub fn cam_to_world_from_colmap(q: [f64; 4], t: [f64; 3]) -> Result<DMat4, String> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !norm.is_finite() || (norm - 1.0).abs() > QUATERNION_NORM_TOL {
        return Err(format!("quaternion has norm {norm:.6}, not 1: not a rotation (non-rigid or non-invertible pose)"));
    }
    if !t.iter().all(|v| v.is_finite()) {
        return Err("translation is not finite".into());
    }
    let rot = DMat3::from_quat(DQuat::from_xyzw(q[1], q[2], q[3], q[0]).normalize());
    let rt = rot.transpose();
    let centre = -(rt * DVec3::from_array(t));
    // Camera-to-world in the OpenCV frame, then flip y and z to the OpenGL frame.
    let flip = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let r_gl = rt * flip;
    Ok(DMat4::from_cols(
        r_gl.x_axis.extend(0.0),
        r_gl.y_axis.extend(0.0),
        r_gl.z_axis.extend(0.0),
        DVec4::from((centre, 1.0)),
    ))
}

/// One image line of `images.txt`, pose already converted to our convention.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// 1-based line of the image entry.
    pub line: usize,
    pub camera_id: u32,
    /// The `NAME` as listed (relative to the image directory; runs of whitespace read as one space).
    pub name: String,
    /// OpenGL camera-to-world.
    pub cam_to_world: DMat4,
}

/// Parses `images.txt` already in memory (`IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME` lines, each followed
/// by a POINTS2D line); `path` is used only in error messages. Camera ids are not resolved here.
pub fn parse_images(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, IngestError> {
    let text = crate::error::utf8(path, bytes)?;
    let mut images = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((k, line)) = lines.next() {
        let ln = k + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        // The POINTS2D line follows every image line (it may be empty).
        lines.next();
        let t: Vec<&str> = line.split_ascii_whitespace().collect();
        if t.len() < 10 {
            return Err(IngestError::line(
                path,
                ln,
                format!("{} values, expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", t.len()),
            ));
        }
        let v: Vec<f64> = t[1..8].iter().map(|s| parse_f64(path, ln, s)).collect::<Result<_, _>>()?;
        let camera_id = t[8]
            .parse::<u32>()
            .map_err(|_| IngestError::line(path, ln, format!("CAMERA_ID {:?} is not an integer", t[8])))?;
        let cam_to_world = cam_to_world_from_colmap([v[0], v[1], v[2], v[3]], [v[4], v[5], v[6]])
            .map_err(|m| IngestError::line(path, ln, m))?;
        images.push(ColmapImage { line: ln, camera_id, name: t[9..].join(" "), cam_to_world });
    }
    Ok(images)
}

/// Reads `images.txt` (+ `cameras.txt` beside it) into views; images are looked up in `image_dir` and their
/// sizes must match their camera.
pub fn load_views(model_dir: &Path, image_dir: &Path) -> Result<Vec<View>, IngestError> {
    let cameras = read_cameras(&model_dir.join("cameras.txt"))?;
    let path = model_dir.join("images.txt");
    let bytes = std::fs::read(&path).map_err(|e| IngestError::io(&path, e))?;
    let mut views = Vec::new();
    for image in parse_images(&path, &bytes)? {
        let (ln, cam_id) = (image.line, image.camera_id);
        let cam = cameras
            .get(&cam_id)
            .ok_or_else(|| IngestError::line(&path, ln, format!("camera {cam_id} is not in cameras.txt")))?;
        let listed = image_dir.join(&image.name);
        let image_path = resolve_image(&listed, &path)?;
        check_image_size(&image_path, cam.width, cam.height, &format!("{}:{ln} (camera {cam_id})", path.display()))?;
        let name = Path::new(&image.name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        views.push(View {
            name,
            image_path,
            camera: Camera {
                width: cam.width,
                height: cam.height,
                intrinsics: cam.intrinsics,
                distortion: cam.distortion,
                cam_to_world: image.cam_to_world,
            },
        });
    }
    check_unique_names(&views, &path)?;
    Ok(views)
}
