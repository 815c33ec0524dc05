//! The split decision (F test of residual structure against noise, pixel footprint, budget) and the mesh
//! update (subdivision, inherited parameters, midpoint normals). See the module docs of [`crate::triangle`].

use glam::{DVec3, Vec3};

use super::fit::Fitted;
use super::pixels::TriSample;
use super::{RoundInputs, TriangleError, TriangleState};
use crate::subdivide::{SplitLimits, SubdivideMesh, Subdivided, subdivide};

/// Upper bound on the triangles one mark adds: 3 from its red split, and at most one per neighbour across
/// its 3 edges from closure (a closure child count grows by 1 per split edge). Used to keep the budget.
const MAX_GROWTH_PER_MARK: usize = 6;

/// Shortest edge a split may create, relative to the mesh's bounding-box diagonal: far below any pixel
/// footprint the F test would accept; it only guards against degenerate splits (subdivide needs a limit > 0).
const MIN_EDGE_RELATIVE: f32 = 1e-6;

/// One-way ANOVA F statistic of `groups` (values per group): between-group mean square over within-group mean
/// square. `None` when fewer than 2 groups are non-empty or there are no within-group degrees of freedom.
#[must_use]
pub fn anova_f(groups: &[Vec<f64>]) -> Option<f64> {
    let used: Vec<&Vec<f64>> = groups.iter().filter(|g| !g.is_empty()).collect();
    let k = used.len();
    let n: usize = used.iter().map(|g| g.len()).sum();
    if k < 2 || n <= k {
        return None;
    }
    let mean = used.iter().flat_map(|g| g.iter()).sum::<f64>() / n as f64;
    let mut between = 0.0;
    let mut within = 0.0;
    for g in &used {
        let m = g.iter().sum::<f64>() / g.len() as f64;
        between += g.len() as f64 * (m - mean) * (m - mean);
        within += g.iter().map(|x| (x - m) * (x - m)).sum::<f64>();
    }
    let ms_between = between / (k - 1) as f64;
    let ms_within = within / (n - k) as f64;
    if ms_within > 0.0 {
        Some(ms_between / ms_within)
    } else if ms_between > 0.0 {
        Some(f64::INFINITY)
    } else {
        Some(0.0)
    }
}

/// The evidence for splitting one triangle, from its interior pixels grouped by would-be child.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitEvidence {
    /// ANOVA F of the residuals (max over channels): structure over noise.
    pub f: f64,
    /// Largest |mean residual of a child − mean residual of the triangle| / mean photo radiance of the triangle
    /// (max over channels): the relative albedo difference between the children that the split would resolve.
    pub contrast: f64,
}

/// Per triangle: its [`SplitEvidence`], or `None` when untestable (fewer than two children with pixels).
#[must_use]
pub fn evidence(triangles: usize, samples: &[TriSample], fitted: &Fitted) -> Vec<Option<SplitEvidence>> {
    let mut groups: Vec<[[Vec<f64>; 4]; 3]> = vec![Default::default(); triangles];
    let mut target = vec![(glam::DVec3::ZERO, 0.0f64); triangles];
    for (s, r) in samples.iter().zip(&fitted.residual) {
        if s.interior {
            for c in 0..3 {
                groups[s.tri as usize][c][s.child as usize].push(f64::from(r[c]));
            }
            target[s.tri as usize].0 += s.target.as_dvec3();
            target[s.tri as usize].1 += 1.0;
        }
    }
    groups
        .iter()
        .zip(&target)
        .map(|(g, (tsum, tn))| {
            let f = g.iter().filter_map(|ch| anova_f(ch)).reduce(f64::max)?;
            let mut contrast = 0.0f64;
            for (c, ch) in g.iter().enumerate() {
                let level = tsum[c] / tn.max(1.0);
                // Children are compared with the triangle's own mean residual: a residual offset shared by the
                // whole triangle (e.g. after its value was pulled to the object's) is no reason to split it.
                let (sum, count) = ch.iter().fold((0.0, 0usize), |(s, n), x| (s + x.iter().sum::<f64>(), n + x.len()));
                let whole = sum / count.max(1) as f64;
                for child in ch.iter().filter(|x| !x.is_empty()) {
                    let m = child.iter().sum::<f64>() / child.len() as f64;
                    if level > 0.0 {
                        contrast = contrast.max((m - whole).abs() / level);
                    }
                }
            }
            Some(SplitEvidence { f, contrast })
        })
        .collect()
}

/// The triangles to split, highest F first, within the budget.
#[must_use]
pub fn choose(inputs: &RoundInputs<'_>, state: &TriangleState, samples: &[TriSample], fitted: &Fitted) -> Vec<u32> {
    let cfg = inputs.config;
    let n = state.triangles.len();
    let ev = evidence(n, samples, fitted);
    // Pixel centres per (triangle, view); the best view is the one with the most.
    let views = inputs.cameras.len();
    let mut per_view = vec![0u32; n * views.max(1)];
    for s in samples {
        per_view[s.tri as usize * views + s.pixel.view as usize] += 1;
    }
    let best = |t: usize| per_view[t * views..(t + 1) * views].iter().copied().max().unwrap_or(0);
    let mut marks: Vec<(f64, u32)> = (0..n)
        .filter(|&t| fitted.free[t] && best(t) >= 4 * cfg.min_pixels.max(1))
        .filter_map(|t| {
            let e = ev[t]?;
            tracing::debug!(
                triangle = t,
                object = state.face_object[t],
                f = e.f,
                contrast = e.contrast,
                best_view_pixels = best(t),
                "split evidence"
            );
            (e.f > cfg.split_threshold && e.contrast > cfg.split_contrast).then_some((e.f, t as u32))
        })
        .collect();
    marks.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let room = (cfg.max_triangles as usize).saturating_sub(n) / MAX_GROWTH_PER_MARK;
    marks.truncate(room);
    let mut out: Vec<u32> = marks.into_iter().map(|m| m.1).collect();
    out.sort_unstable();
    out
}

/// Splits the marked triangles of `state`: new mesh, parameters inherited from the parents, midpoint normals
/// the normalised mean of their edge's end normals.
pub fn apply(state: &mut TriangleState, marks: &[u32]) -> Result<Subdivided, TriangleError> {
    let object_id: Vec<i32> = state.face_object.iter().map(|&o| o as i32).collect();
    let (lo, hi) =
        state.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    let diag = (hi - lo).length();
    let limits = SplitLimits { min_edge_length: (MIN_EDGE_RELATIVE * diag).max(f32::MIN_POSITIVE), min_area: 0.0 };
    let mesh = SubdivideMesh { positions: &state.positions, triangles: &state.triangles, object_id: &object_id };
    let sub = subdivide(&mesh, marks, &limits)?;
    let old_n = state.positions.len();
    if let Some(normals) = &state.normals {
        let mut out = normals.clone();
        out.resize(sub.positions.len(), Vec3::ZERO);
        let mut done = vec![false; sub.positions.len() - old_n];
        for (t, tri) in sub.triangles.iter().enumerate() {
            let parent = state.triangles[sub.parent_of_new_triangle[t] as usize];
            for &v in tri {
                let v = v as usize;
                if v < old_n || done[v - old_n] {
                    continue;
                }
                // The midpoint of the parent's edge nearest to the new vertex (it lies exactly on one).
                let p = sub.positions[v].as_dvec3();
                let (a, b) = (0..3)
                    .map(|e| (parent[e] as usize, parent[(e + 1) % 3] as usize))
                    .min_by(|x, y| {
                        let d = |(i, j): (usize, usize)| {
                            ((state.positions[i].as_dvec3() + state.positions[j].as_dvec3()) * 0.5 - p).length_squared()
                        };
                        d(*x).total_cmp(&d(*y))
                    })
                    .unwrap_or((parent[0] as usize, parent[1] as usize));
                let nrm: DVec3 = normals[a].as_dvec3() + normals[b].as_dvec3();
                out[v] = nrm.normalize_or(normals[a].as_dvec3()).as_vec3();
                done[v - old_n] = true;
            }
        }
        state.normals = Some(out);
    }
    state.materials = sub.inherit(&state.materials)?;
    state.face_object = sub.inherit(&state.face_object)?;
    state.positions = sub.positions.clone();
    state.triangles = sub.triangles.clone();
    Ok(sub)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_is_large_for_a_step_and_near_one_for_noise() {
        // Two groups with different means and small noise.
        let step = [vec![0.0, 0.01, -0.01, 0.0], vec![1.0, 1.01, 0.99, 1.0]];
        assert!(anova_f(&step).unwrap() > 1000.0);
        // Deterministic "noise": same spread, same means.
        let noise = [vec![-1.0, 1.0, 0.5, -0.5], vec![0.5, -0.5, 1.0, -1.0]];
        assert_eq!(anova_f(&noise), Some(0.0));
        assert_eq!(anova_f(&[vec![1.0], vec![]]), None);
    }
}
