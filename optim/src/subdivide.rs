//! Adaptive subdivision geometry for the per-triangle stage: split the triangles the caller marks, keep the
//! mesh conforming, and say which input triangle every output triangle came from.
//!
//! # Scheme: one level of red refinement with green/blue closure (no propagation)
//!
//! * A **marked** triangle is split 4-way at its edge midpoints ("red"): four children similar to the parent
//!   at scale ½, so refinement never degrades shape.
//! * Every edge of a red triangle is split at its midpoint, and that midpoint is **one** shared vertex. Every
//!   other triangle that contains a split edge — in the same object or not — is cut so that it uses the
//!   midpoint too ("closure"):
//!   - one split edge → **green**: bisected from the opposite corner (2 children);
//!   - two split edges → **blue**: the corner between the two split edges is cut off at their midpoints and
//!     the remaining quadrilateral is cut along its shorter diagonal (3 children);
//!   - three split edges → red (4 children).
//!
//!   Closure cuts only edges that are already split, so it never propagates beyond the direct neighbours of
//!   the marked triangles and the set of split edges is exactly the edges of the marked triangles. The
//!   result has no T-junction: every split edge is replaced by its two halves in *every* triangle that
//!   contained it.
//! * **Across objects** closure applies too (decision): an edge shared by two objects is split on both
//!   sides, so light cannot leak through a crack at an object boundary. The neighbouring object's triangles
//!   are *cut*, not refined (green/blue children inherit the parent's parameters, so its appearance is
//!   unchanged); [`Subdivided::closure_cut`] lists them. An object none of whose edges is split is untouched.
//! * **Edges are identified by vertex position** (bit-equal, with −0 = +0), not by vertex index: scan meshes
//!   often duplicate vertices along object boundaries, and two triangles that meet there geometrically must
//!   still share the midpoint. Input vertices keep their indices; midpoints are appended after them in a
//!   deterministic order (first use while walking the triangles in order).
//! * **Limits**: no triangle created by a call has an edge shorter than [`SplitLimits::min_edge_length`] or
//!   an area below [`SplitLimits::min_area`] (checked in f64 on the exact midpoints; the stored f32 midpoints
//!   differ by at most half an ulp). A marked triangle whose own red children would break a limit is
//!   refused; when a closure (or forced red) split of some triangle would create a child below a limit, every
//!   mark sharing a split edge with that triangle is refused (conservative; iterated until no created
//!   triangle breaks a limit — marks only ever drop, so this terminates). Refused marks are reported in [`Subdivided::refused`].
//!
//! Rounds (fit → split → fit) call [`subdivide`] repeatedly. Known limitation: a green/blue closure child
//! that is later marked is itself red-split (the classic red-green "undo the green closure first" is not
//! done, since it needs the refinement history); each such round can lower the smallest angle of those
//! children, so callers should keep the number of rounds small (a handful).

use std::collections::HashMap;

use glam::{DVec3, Vec3};

/// The mesh to refine; `object_id` is per triangle.
#[derive(Debug, Clone, Copy)]
pub struct SubdivideMesh<'a> {
    pub positions: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
    pub object_id: &'a [i32],
}

/// Smallest triangles a call may create (world units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitLimits {
    /// No created edge is shorter than this; must be finite and > 0 (a zero limit would let a degenerate
    /// marked triangle be split forever).
    pub min_edge_length: f32,
    /// No created triangle has a smaller area; finite and ≥ 0.
    pub min_area: f32,
}

/// How an input triangle was split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SplitKind {
    /// Not split: copied as is.
    Unchanged,
    /// 4-way at its edge midpoints (marked, or closure with all three edges split).
    Red,
    /// Closure with one split edge: 2 children.
    Green,
    /// Closure with two split edges: 3 children.
    Blue,
}

impl SplitKind {
    /// Number of output triangles an input triangle split this way becomes.
    #[must_use]
    pub fn child_count(self) -> usize {
        match self {
            Self::Unchanged => 1,
            Self::Green => 2,
            Self::Blue => 3,
            Self::Red => 4,
        }
    }
}

/// The refined mesh. Output triangles are grouped by parent, parents in input order, so unsplit triangles
/// keep their relative order and `parent_of_new_triangle` is non-decreasing.
#[derive(Debug, Clone, PartialEq)]
pub struct Subdivided {
    /// Input vertices (same indices) followed by the new midpoint vertices.
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per output triangle: its parent's object id.
    pub object_id: Vec<i32>,
    /// Per output triangle: index of the input triangle it lies in; per-triangle parameters are inherited
    /// through it.
    pub parent_of_new_triangle: Vec<u32>,
    /// Per input triangle: how it was split.
    pub kind: Vec<SplitKind>,
    /// Input triangles that were marked and refined (red), ascending.
    pub refined: Vec<u32>,
    /// Input triangles that were marked but refused because a limit would be broken, ascending.
    pub refused: Vec<u32>,
    /// Input triangles that were not marked but were cut to keep the mesh conforming, ascending.
    pub closure_cut: Vec<u32>,
}

impl Subdivided {
    /// Per-triangle values of the input mesh carried to the output (each child takes its parent's value).
    /// `values` must have one entry per input triangle.
    pub fn inherit<T: Clone>(&self, values: &[T]) -> Result<Vec<T>, SubdivideError> {
        if values.len() != self.kind.len() {
            return Err(SubdivideError::LengthMismatch {
                what: "inherited values",
                got: values.len(),
                expected: self.kind.len(),
            });
        }
        Ok(self.parent_of_new_triangle.iter().map(|&p| values[p as usize].clone()).collect())
    }
}

/// Bad input to [`subdivide`]; never a panic.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SubdivideError {
    #[error("subdivide: {what} has {got} entries for {expected} triangles")]
    LengthMismatch { what: &'static str, got: usize, expected: usize },
    #[error("subdivide: triangle {triangle} uses vertex {vertex}, but there are only {vertex_count} vertices")]
    VertexOutOfRange { triangle: usize, vertex: u32, vertex_count: usize },
    #[error("subdivide: vertex {vertex} has a non-finite position")]
    NonFinitePosition { vertex: usize },
    #[error("subdivide: marked triangle {triangle} does not exist ({triangle_count} triangles)")]
    MarkOutOfRange { triangle: u32, triangle_count: usize },
    #[error("subdivide: limits must be finite with min_edge_length > 0 and min_area >= 0, got {limits:?}")]
    BadLimits { limits: SplitLimits },
    #[error("subdivide: the refined mesh would have more than u32::MAX vertices")]
    TooManyVertices,
}

/// Canonical undirected edge between two welded vertex ids (smaller first).
type EdgeKey = (u32, u32);

fn edge_key(a: u32, b: u32) -> EdgeKey {
    if a < b { (a, b) } else { (b, a) }
}

/// Per vertex, the index of the first vertex at the bit-identical position (−0 folded to +0).
fn weld_exact(positions: &[Vec3]) -> Vec<u32> {
    let mut first: HashMap<[u32; 3], u32> = HashMap::with_capacity(positions.len());
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            // Adding +0.0 turns −0.0 into +0.0 and leaves every other finite value unchanged.
            let bits = [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()];
            *first.entry(bits).or_insert(i as u32)
        })
        .collect()
}

fn area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    0.5 * (b - a).cross(c - a).length()
}

/// The children of triangle `v` (corner positions, in f64) for a split pattern; `mid[i]` is the midpoint of
/// edge i = (v[i], v[i+1]) when that edge is split. Returns corner references as indices into
/// `[v0, v1, v2, m0, m1, m2]` so the same table serves geometry checks and index output.
fn children(split: [bool; 3], corners: [DVec3; 3]) -> (SplitKind, Vec<[usize; 3]>) {
    // Slot numbering: 0..3 are the corners, 3 + i is the midpoint of edge i = (corner i, corner i+1).
    let n = split.iter().filter(|&&s| s).count();
    match n {
        0 => (SplitKind::Unchanged, vec![[0, 1, 2]]),
        1 => {
            let i = split.iter().position(|&s| s).unwrap_or(0);
            let (a, b, c) = (i, (i + 1) % 3, (i + 2) % 3);
            (SplitKind::Green, vec![[a, 3 + i, c], [3 + i, b, c]])
        }
        2 => {
            // Rotate so the split edges are (v0,v1) and (v1,v2) and (v2,v0) is whole.
            let j = split.iter().position(|&s| !s).unwrap_or(0);
            let (v0, v1, v2) = ((j + 1) % 3, (j + 2) % 3, j);
            let (m01, m12) = (3 + v0, 3 + v1);
            let pos = |s: usize| if s < 3 { corners[s] } else { 0.5 * (corners[s - 3] + corners[(s - 2) % 3]) };
            let corner = [m01, v1, m12];
            // The quadrilateral v0, m01, m12, v2 is cut along its shorter diagonal (better-shaped children);
            // ties take the first, so the result is deterministic.
            if pos(v0).distance(pos(m12)) <= pos(m01).distance(pos(v2)) {
                (SplitKind::Blue, vec![corner, [v0, m01, m12], [v0, m12, v2]])
            } else {
                (SplitKind::Blue, vec![corner, [v0, m01, v2], [m01, m12, v2]])
            }
        }
        _ => (SplitKind::Red, vec![[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]]),
    }
}

/// True when every child of the pattern respects the limits.
fn children_respect(split: [bool; 3], corners: [DVec3; 3], limits: &SplitLimits) -> bool {
    let pos = |s: usize| if s < 3 { corners[s] } else { 0.5 * (corners[s - 3] + corners[(s - 2) % 3]) };
    let min_edge = f64::from(limits.min_edge_length);
    let min_area = f64::from(limits.min_area);
    children(split, corners).1.iter().all(|c| {
        let p = [pos(c[0]), pos(c[1]), pos(c[2])];
        (0..3).all(|k| p[k].distance(p[(k + 1) % 3]) >= min_edge) && area(p[0], p[1], p[2]) >= min_area
    })
}

fn validate(mesh: &SubdivideMesh<'_>, marked: &[u32], limits: &SplitLimits) -> Result<(), SubdivideError> {
    let n = mesh.triangles.len();
    if mesh.object_id.len() != n {
        return Err(SubdivideError::LengthMismatch { what: "object_id", got: mesh.object_id.len(), expected: n });
    }
    if !(limits.min_edge_length.is_finite()
        && limits.min_edge_length > 0.0
        && limits.min_area.is_finite()
        && limits.min_area >= 0.0)
    {
        return Err(SubdivideError::BadLimits { limits: *limits });
    }
    if let Some(vertex) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(SubdivideError::NonFinitePosition { vertex });
    }
    for (triangle, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= mesh.positions.len()) {
            return Err(SubdivideError::VertexOutOfRange { triangle, vertex, vertex_count: mesh.positions.len() });
        }
    }
    if let Some(&triangle) = marked.iter().find(|&&t| t as usize >= n) {
        return Err(SubdivideError::MarkOutOfRange { triangle, triangle_count: n });
    }
    Ok(())
}

/// Splits the `marked` triangles (indices; duplicates allowed) 4-way and closes the mesh around them; see the
/// module documentation for the scheme, the cross-object decision and the limits.
pub fn subdivide(mesh: &SubdivideMesh<'_>, marked: &[u32], limits: &SplitLimits) -> Result<Subdivided, SubdivideError> {
    validate(mesh, marked, limits)?;
    let n = mesh.triangles.len();
    let canon = weld_exact(mesh.positions);
    let keys: Vec<[EdgeKey; 3]> = mesh
        .triangles
        .iter()
        .map(|t| std::array::from_fn(|i| edge_key(canon[t[i] as usize], canon[t[(i + 1) % 3] as usize])))
        .collect();
    let corners = |t: usize| -> [DVec3; 3] { mesh.triangles[t].map(|v| mesh.positions[v as usize].as_dvec3()) };
    let mut adjacency: HashMap<EdgeKey, Vec<u32>> = HashMap::new();
    for (t, k) in keys.iter().enumerate() {
        for &e in k {
            adjacency.entry(e).or_default().push(t as u32);
        }
    }

    let mut is_marked = vec![false; n];
    for &t in marked {
        is_marked[t as usize] = true;
    }
    // A mark survives only if its own red children respect the limits.
    let mut active: Vec<bool> =
        (0..n).map(|t| is_marked[t] && children_respect([true; 3], corners(t), limits)).collect();

    // Drop marks whose closure would create a too-small neighbour child, until none does.
    let split_of =
        |active: &[bool], t: usize| -> [bool; 3] { keys[t].map(|e| adjacency[&e].iter().any(|&s| active[s as usize])) };
    loop {
        let mut touched: Vec<usize> = (0..n)
            .filter(|&t| active[t])
            .flat_map(|t| keys[t].iter().flat_map(|e| adjacency[e].iter().map(|&s| s as usize)))
            .collect();
        touched.sort_unstable();
        touched.dedup();
        let mut dropped = false;
        for t in touched {
            let split = split_of(&active, t);
            if children_respect(split, corners(t), limits) {
                continue;
            }
            for (i, e) in keys[t].iter().enumerate() {
                if split[i] {
                    for &s in &adjacency[e] {
                        dropped |= std::mem::replace(&mut active[s as usize], false);
                    }
                }
            }
        }
        if !dropped {
            break;
        }
    }

    let mut out = Subdivided {
        positions: mesh.positions.to_vec(),
        triangles: Vec::with_capacity(n),
        object_id: Vec::with_capacity(n),
        parent_of_new_triangle: Vec::with_capacity(n),
        kind: Vec::with_capacity(n),
        refined: Vec::new(),
        refused: Vec::new(),
        closure_cut: Vec::new(),
    };
    let mut midpoint: HashMap<EdgeKey, u32> = HashMap::new();
    for t in 0..n {
        let split = split_of(&active, t);
        let tri = mesh.triangles[t];
        let mut slot = [tri[0], tri[1], tri[2], 0, 0, 0];
        for i in 0..3 {
            if split[i] {
                let next = out.positions.len();
                let m = *midpoint.entry(keys[t][i]).or_insert(next as u32);
                if m as usize == next {
                    if next > u32::MAX as usize {
                        return Err(SubdivideError::TooManyVertices);
                    }
                    // Endpoints in canonical order so both sides would compute the same bits (IEEE addition is
                    // commutative anyway; the vertex is created once and shared).
                    let (a, b) = keys[t][i];
                    out.positions.push(0.5 * (mesh.positions[a as usize] + mesh.positions[b as usize]));
                }
                slot[3 + i] = m;
            }
        }
        let (kind, kids) = children(split, corners(t));
        for c in kids {
            out.triangles.push(c.map(|s| slot[s]));
            out.object_id.push(mesh.object_id[t]);
            out.parent_of_new_triangle.push(t as u32);
        }
        out.kind.push(kind);
        if active[t] {
            out.refined.push(t as u32);
        } else if is_marked[t] {
            out.refused.push(t as u32);
        } else if kind != SplitKind::Unchanged {
            out.closure_cut.push(t as u32);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn child_counts_match_patterns() {
        let c = [DVec3::ZERO, DVec3::X, DVec3::Y];
        for (split, kind) in [
            ([false; 3], SplitKind::Unchanged),
            ([false, true, false], SplitKind::Green),
            ([true, false, true], SplitKind::Blue),
            ([true; 3], SplitKind::Red),
        ] {
            let (k, kids) = children(split, c);
            assert_eq!(k, kind);
            assert_eq!(kids.len(), kind.child_count());
        }
    }

    #[test]
    fn weld_folds_negative_zero() {
        let w = weld_exact(&[Vec3::new(0.0, 1.0, 2.0), Vec3::new(-0.0, 1.0, 2.0), Vec3::ONE]);
        assert_eq!(w, [0, 0, 2]);
    }
}
