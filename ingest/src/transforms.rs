//! nerfstudio / instant-ngp `transforms.json`: pinhole + `k1 k2 (k3) p1 p2` intrinsics (top level, or per frame)
//! and OpenGL camera-to-world `transform_matrix` per frame.
//!
//! nerfstudio's pixel centres are at +0.5 (as COLMAP's), so `cx, cy` are shifted by -0.5 into this crate's
//! convention; the camera frame is already OpenGL, so poses are used as they are.

use std::path::{Path, PathBuf};

use glam::DMat4;
use serde_json::Value;

use crate::camera::{Camera, Distortion, Intrinsics, View, check_unique_names};
use crate::error::IngestError;
use crate::image_header::{image_dimensions, resolve_image};
use crate::pose::check_rigid;

/// Reads `transforms.json` at `path`; image paths are relative to its directory.
pub fn load_views(path: &Path) -> Result<Vec<View>, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    load_views_bytes(path, &bytes)
}

/// [`load_views`] on the file's bytes already in memory; images are still looked up (and their headers read)
/// relative to `path`'s directory.
pub fn load_views_bytes(path: &Path, bytes: &[u8]) -> Result<Vec<View>, IngestError> {
    let root: Value =
        serde_json::from_slice(bytes).map_err(|e| IngestError::line(path, e.line(), format!("bad JSON: {e}")))?;
    let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    if let Some(model) = root.get("camera_model").and_then(Value::as_str)
        && model != "OPENCV"
        && model != "PINHOLE"
    {
        return Err(IngestError::format(
            path,
            format!("unsupported camera_model {model:?} (supported: OPENCV, PINHOLE)"),
        ));
    }
    let frames =
        root.get("frames").and_then(Value::as_array).ok_or_else(|| IngestError::format(path, "no `frames` array"))?;
    let views =
        frames.iter().enumerate().map(|(i, f)| frame_view(path, &base, &root, i, f)).collect::<Result<Vec<_>, _>>()?;
    check_unique_names(&views, path)?;
    Ok(views)
}

fn frame_view(path: &Path, base: &Path, root: &Value, i: usize, frame: &Value) -> Result<View, IngestError> {
    let err = |m: String| IngestError::element(path, "frame", i, m);
    // A frame's own value overrides the top-level one.
    let num = |key: &str| -> Result<Option<f64>, IngestError> {
        match frame.get(key).or_else(|| root.get(key)) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(err(format!("`{key}` is not a finite number"))),
            },
        }
    };
    let file = frame.get("file_path").and_then(Value::as_str).ok_or_else(|| err("no `file_path`".into()))?;
    // Error messages quote the path; a line break in it would split them.
    if file.chars().any(char::is_control) {
        return Err(err(format!("`file_path` {file:?} contains a control character")));
    }
    let listed = with_image_extension(&base.join(file));
    let image_path = resolve_image(&listed, path)?;
    let (iw, ih) = image_dimensions(&image_path)?;
    let (w, h) = match (num("w")?, num("h")?) {
        (Some(w), Some(h)) => (w, h),
        (None, None) => (f64::from(iw), f64::from(ih)),
        _ => return Err(err("has only one of `w`, `h`".into())),
    };
    if (w, h) != (f64::from(iw), f64::from(ih)) {
        return Err(IngestError::ImageSize {
            path: image_path,
            width: iw,
            height: ih,
            expected: format!("{} frame {i} says {w}x{h}", path.display()),
        });
    }
    // A field of view is an angle strictly between 0 and π (180°); outside, tan gives a focal length of 0, ∞ or
    // below 0.
    let angle = |key: &str| -> Result<Option<f64>, IngestError> {
        match num(key)? {
            Some(a) if !(a > 0.0 && a < std::f64::consts::PI) => {
                Err(err(format!("`{key}` = {a} is not a field of view in (0, π): no valid focal length")))
            }
            a => Ok(a),
        }
    };
    let fx = match (num("fl_x")?, angle("camera_angle_x")?) {
        (Some(f), _) => f,
        (None, Some(a)) => 0.5 * w / (0.5 * a).tan(),
        (None, None) => return Err(err("no `fl_x` or `camera_angle_x`".into())),
    };
    let fy = match (num("fl_y")?, angle("camera_angle_y")?) {
        (Some(f), _) => f,
        (None, Some(a)) => 0.5 * h / (0.5 * a).tan(),
        (None, None) => fx,
    };
    // A `camera_angle_x` of 0 gives an infinite focal length, one of π or more a negative one.
    if !(fx.is_finite() && fy.is_finite() && fx > 0.0 && fy > 0.0) {
        return Err(err(format!("focal lengths ({fx}, {fy}) must be positive and finite")));
    }
    // Default principal point: the image centre, w/2 in the +0.5-centre convention.
    let cx = num("cx")?.unwrap_or(0.5 * w) - 0.5;
    let cy = num("cy")?.unwrap_or(0.5 * h) - 0.5;
    let d = |k: &str| num(k).map(|v| v.unwrap_or(0.0));
    let distortion =
        Distortion { k1: d("k1")?, k2: d("k2")?, k3: d("k3")?, p1: d("p1")?, p2: d("p2")?, ..Distortion::default() };
    let cam_to_world = read_matrix(frame.get("transform_matrix"))
        .ok_or_else(|| err("`transform_matrix` is not a 4x4 array of numbers".into()))?;
    check_rigid(&cam_to_world).map_err(err)?;
    let name = image_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    Ok(View {
        name,
        image_path,
        camera: Camera { width: iw, height: ih, intrinsics: Intrinsics { fx, fy, cx, cy }, distortion, cam_to_world },
    })
}

/// instant-ngp's NeRF-synthetic files omit the extension (`./train/r_0`); add the first one that exists.
fn with_image_extension(p: &Path) -> PathBuf {
    if p.extension().is_some() || p.is_file() {
        return p.to_path_buf();
    }
    ["png", "jpg", "jpeg", "exr", "hdr"]
        .iter()
        .map(|e| p.with_extension(e))
        .find(|c| c.is_file())
        .unwrap_or_else(|| p.to_path_buf())
}

/// A 4x4 matrix given as an array of 4 rows.
fn read_matrix(v: Option<&Value>) -> Option<DMat4> {
    let rows = v?.as_array()?;
    if rows.len() != 4 {
        return None;
    }
    let mut m = [0.0; 16];
    for (r, row) in rows.iter().enumerate() {
        let row = row.as_array()?;
        if row.len() != 4 {
            return None;
        }
        for (c, x) in row.iter().enumerate() {
            m[r * 4 + c] = x.as_f64()?;
        }
    }
    Some(crate::pose::from_row_major(&m))
}
