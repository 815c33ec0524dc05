//! On-disk cache of prepared views in a run directory: `<name>.exr` holds channels R, G, B (linear radiance;
//! half float when that keeps every value within 2⁻¹¹ of the image's maximum, else 32-bit float, see
//! [`super::exr::half_keeps`]) and `mask` (half float, exactly 0 or 1), ZIP-compressed; `<name>.json` is the
//! manifest entry (camera of the prepared image, size, valid-pixel count). Both are written atomically with [`crate::write_atomic`]
//! (temporary file in the same directory, fsync, rename), EXR first, so a manifest entry only exists for a
//! complete image.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::image_io::{DecodedImage, read_image_checked};
use super::{LinearImage, PhotoError};
use crate::camera::Camera;

/// `format` field of every manifest entry.
const MANIFEST_FORMAT: &str = "ipt-photo-cache";
/// Bumped whenever the cache layout changes; older entries are rejected, not misread.
const MANIFEST_VERSION: u32 = 1;

/// One manifest entry (`<name>.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestEntry {
    pub format: String,
    pub version: u32,
    pub name: String,
    /// File name of the image, relative to the manifest's directory.
    pub image: String,
    pub width: u32,
    pub height: u32,
    pub valid_pixels: usize,
    /// Camera of the cached (undistorted, downscaled) image.
    pub camera: Camera,
}

fn check_name(dir: &Path, name: &str) -> Result<(), PhotoError> {
    let ok =
        !name.is_empty() && name != "." && name != ".." && !name.starts_with('.') && !name.contains(['/', '\\', '\0']);
    if ok {
        Ok(())
    } else {
        Err(PhotoError::Manifest {
            path: dir.join(name),
            message: format!("cache name {name:?} must be a plain file name (no separators, no leading dot)"),
        })
    }
}

/// Paths of the image and manifest of cache entry `name` in `dir`.
#[must_use]
pub fn cached_paths(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    (dir.join(format!("{name}.exr")), dir.join(format!("{name}.json")))
}

/// Encodes `img` as an EXR (R, G, B, mask; see [`super::exr::encode_rgb_mask`]).
pub fn encode_exr(path: &Path, img: &LinearImage) -> Result<Vec<u8>, PhotoError> {
    let n = img.pixel_count();
    if img.rgb.len() != 3 * n || img.mask.len() != n {
        return Err(PhotoError::Manifest {
            path: path.to_path_buf(),
            message: "image buffers do not match its size".into(),
        });
    }
    super::exr::encode_rgb_mask(img.width, img.height, &img.rgb, &img.mask).map_err(|e| PhotoError::Write {
        path: path.to_path_buf(),
        source: crate::error::IngestError::format(path, e.to_string()),
    })
}

/// Writes `img` to `path` as an EXR (R, G, B, mask), atomically.
pub fn write_exr(path: &Path, img: &LinearImage) -> Result<(), PhotoError> {
    let bytes = encode_exr(path, img)?;
    crate::write_atomic(path, &bytes).map_err(|source| PhotoError::Write { path: path.to_path_buf(), source })
}

/// Caches a prepared view as `<dir>/<name>.exr` + `<dir>/<name>.json` (creating `dir` if needed). Returns the
/// path of the EXR.
pub fn write_cached(dir: &Path, name: &str, camera: &Camera, img: &LinearImage) -> Result<PathBuf, PhotoError> {
    check_name(dir, name)?;
    let (exr_path, json_path) = cached_paths(dir, name);
    if (camera.width, camera.height) != (img.width, img.height) {
        return Err(PhotoError::WrongSize {
            path: exr_path,
            expected: (camera.width, camera.height),
            found: (img.width, img.height),
        });
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| PhotoError::Write { path: dir.to_path_buf(), source: crate::error::IngestError::io(dir, e) })?;
    write_exr(&exr_path, img)?;
    let entry = ManifestEntry {
        format: MANIFEST_FORMAT.into(),
        version: MANIFEST_VERSION,
        name: name.into(),
        image: format!("{name}.exr"),
        width: img.width,
        height: img.height,
        valid_pixels: img.valid_count(),
        camera: *camera,
    };
    let json = serde_json::to_vec_pretty(&entry)
        .map_err(|e| PhotoError::Manifest { path: json_path.clone(), message: e.to_string() })?;
    crate::write_atomic(&json_path, &json).map_err(|source| PhotoError::Write { path: json_path, source })?;
    Ok(exr_path)
}

/// Reads the manifest entry `<dir>/<name>.json`.
pub fn read_manifest(dir: &Path, name: &str) -> Result<ManifestEntry, PhotoError> {
    check_name(dir, name)?;
    let (_, json_path) = cached_paths(dir, name);
    let text = std::fs::read(&json_path).map_err(|source| PhotoError::Read { path: json_path.clone(), source })?;
    parse_manifest(&json_path, &text)
}

/// Parses and checks a manifest entry already in memory; `json_path` is used only in error messages.
pub fn parse_manifest(json_path: &Path, bytes: &[u8]) -> Result<ManifestEntry, PhotoError> {
    let entry: ManifestEntry = serde_json::from_slice(bytes)
        .map_err(|e| PhotoError::Manifest { path: json_path.to_path_buf(), message: e.to_string() })?;
    if entry.format != MANIFEST_FORMAT || entry.version != MANIFEST_VERSION {
        return Err(PhotoError::Manifest {
            path: json_path.to_path_buf(),
            message: format!(
                "format {:?} version {} is not {MANIFEST_FORMAT:?} version {MANIFEST_VERSION}",
                entry.format, entry.version
            ),
        });
    }
    if (entry.camera.width, entry.camera.height) != (entry.width, entry.height) {
        return Err(PhotoError::Manifest {
            path: json_path.to_path_buf(),
            message: "camera size differs from image size".into(),
        });
    }
    Ok(entry)
}

/// Reads a view cached by [`write_cached`]: its camera and image (with mask). Errors name the manifest or
/// image file and say what is wrong (missing, undecodable, size differing from the manifest).
pub fn read_cached(dir: &Path, name: &str) -> Result<(Camera, LinearImage), PhotoError> {
    let entry = read_manifest(dir, name)?;
    read_cached_entry(dir, name, entry)
}

/// [`read_cached`] with the manifest's bytes already in memory; the image is read from `dir`.
pub fn read_cached_bytes(dir: &Path, name: &str, manifest: &[u8]) -> Result<(Camera, LinearImage), PhotoError> {
    check_name(dir, name)?;
    let entry = parse_manifest(&cached_paths(dir, name).1, manifest)?;
    read_cached_entry(dir, name, entry)
}

fn read_cached_entry(dir: &Path, name: &str, entry: ManifestEntry) -> Result<(Camera, LinearImage), PhotoError> {
    let (_, json_path) = cached_paths(dir, name);
    if entry.image.contains(['/', '\\']) || entry.image.starts_with('.') {
        return Err(PhotoError::Manifest {
            path: json_path,
            message: format!("image {:?} is not a plain file name", entry.image),
        });
    }
    let exr_path = dir.join(&entry.image);
    if !exr_path.is_file() {
        return Err(PhotoError::Manifest {
            path: json_path,
            message: format!("lists image {:?}, which does not exist", entry.image),
        });
    }
    // A size mismatch is the manifest's and the image's disagreement: the error names both.
    let size_error = |found: (u32, u32)| PhotoError::Manifest {
        path: json_path.clone(),
        message: format!(
            "says {}x{} but its image {} is {}x{}",
            entry.width,
            entry.height,
            exr_path.display(),
            found.0,
            found.1
        ),
    };
    let decoded = match read_image_checked(&exr_path, Some((entry.width, entry.height))) {
        Ok((decoded, _)) => decoded,
        Err(PhotoError::WrongSize { found, .. }) => return Err(size_error(found)),
        Err(e) => return Err(e),
    };
    let img = match decoded {
        DecodedImage::Linear(img) => img,
        DecodedImage::Display(_) => {
            return Err(PhotoError::Unsupported { path: exr_path, message: "cached image is not an EXR".into() });
        }
    };
    if (img.width, img.height) != (entry.width, entry.height) {
        return Err(size_error((img.width, img.height)));
    }
    Ok((entry.camera, img))
}
