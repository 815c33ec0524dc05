//! The crate's error type. Every variant names the file it is about and, where one exists, the line or the
//! element index, so a user can go straight to the offending input.

use std::path::PathBuf;

/// Errors from reading or writing scan files.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    /// The operating system refused an operation on `path`.
    #[error("{path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file as a whole is malformed (no finer location applies).
    #[error("{path}: {message}", path = .path.display())]
    Format { path: PathBuf, message: String },
    /// A text file is malformed at a 1-based line.
    #[error("{path}:{line}: {message}", path = .path.display())]
    Line { path: PathBuf, line: usize, message: String },
    /// An element (PLY vertex/face, COLMAP image, JSON frame, ...) is malformed; `index` is 0-based.
    #[error("{path}: {element} {index}: {message}", path = .path.display())]
    Element { path: PathBuf, element: String, index: usize, message: String },
    /// A file listed by another file does not exist.
    #[error("{listed_in}: lists image {missing}, which does not exist", listed_in = .listed_in.display(), missing = .missing.display())]
    MissingImage { listed_in: PathBuf, missing: PathBuf },
    /// An image's pixel size disagrees with the calibration that describes it.
    #[error("{path}: image is {width}x{height} but {expected}", path = .path.display())]
    ImageSize { path: PathBuf, width: u32, height: u32, expected: String },
    /// The scan directory does not hold a layout we know.
    #[error("{dir}: {message}", dir = .dir.display())]
    Layout { dir: PathBuf, message: String },
}

impl IngestError {
    /// Wraps an I/O error with the path it concerns.
    #[must_use]
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }

    /// A whole-file format error.
    #[must_use]
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format { path: path.into(), message: message.into() }
    }

    /// A format error at a 1-based line of a text file.
    #[must_use]
    pub fn line(path: impl Into<PathBuf>, line: usize, message: impl Into<String>) -> Self {
        Self::Line { path: path.into(), line, message: message.into() }
    }

    /// A format error at a 0-based element index.
    #[must_use]
    pub fn element(
        path: impl Into<PathBuf>,
        element: impl Into<String>,
        index: usize,
        message: impl Into<String>,
    ) -> Self {
        Self::Element { path: path.into(), element: element.into(), index, message: message.into() }
    }
}

/// A third-party error message made fit for a one-line error: control characters (line breaks, NULs, ...;
/// some decoders end their messages with a newline or quote raw input bytes) are escaped and surrounding
/// whitespace is trimmed.
pub(crate) fn one_line(message: impl std::fmt::Display) -> String {
    let message = message.to_string();
    let mut out = String::with_capacity(message.len());
    for c in message.trim().chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// A text file's bytes as UTF-8, or an error naming the file and the offset of the first bad byte.
pub(crate) fn utf8<'a>(path: &std::path::Path, bytes: &'a [u8]) -> Result<&'a str, IngestError> {
    std::str::from_utf8(bytes)
        .map_err(|e| IngestError::format(path, format!("not UTF-8 text (byte {})", e.valid_up_to())))
}
