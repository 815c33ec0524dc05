//! The PLY header: format line, elements and their properties.

use std::path::Path;

use crate::error::IngestError;

/// PLY scalar types (both the `char`/`int` and the `int8`/`int32` spellings are accepted).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    /// Parses a PLY type name.
    #[must_use]
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// Size in bytes in binary encodings.
    #[must_use]
    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Smallest and largest value of an integer type (the whole f64 line for float types).
    #[must_use]
    pub fn integer_range(self) -> (f64, f64) {
        match self {
            Self::I8 => (f64::from(i8::MIN), f64::from(i8::MAX)),
            Self::U8 => (0.0, f64::from(u8::MAX)),
            Self::I16 => (f64::from(i16::MIN), f64::from(i16::MAX)),
            Self::U16 => (0.0, f64::from(u16::MAX)),
            Self::I32 => (f64::from(i32::MIN), f64::from(i32::MAX)),
            Self::U32 => (0.0, f64::from(u32::MAX)),
            Self::F32 | Self::F64 => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }

    /// True for the integer types.
    #[must_use]
    pub fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

/// A property's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropertyKind {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

/// One `property` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Property {
    pub name: String,
    pub kind: PropertyKind,
}

/// One `element` line with its properties.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Element {
    pub name: String,
    pub count: usize,
    pub props: Vec<Property>,
}

impl Element {
    /// Fewest bytes one row can take in a binary encoding (lists with zero items).
    #[must_use]
    pub fn min_binary_row(&self) -> usize {
        self.props
            .iter()
            .map(|p| match p.kind {
                PropertyKind::Scalar(t) => t.size(),
                PropertyKind::List { count, .. } => count.size(),
            })
            .sum()
    }
}

/// The data encoding named on the `format` line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A parsed header and where the data starts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    /// Byte offset of the first data byte (just after the `end_header` line).
    pub data_offset: usize,
}

/// Parses the header at the start of `bytes`. `path` is used only in error messages.
pub fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, IngestError> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(rel_end) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(IngestError::format(path, "bad PLY header: file ends before `end_header`"));
        };
        line_no += 1;
        let raw = &bytes[pos..pos + rel_end];
        pos += rel_end + 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| IngestError::line(path, line_no, "bad PLY header: line is not ASCII text"))?
            .trim_end_matches('\r');
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        if line_no == 1 {
            if tokens != ["ply"] {
                return Err(IngestError::line(path, 1, format!("bad PLY header: first line is {line:?}, not \"ply\"")));
            }
            continue;
        }
        let Some(&keyword) = tokens.first() else { continue };
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                if tokens.len() != 3 {
                    return Err(IngestError::line(path, line_no, "bad PLY header: `format` needs 2 values"));
                }
                encoding = Some(match tokens[1] {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return Err(IngestError::line(
                            path,
                            line_no,
                            format!("bad PLY header: unknown format {other:?}"),
                        ));
                    }
                });
            }
            "element" => {
                if tokens.len() != 3 {
                    return Err(IngestError::line(path, line_no, "bad PLY header: `element` needs a name and a count"));
                }
                let count = tokens[2].parse::<usize>().map_err(|_| {
                    IngestError::line(
                        path,
                        line_no,
                        format!("bad PLY header: element count {:?} is not a count", tokens[2]),
                    )
                })?;
                elements.push(Element { name: tokens[1].to_string(), count, props: Vec::new() });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(IngestError::line(path, line_no, "bad PLY header: `property` before any `element`"));
                };
                let ty = |name: &str| {
                    ScalarType::parse(name)
                        .ok_or_else(|| IngestError::line(path, line_no, format!("unknown PLY property type {name:?}")))
                };
                let prop = match tokens.as_slice() {
                    ["property", "list", c, i, name] => {
                        let count = ty(c)?;
                        let item = ty(i)?;
                        if !count.is_integer() {
                            return Err(IngestError::line(
                                path,
                                line_no,
                                format!("PLY list count type {c:?} is not an integer type"),
                            ));
                        }
                        Property { name: (*name).to_string(), kind: PropertyKind::List { count, item } }
                    }
                    ["property", t, name] if *t != "list" => {
                        Property { name: (*name).to_string(), kind: PropertyKind::Scalar(ty(t)?) }
                    }
                    _ => {
                        return Err(IngestError::line(
                            path,
                            line_no,
                            format!("bad PLY header: malformed property line {line:?}"),
                        ));
                    }
                };
                element.props.push(prop);
            }
            "end_header" => break,
            other => {
                return Err(IngestError::line(path, line_no, format!("bad PLY header: unknown keyword {other:?}")));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| IngestError::format(path, "bad PLY header: no `format` line"))?;
    Ok(Header { encoding, elements, data_offset: pos })
}
