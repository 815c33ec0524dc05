//! The scene mesh: triangles with per-face id columns, and the removal of zero-area triangles.

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec3, Vec3};

/// A triangle mesh with three per-face integer id columns. A column is `-1` on every face when the source file
/// has no such id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub triangles: Vec<[u32; 3]>,
    /// Object instance id (Matterport `segment_id`; OBJ: index of the `o`/`g` group).
    pub face_segment: Vec<i32>,
    /// Semantic class (Matterport `category_id`, a row of `category_mapping.tsv`).
    pub face_category: Vec<i32>,
    /// Matterport `material_id` (over-segment id, as in `.fsegs.json`); OBJ: index of the `usemtl` material.
    pub face_material: Vec<i32>,
}

/// A mesh plus human-readable names for the ids in each column (ids without a name are absent).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LabeledMesh {
    pub mesh: Mesh,
    pub segment_labels: HashMap<i32, String>,
    pub category_labels: HashMap<i32, String>,
    pub material_labels: HashMap<i32, String>,
}

/// A triangle counts as zero-area when twice its area is at most this fraction of its longest edge squared,
/// i.e. its height is below single-precision resolution relative to its size: positions are `f32`, so such a
/// triangle is a line (or a point) as far as the stored data can tell, and has no usable normal.
const DEGENERATE_REL_AREA: f64 = f32::EPSILON as f64;

impl Mesh {
    /// Builds a mesh with all id columns set to `-1`.
    #[must_use]
    pub fn without_ids(positions: Vec<Vec3>, normals: Option<Vec<Vec3>>, triangles: Vec<[u32; 3]>) -> Self {
        let n = triangles.len();
        Self {
            positions,
            normals,
            triangles,
            face_segment: vec![-1; n],
            face_category: vec![-1; n],
            face_material: vec![-1; n],
        }
    }

    /// True when triangle `t` has (numerically) zero area.
    #[must_use]
    pub fn is_zero_area(&self, t: usize) -> bool {
        let [a, b, c] = self.triangles[t].map(|i| self.positions[i as usize].as_dvec3());
        let (e0, e1, e2): (DVec3, DVec3, DVec3) = (b - a, c - a, c - b);
        let longest2 = e0.length_squared().max(e1.length_squared()).max(e2.length_squared());
        let twice_area = e0.cross(e1).length();
        longest2 == 0.0 || twice_area <= DEGENERATE_REL_AREA * longest2
    }

    /// Removes zero-area triangles (and their ids), logging one counted warning naming `source`. Returns how
    /// many were dropped.
    pub fn drop_zero_area(&mut self, source: &Path) -> usize {
        let keep: Vec<bool> = (0..self.triangles.len()).map(|t| !self.is_zero_area(t)).collect();
        let dropped = keep.iter().filter(|&&k| !k).count();
        if dropped == 0 {
            return 0;
        }
        tracing::warn!(
            "{}: dropped {dropped} zero-area triangle(s) of {} (no area, no normal)",
            source.display(),
            self.triangles.len()
        );
        retain_by(&mut self.triangles, &keep);
        retain_by(&mut self.face_segment, &keep);
        retain_by(&mut self.face_category, &keep);
        retain_by(&mut self.face_material, &keep);
        dropped
    }

    /// Centroid of triangle `t`.
    #[must_use]
    pub fn centroid(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangles[t].map(|i| self.positions[i as usize]);
        (a + b + c) / 3.0
    }
}

fn retain_by<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        i += 1;
        keep[i - 1]
    });
}
