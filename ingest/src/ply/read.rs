//! Single-pass PLY reader over the file's bytes.
//!
//! The header is parsed first and every element count is checked against the bytes that follow it before any
//! per-element buffer is allocated, so a corrupt count cannot trigger a huge allocation.

use std::path::Path;

use glam::Vec3;

use super::header::{Element, Encoding, Header, PropertyKind, ScalarType, parse_header};
use super::{FaceProperty, FaceValues, PlyMesh};
use crate::error::IngestError;

/// What `read_ply` returns: the mesh and how its triangles map back to the file's faces.
#[derive(Debug, Clone, PartialEq)]
pub struct PlyRead {
    /// Triangles and per-triangle columns (a polygon's columns are repeated on each of its triangles).
    pub mesh: PlyMesh,
    /// For each triangle, the index of the file face it came from (for per-face side files like `.fsegs.json`).
    pub source_face: Vec<u32>,
    /// Number of faces in the file.
    pub face_count: usize,
    /// Number of faces with more than three vertices, fan-triangulated.
    pub polygons_triangulated: usize,
}

/// Reads a PLY file (ASCII, binary little- or big-endian).
pub fn read_ply(path: &Path) -> Result<PlyRead, IngestError> {
    let bytes = std::fs::read(path).map_err(|e| IngestError::io(path, e))?;
    read_ply_bytes(path, &bytes)
}

/// Reads PLY data already in memory; `path` is used only in error messages.
pub fn read_ply_bytes(path: &Path, bytes: &[u8]) -> Result<PlyRead, IngestError> {
    let header = parse_header(path, bytes)?;
    let data = &bytes[header.data_offset..];
    check_counts_fit(path, &header, data.len())?;
    match header.encoding {
        Encoding::BinaryLittleEndian => read_body(path, &header, data.len(), &mut Binary::<false> { data, pos: 0 }),
        Encoding::BinaryBigEndian => read_body(path, &header, data.len(), &mut Binary::<true> { data, pos: 0 }),
        Encoding::Ascii => {
            let text = std::str::from_utf8(data).map_err(|e| {
                IngestError::format(path, format!("ASCII PLY body is not text (byte {})", e.valid_up_to()))
            })?;
            read_body(path, &header, data.len(), &mut Ascii { tokens: text.split_ascii_whitespace() })
        }
    }
}

/// Rejects headers that declare more rows than the remaining bytes can hold, before anything is allocated.
fn check_counts_fit(path: &Path, header: &Header, available: usize) -> Result<(), IngestError> {
    let mut needed: usize = 0;
    for e in &header.elements {
        let before = needed;
        // Binary: a row takes at least its fixed-size scalars and list counts. ASCII: every property is at least
        // one character plus one separator.
        let min_row = min_row(header.encoding, e, 0);
        let element_bytes = e.count.checked_mul(min_row);
        needed = match element_bytes.and_then(|b| needed.checked_add(b)) {
            Some(n) => n,
            None => usize::MAX,
        };
        // ASCII's last row may lack its final separator.
        let slack = usize::from(header.encoding == Encoding::Ascii);
        if needed > available.saturating_add(slack) {
            // The first row that cannot fit even at minimum size: the file is truncated there at the latest.
            let first_missing = (available.saturating_add(slack).saturating_sub(before)) / min_row.max(1);
            return Err(IngestError::element(
                path,
                e.name.clone(),
                first_missing.min(e.count),
                format!(
                    "truncated or bad header: header declares {} {:?} elements, but the {available} bytes after the \
                     header cannot hold them (at least {} bytes needed up to this element)",
                    e.count,
                    e.name,
                    if needed == usize::MAX { "more than usize::MAX".to_string() } else { needed.to_string() }
                ),
            ));
        }
    }
    Ok(())
}

/// Fewest bytes a row of `e` takes with `items` items in its vertex index list (0 for other lists). Binary: its
/// fixed-size scalars, list counts and those items. ASCII: every value is at least one character plus one
/// separator.
fn min_row(encoding: Encoding, e: &Element, items: usize) -> usize {
    match encoding {
        Encoding::Ascii => 2 * (e.props.len() + items),
        _ => e.min_binary_row() + items * vertex_index_item_size(e),
    }
}

/// How many faces of `e` the `available` bytes can hold when every face is valid (at least 3 vertex indices):
/// the most worth reserving per-face buffers for. A file with more faces is refused while they are read.
fn faces_that_fit(encoding: Encoding, e: &Element, available: usize) -> usize {
    let items = if e.props.iter().any(is_vertex_indices) { 3 } else { 0 };
    e.count.min(available / min_row(encoding, e, items).max(1))
}

/// True for the face property read as the vertex index list (the first list named `vertex_indices` or
/// `vertex_index`).
fn is_vertex_indices(p: &super::header::Property) -> bool {
    matches!(p.kind, PropertyKind::List { .. }) && (p.name == "vertex_indices" || p.name == "vertex_index")
}

/// Size in bytes of one item of `e`'s vertex index list (0 without one).
fn vertex_index_item_size(e: &Element) -> usize {
    e.props.iter().find(|p| is_vertex_indices(p)).map_or(0, |p| match p.kind {
        PropertyKind::List { item, .. } => item.size(),
        PropertyKind::Scalar(_) => 0,
    })
}

/// Why one value could not be read.
enum ValueError {
    /// The data ended.
    Eof,
    /// An ASCII token that does not parse as the declared type.
    Bad(String),
}

/// A stream of scalar values in one encoding.
trait Source {
    fn scalar(&mut self, t: ScalarType) -> Result<f64, ValueError>;
}

struct Binary<'a, const BIG: bool> {
    data: &'a [u8],
    pos: usize,
}

impl<const BIG: bool> Binary<'_, BIG> {
    #[inline]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], ValueError> {
        let end = self.pos + N;
        let Some(slice) = self.data.get(self.pos..end) else { return Err(ValueError::Eof) };
        self.pos = end;
        let mut a = [0u8; N];
        a.copy_from_slice(slice);
        if BIG {
            a.reverse();
        }
        Ok(a)
    }
}

impl<const BIG: bool> Source for Binary<'_, BIG> {
    #[inline]
    fn scalar(&mut self, t: ScalarType) -> Result<f64, ValueError> {
        Ok(match t {
            ScalarType::I8 => f64::from(i8::from_le_bytes(self.take::<1>()?)),
            ScalarType::U8 => f64::from(self.take::<1>()?[0]),
            ScalarType::I16 => f64::from(i16::from_le_bytes(self.take::<2>()?)),
            ScalarType::U16 => f64::from(u16::from_le_bytes(self.take::<2>()?)),
            ScalarType::I32 => f64::from(i32::from_le_bytes(self.take::<4>()?)),
            ScalarType::U32 => f64::from(u32::from_le_bytes(self.take::<4>()?)),
            ScalarType::F32 => f64::from(f32::from_le_bytes(self.take::<4>()?)),
            ScalarType::F64 => f64::from_le_bytes(self.take::<8>()?),
        })
    }
}

struct Ascii<'a> {
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl Source for Ascii<'_> {
    fn scalar(&mut self, t: ScalarType) -> Result<f64, ValueError> {
        let tok = self.tokens.next().ok_or(ValueError::Eof)?;
        if t.is_integer() {
            let v = match tok.parse::<i64>() {
                // i64 → f64 is exact for every value a PLY integer type can hold (at most 32 bits).
                Ok(v) => v as f64,
                // Some writers print integers as "3.0"; accept integral floats.
                Err(_) => match tok.parse::<f64>() {
                    Ok(v) if v.fract() == 0.0 => v,
                    _ => return Err(ValueError::Bad(format!("{tok:?} is not an integer"))),
                },
            };
            // A binary file cannot hold a value outside its declared type; an ASCII one must not either, or a
            // later cast to that type would silently clamp it.
            let (lo, hi) = t.integer_range();
            if !(lo..=hi).contains(&v) {
                return Err(ValueError::Bad(format!("{tok:?} is outside the range of its type {t:?} ({lo}..={hi})")));
            }
            return Ok(v);
        }
        tok.parse::<f64>().map_err(|_| ValueError::Bad(format!("{tok:?} is not a number")))
    }
}

/// What to do with each vertex property.
#[derive(Clone, Copy)]
enum VertexSlot {
    Pos(usize),
    Normal(usize),
    Skip,
}

/// What to do with each face property.
#[derive(Clone, Copy)]
enum FaceSlot {
    Indices,
    Column(usize),
    Skip,
}

/// A face column being filled, in the type it will be stored as.
enum Column {
    F32(Vec<f32>),
    I32(Vec<i32>),
    U8(Vec<u8>),
}

/// Reads every element; `available` is the number of data bytes (bounds the per-face reservations).
fn read_body<S: Source>(path: &Path, header: &Header, available: usize, src: &mut S) -> Result<PlyRead, IngestError> {
    let vertex_count = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| IngestError::format(path, "PLY has no `vertex` element"))?
        .count;
    if vertex_count > u32::MAX as usize {
        return Err(IngestError::format(path, format!("{vertex_count} vertices exceed the 2^32 vertex limit")));
    }
    for name in ["vertex", "face"] {
        if header.elements.iter().filter(|e| e.name == name).count() > 1 {
            return Err(IngestError::format(path, format!("PLY header declares more than one `{name}` element")));
        }
    }
    let mut positions = Vec::new();
    let mut normals = None;
    let mut faces = None;
    for element in &header.elements {
        match element.name.as_str() {
            "vertex" => {
                let (p, n) = read_vertices(path, element, src)?;
                positions = p;
                normals = n;
            }
            "face" => {
                let reserve = faces_that_fit(header.encoding, element, available);
                faces = Some(read_faces(path, element, vertex_count, reserve, src)?);
            }
            // An element without properties has rows of zero bytes: nothing to skip, however large its count.
            _ if element.props.is_empty() => {}
            _ => {
                for i in 0..element.count {
                    for prop in &element.props {
                        skip_property(prop.kind, src).map_err(|e| value_error(path, element, i, &prop.name, e))?;
                    }
                }
            }
        }
    }
    let faces = faces.ok_or_else(|| IngestError::format(path, "PLY has no `face` element"))?;
    Ok(PlyRead {
        mesh: PlyMesh { positions, normals, triangles: faces.triangles, face_props: faces.columns },
        source_face: faces.source_face,
        face_count: faces.face_count,
        polygons_triangulated: faces.polygons,
    })
}

fn value_error(path: &Path, element: &Element, index: usize, prop: &str, e: ValueError) -> IngestError {
    let message = match e {
        ValueError::Eof => format!("file is truncated: data ends while reading property {prop:?}"),
        ValueError::Bad(why) => format!("property {prop:?}: {why}"),
    };
    IngestError::element(path, element.name.clone(), index, message)
}

fn skip_property<S: Source>(kind: PropertyKind, src: &mut S) -> Result<(), ValueError> {
    match kind {
        PropertyKind::Scalar(t) => {
            src.scalar(t)?;
        }
        PropertyKind::List { count, item } => {
            let n = src.scalar(count)?;
            if n < 0.0 {
                return Err(ValueError::Bad(format!("list length {n} is negative")));
            }
            for _ in 0..n as u64 {
                src.scalar(item)?;
            }
        }
    }
    Ok(())
}

type Vertices = (Vec<Vec3>, Option<Vec<Vec3>>);

fn read_vertices<S: Source>(path: &Path, element: &Element, src: &mut S) -> Result<Vertices, IngestError> {
    let slots: Vec<VertexSlot> = element
        .props
        .iter()
        .map(|p| match (p.name.as_str(), p.kind) {
            ("x", PropertyKind::Scalar(_)) => VertexSlot::Pos(0),
            ("y", PropertyKind::Scalar(_)) => VertexSlot::Pos(1),
            ("z", PropertyKind::Scalar(_)) => VertexSlot::Pos(2),
            ("nx", PropertyKind::Scalar(_)) => VertexSlot::Normal(0),
            ("ny", PropertyKind::Scalar(_)) => VertexSlot::Normal(1),
            ("nz", PropertyKind::Scalar(_)) => VertexSlot::Normal(2),
            _ => VertexSlot::Skip,
        })
        .collect();
    let has = |slot: fn(&VertexSlot) -> bool| slots.iter().filter(|s| slot(s)).count() == 3;
    if !has(|s| matches!(s, VertexSlot::Pos(_))) {
        return Err(IngestError::format(path, "PLY vertex element lacks one of the properties x, y, z"));
    }
    let want_normals = has(|s| matches!(s, VertexSlot::Normal(_)));
    let mut positions = Vec::with_capacity(element.count);
    let mut normals = if want_normals { Vec::with_capacity(element.count) } else { Vec::new() };
    for i in 0..element.count {
        let mut p = [0.0f32; 3];
        let mut n = [0.0f32; 3];
        for (prop, slot) in element.props.iter().zip(&slots) {
            let read = |src: &mut S, t| src.scalar(t).map_err(|e| value_error(path, element, i, &prop.name, e));
            match (*slot, prop.kind) {
                (VertexSlot::Pos(k), PropertyKind::Scalar(t)) => p[k] = read(src, t)? as f32,
                (VertexSlot::Normal(k), PropertyKind::Scalar(t)) => n[k] = read(src, t)? as f32,
                (_, kind) => skip_property(kind, src).map_err(|e| value_error(path, element, i, &prop.name, e))?,
            }
        }
        if !p.iter().all(|v| v.is_finite()) {
            return Err(IngestError::element(path, "vertex", i, format!("position {p:?} is not finite (NaN or Inf)")));
        }
        if want_normals && !n.iter().all(|v| v.is_finite()) {
            return Err(IngestError::element(path, "vertex", i, format!("normal {n:?} is not finite (NaN or Inf)")));
        }
        positions.push(Vec3::from_array(p));
        if want_normals {
            normals.push(Vec3::from_array(n));
        }
    }
    Ok((positions, want_normals.then_some(normals)))
}

struct Faces {
    triangles: Vec<[u32; 3]>,
    source_face: Vec<u32>,
    columns: Vec<FaceProperty>,
    face_count: usize,
    polygons: usize,
}

/// Reads the faces; per-face buffers reserve room for `reserve` faces (they grow if polygons need more).
fn read_faces<S: Source>(
    path: &Path,
    element: &Element,
    vertex_count: usize,
    reserve: usize,
    src: &mut S,
) -> Result<Faces, IngestError> {
    let face_err = |i: usize, msg: String| IngestError::element(path, "face", i, msg);
    if element.count > u32::MAX as usize {
        return Err(IngestError::format(path, format!("{} faces exceed the 2^32 face limit", element.count)));
    }
    let mut names = Vec::new();
    let mut columns = Vec::new();
    let mut index_prop = None;
    let slots: Vec<FaceSlot> = element
        .props
        .iter()
        .enumerate()
        .map(|(k, p)| match p.kind {
            PropertyKind::List { item, .. }
                if (p.name == "vertex_indices" || p.name == "vertex_index") && index_prop.is_none() =>
            {
                index_prop = Some((k, item));
                FaceSlot::Indices
            }
            PropertyKind::Scalar(t) => {
                names.push(p.name.clone());
                columns.push(match t {
                    ScalarType::F32 | ScalarType::F64 => Column::F32(Vec::with_capacity(reserve)),
                    ScalarType::U8 => Column::U8(Vec::with_capacity(reserve)),
                    _ => Column::I32(Vec::with_capacity(reserve)),
                });
                FaceSlot::Column(columns.len() - 1)
            }
            PropertyKind::List { .. } => FaceSlot::Skip,
        })
        .collect();
    let Some((_, item_type)) = index_prop else {
        return Err(IngestError::format(path, "PLY face element has no `vertex_indices` list property"));
    };
    if !item_type.is_integer() {
        return Err(IngestError::format(path, "PLY `vertex_indices` items are not an integer type"));
    }
    let mut triangles = Vec::with_capacity(reserve);
    let mut source_face = Vec::with_capacity(reserve);
    let mut polygons = 0usize;
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    for i in 0..element.count {
        for (prop, slot) in element.props.iter().zip(&slots) {
            let ve = |e| value_error(path, element, i, &prop.name, e);
            match (*slot, prop.kind) {
                (FaceSlot::Indices, PropertyKind::List { count, item }) => {
                    let n = src.scalar(count).map_err(ve)?;
                    if !(3.0..=f64::from(u32::MAX)).contains(&n) {
                        return Err(face_err(i, format!("has {n} vertex indices; a face needs at least 3")));
                    }
                    poly.clear();
                    for _ in 0..n as u32 {
                        let v = src.scalar(item).map_err(ve)?;
                        if !(0.0..vertex_count as f64).contains(&v) {
                            return Err(face_err(
                                i,
                                format!("vertex index {v} is out of range (the file has {vertex_count} vertices)"),
                            ));
                        }
                        poly.push(v as u32);
                    }
                }
                (FaceSlot::Column(c), PropertyKind::Scalar(t)) => {
                    let v = src.scalar(t).map_err(ve)?;
                    match &mut columns[c] {
                        Column::F32(col) => col.push(v as f32),
                        Column::U8(col) => col.push(v as u8),
                        Column::I32(col) => {
                            let Ok(x) = i32::try_from(v as i64) else {
                                return Err(face_err(
                                    i,
                                    format!("property {:?} = {v} does not fit in an int", prop.name),
                                ));
                            };
                            col.push(x);
                        }
                    }
                }
                (_, kind) => skip_property(kind, src).map_err(ve)?,
            }
        }
        if poly.len() > 3 {
            polygons += 1;
        }
        // Fan triangulation: (v0, v_k, v_k+1).
        for k in 1..poly.len() - 1 {
            triangles.push([poly[0], poly[k], poly[k + 1]]);
            source_face.push(i as u32);
        }
    }
    // Repeat each polygon's column values on all of its triangles.
    let expand = polygons > 0;
    let columns = names
        .into_iter()
        .zip(columns)
        .map(|(name, col)| {
            let values = match col {
                Column::F32(v) => FaceValues::F32(if expand { remap(&v, &source_face) } else { v }),
                Column::I32(v) => FaceValues::I32(if expand { remap(&v, &source_face) } else { v }),
                Column::U8(v) => FaceValues::U8(if expand { remap(&v, &source_face) } else { v }),
            };
            FaceProperty { name, values }
        })
        .collect();
    Ok(Faces { triangles, source_face, columns, face_count: element.count, polygons })
}

fn remap<T: Copy>(per_face: &[T], source_face: &[u32]) -> Vec<T> {
    source_face.iter().map(|&f| per_face[f as usize]).collect()
}
