//! Image files referenced by camera files: preferring linear HDR siblings, and reading pixel sizes from headers
//! without decoding pixels.

use std::path::{Path, PathBuf};

use crate::error::IngestError;

/// Returns the `.exr` (or else `.hdr`) file with the same stem as `listed` when one exists — linear radiance is
/// preferred over a tone-mapped 8-bit image — and `listed` otherwise.
#[must_use]
pub fn prefer_linear(listed: &Path) -> PathBuf {
    for ext in ["exr", "hdr"] {
        let candidate = listed.with_extension(ext);
        if candidate != listed && candidate.is_file() {
            return candidate;
        }
    }
    listed.to_path_buf()
}

/// Resolves an image named in `listed_in`: the linear sibling if present, else the file itself; an error naming
/// both files if neither exists.
pub fn resolve_image(listed: &Path, listed_in: &Path) -> Result<PathBuf, IngestError> {
    let p = prefer_linear(listed);
    if p.is_file() {
        Ok(p)
    } else {
        Err(IngestError::MissingImage { listed_in: listed_in.to_path_buf(), missing: listed.to_path_buf() })
    }
}

/// Width and height of an image (EXR via its header, JPEG/PNG/HDR via the `image` crate's header reader).
pub fn image_dimensions(path: &Path) -> Result<(u32, u32), IngestError> {
    let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| IngestError::format(path, format!("cannot read EXR header: {e}")))?;
        let header = meta.headers.first().ok_or_else(|| IngestError::format(path, "EXR has no layers"))?;
        let size = header.layer_size;
        let w = u32::try_from(size.0).map_err(|_| IngestError::format(path, "EXR width too large"))?;
        let h = u32::try_from(size.1).map_err(|_| IngestError::format(path, "EXR height too large"))?;
        return Ok((w, h));
    }
    image::ImageReader::open(path)
        .map_err(|e| IngestError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| IngestError::io(path, e))?
        .into_dimensions()
        .map_err(|e| IngestError::format(path, format!("cannot read image header: {e}")))
}

/// Checks an image's header size against the size its calibration declares.
pub fn check_image_size(path: &Path, width: u32, height: u32, source: &str) -> Result<(), IngestError> {
    let (w, h) = image_dimensions(path)?;
    if (w, h) != (width, height) {
        return Err(IngestError::ImageSize {
            path: path.to_path_buf(),
            width: w,
            height: h,
            expected: format!("{source} says {width}x{height}"),
        });
    }
    Ok(())
}
