//! Image files referenced by camera files: preferring linear HDR siblings, and reading pixel sizes from headers
//! without decoding pixels.

use std::io::{BufRead, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::error::{IngestError, one_line};

/// First four bytes of every OpenEXR file.
pub(crate) const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

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
    let file = std::fs::File::open(path).map_err(|e| IngestError::io(path, e))?;
    dimensions_from(path, std::io::BufReader::new(file))
}

/// [`image_dimensions`] of an image file already in memory; `path` is used only in error messages.
pub fn image_dimensions_bytes(path: &Path, bytes: &[u8]) -> Result<(u32, u32), IngestError> {
    dimensions_from(path, std::io::Cursor::new(bytes))
}

/// Reads only the header: an EXR is recognised by its magic number, anything else by the `image` crate's format
/// sniffing.
fn dimensions_from<R: BufRead + Seek>(path: &Path, mut reader: R) -> Result<(u32, u32), IngestError> {
    let mut magic = [0u8; 4];
    let got = read_up_to(&mut reader, &mut magic).map_err(|e| IngestError::io(path, e))?;
    reader.seek(SeekFrom::Start(0)).map_err(|e| IngestError::io(path, e))?;
    if got == 4 && magic == EXR_MAGIC {
        let meta = exr::meta::MetaData::read_from_buffered(reader, false)
            .map_err(|e| IngestError::format(path, format!("cannot read EXR header: {}", one_line(e))))?;
        let header = meta.headers.first().ok_or_else(|| IngestError::format(path, "EXR has no layers"))?;
        let size = header.layer_size;
        let w = u32::try_from(size.0).map_err(|_| IngestError::format(path, "EXR width too large"))?;
        let h = u32::try_from(size.1).map_err(|_| IngestError::format(path, "EXR height too large"))?;
        return Ok((w, h));
    }
    image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| IngestError::io(path, e))?
        .into_dimensions()
        .map_err(|e| IngestError::format(path, format!("cannot read image header: {}", one_line(e))))
}

/// Reads until `buf` is full or the data ends; returns the number of bytes read.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match reader.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
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
