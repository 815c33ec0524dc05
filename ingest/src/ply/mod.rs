//! PLY meshes: a single-pass reader (ASCII, binary little- and big-endian) and a binary little-endian writer.
//!
//! The reader keeps what a scan needs — vertex positions, optional normals, triangles (polygons are
//! fan-triangulated) and every scalar face property as a per-triangle column — and skips everything else
//! (extra vertex properties, other elements, list properties other than `vertex_indices`).

mod header;
mod read;
mod write;

pub use header::{Element, Encoding, Header, Property, PropertyKind, ScalarType, parse_header};
pub use read::{PlyRead, read_ply, read_ply_bytes};
pub use write::{encode_ply, write_ply};

use glam::Vec3;

/// One per-face (per-triangle) column.
#[derive(Debug, Clone, PartialEq)]
pub enum FaceValues {
    /// Written as PLY `float`.
    F32(Vec<f32>),
    /// Written as PLY `int`.
    I32(Vec<i32>),
    /// Written as PLY `uchar`.
    U8(Vec<u8>),
}

impl FaceValues {
    /// Number of values in the column.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::F32(v) => v.len(),
            Self::I32(v) => v.len(),
            Self::U8(v) => v.len(),
        }
    }

    /// True when the column is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The PLY type name this column is written as.
    #[must_use]
    pub fn ply_type(&self) -> &'static str {
        match self {
            Self::F32(_) => "float",
            Self::I32(_) => "int",
            Self::U8(_) => "uchar",
        }
    }
}

/// A named per-face column.
#[derive(Debug, Clone, PartialEq)]
pub struct FaceProperty {
    pub name: String,
    pub values: FaceValues,
}

/// A triangle mesh as stored in a PLY file: per-vertex positions (+ normals) and per-face named columns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-triangle columns, written in this order after `vertex_indices`.
    pub face_props: Vec<FaceProperty>,
}

impl PlyMesh {
    /// The face column called `name`, if any.
    #[must_use]
    pub fn face_prop(&self, name: &str) -> Option<&FaceValues> {
        self.face_props.iter().find(|p| p.name == name).map(|p| &p.values)
    }

    /// An integer id column (`int` or `uchar`) as `i32`; `None` if absent or a float column.
    #[must_use]
    pub fn face_ids(&self, name: &str) -> Option<Vec<i32>> {
        match self.face_prop(name)? {
            FaceValues::I32(v) => Some(v.clone()),
            FaceValues::U8(v) => Some(v.iter().map(|&x| i32::from(x)).collect()),
            FaceValues::F32(_) => None,
        }
    }
}
