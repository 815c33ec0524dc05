//! The split decision (F test of residual structure against noise, Holm-corrected over the triangles tested;
//! contrast; pixel footprint; budget) and the mesh update (subdivision, inherited parameters, midpoint
//! normals). See the module docs of [`crate::triangle`].

use glam::{DVec3, Vec3};

use super::pixels::TriSample;
use super::ratio::Fitted;
use super::significance::{f_survival, holm};
use super::{RoundInputs, TriangleError, TriangleState};
use crate::subdivide::{SplitLimits, SubdivideMesh, Subdivided, subdivide};

/// Upper bound on the triangles one mark adds: 3 from its red split, and at most one per neighbour across
/// its 3 edges from closure (a closure child count grows by 1 per split edge). Used to keep the budget.
const MAX_GROWTH_PER_MARK: usize = 6;

/// Shortest edge a split may create, relative to the mesh's bounding-box diagonal: far below any pixel
/// footprint the F test would accept; it only guards against degenerate splits (subdivide needs a limit > 0).
const MIN_EDGE_RELATIVE: f32 = 1e-6;

/// Colour channels tested per triangle: the per-channel p-values are Bonferroni-combined (× 3), valid whatever
/// the correlation between the channels (their noise comes from the same paths, so it is correlated).
const CHANNELS: f64 = 3.0;

/// A one-way ANOVA: the F statistic and its degrees of freedom (between groups, within groups), with the
/// mean squares and the effective group size behind them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anova {
    pub f: f64,
    /// k − 1 for k non-empty groups.
    pub df_between: usize,
    /// n − k for n values.
    pub df_within: usize,
    /// Σ_g n_g (mean_g − mean)² / (k − 1).
    pub ms_between: f64,
    /// Σ_g Σ (x − mean_g)² / (n − k): the pooled variance of a value about its group's mean.
    pub ms_within: f64,
    /// (n − Σ_g n_g² / n) / (k − 1): the group size that makes `ms_between`'s expectation
    /// `ms_within + n0 · τ²` for groups whose true means spread with variance τ² (n_g for equal groups).
    pub n0: f64,
}

impl Anova {
    /// P(F(df_between, df_within) > f): the probability of an F this large when all groups share one mean
    /// (independent normal values of equal variance).
    #[must_use]
    pub fn p_value(&self) -> f64 {
        f_survival(self.f, self.df_between as f64, self.df_within as f64)
    }

    /// The variance τ² of the groups' true means, by the method of moments of the one-way random-effects
    /// model: (`ms_between` − `ms_within`) / `n0`, at least 0 (a between-group spread no larger than the
    /// values' own noise predicts is no spread).
    #[must_use]
    pub fn between_variance(&self) -> f64 {
        if self.n0 > 0.0 { ((self.ms_between - self.ms_within) / self.n0).max(0.0) } else { 0.0 }
    }
}

/// One-way ANOVA of `groups` (values per group): between-group mean square over within-group mean square,
/// with its degrees of freedom. `None` when fewer than 2 groups are non-empty or there are no within-group
/// degrees of freedom.
#[must_use]
pub fn anova(groups: &[Vec<f64>]) -> Option<Anova> {
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
    let f = if ms_within > 0.0 {
        ms_between / ms_within
    } else if ms_between > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let n0 = (n as f64 - used.iter().map(|g| (g.len() * g.len()) as f64).sum::<f64>() / n as f64) / (k - 1) as f64;
    Some(Anova { f, df_between: k - 1, df_within: n - k, ms_between, ms_within, n0 })
}

/// The ANOVA F statistic of `groups` alone ([`anova`]).
#[must_use]
pub fn anova_f(groups: &[Vec<f64>]) -> Option<f64> {
    anova(groups).map(|a| a.f)
}

/// The evidence for splitting one triangle, from its interior pixels grouped by would-be child.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitEvidence {
    /// ANOVA F of the residuals (max over channels): structure over noise.
    pub f: f64,
    /// The triangle's p-value: the smallest per-channel p-value of the F test (with the channel's degrees of
    /// freedom), times 3 for the 3 channels (Bonferroni), at most 1. Small = the children differ beyond noise.
    pub p: f64,
    /// Interior pixels the test used.
    pub pixels: usize,
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
            let tests: Vec<Anova> = g.iter().filter_map(|ch| anova(ch)).collect();
            let f = tests.iter().map(|a| a.f).reduce(f64::max)?;
            let p_min = tests.iter().map(Anova::p_value).reduce(f64::min)?;
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
            Some(SplitEvidence { f, p: (CHANNELS * p_min).min(1.0), pixels: *tn as usize, contrast })
        })
        .collect()
}

/// The split test's choice in one round.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Marks {
    /// The triangles to split, ascending.
    pub marks: Vec<u32>,
    /// Triangles the test found significant but left unsplit because the mesh would outgrow
    /// `triangle.max_triangles` (all of them when the mesh is already at or above it).
    pub over_budget: usize,
}

/// The triangles to split: those whose children differ significantly after Holm's correction over every
/// triangle tested in the round (family-wise level `split_significance`) and by more than `split_contrast`,
/// smallest p first (then largest F), within the budget; and how many the budget left out.
///
/// `best_view[t]`: triangle t's pixel centres in the view with the most of them (counted before the pixel
/// budget, [`super::pixels::TriPixels::best_view`]).
#[must_use]
pub fn choose(
    inputs: &RoundInputs<'_>,
    state: &TriangleState,
    samples: &[TriSample],
    best_view: &[u32],
    fitted: &Fitted,
) -> Marks {
    let cfg = inputs.settings;
    let n = state.triangles.len();
    let ev = evidence(n, samples, fitted);
    let best = |t: usize| best_view.get(t).copied().unwrap_or(0);
    // Every triangle tested enters the correction, whatever its contrast: the family is the tests made.
    let tested: Vec<(usize, SplitEvidence)> = (0..n)
        .filter(|&t| fitted.free[t] && best(t) >= 4 * cfg.min_pixels.max(1))
        .filter_map(|t| Some((t, ev[t]?)))
        .collect();
    let p: Vec<f64> = tested.iter().map(|(_, e)| e.p).collect();
    let significant = holm(&p, cfg.split_significance);
    let mut marks: Vec<(f64, f64, u32)> = tested
        .iter()
        .zip(&significant)
        .filter_map(|(&(t, e), &sig)| {
            tracing::debug!(
                triangle = t,
                object = state.face_object[t],
                f = e.f,
                p = e.p,
                significant = sig,
                contrast = e.contrast,
                interior_pixels = e.pixels,
                best_view_pixels = best(t),
                "split evidence"
            );
            (sig && e.contrast > cfg.split_contrast).then_some((e.p, e.f, t as u32))
        })
        .collect();
    tracing::debug!(tested = tested.len(), marked = marks.len(), "split test");
    marks.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)).then(a.2.cmp(&b.2)));
    let room = within_budget(cfg.max_triangles as usize, n, marks.len());
    let over_budget = marks.len() - room;
    marks.truncate(room);
    let mut out: Vec<u32> = marks.into_iter().map(|m| m.2).collect();
    out.sort_unstable();
    Marks { marks: out, over_budget }
}

/// How many of `wanted` marks a mesh of `n` triangles can take without outgrowing `max_triangles`, each mark
/// counted at its most growth ([`MAX_GROWTH_PER_MARK`]).
#[must_use]
pub fn within_budget(max_triangles: usize, n: usize, wanted: usize) -> usize {
    (max_triangles.saturating_sub(n) / MAX_GROWTH_PER_MARK).min(wanted)
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
    use crate::streams::uniform;

    #[test]
    fn the_budget_counts_each_mark_at_its_most_growth_and_never_goes_negative() {
        // 1000 triangles of room: 166 marks of at most 6 new triangles each.
        assert_eq!(within_budget(2000, 1000, 500), 166);
        assert_eq!(within_budget(2000, 1000, 10), 10);
        // A mesh already at or above the budget (a scan of 521 362 triangles against 200 000) splits none.
        assert_eq!(within_budget(200_000, 200_000, 7), 0);
        assert_eq!(within_budget(200_000, 521_362, 7), 0);
    }

    /// Seeded standard normal numbers (Box–Muller on [`uniform`]), keyed by (stream, a, b).
    fn normal(stream: u64, a: u64, b: u64) -> f64 {
        let u1 = 1.0 - uniform(7, stream, a, 2 * b); // (0, 1]: ln stays finite
        let u2 = uniform(7, stream, a, 2 * b + 1);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Groups of pure noise with `sizes` values per child.
    fn noise_groups(sizes: &[usize; 4], stream: u64, trial: u64, shift: [f64; 4]) -> Vec<Vec<f64>> {
        let mut k = 0;
        sizes
            .iter()
            .zip(shift)
            .map(|(&n, d)| {
                (0..n)
                    .map(|_| {
                        k += 1;
                        normal(stream, trial, k) + d
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn p_values_of_noise_are_uniform_whatever_the_child_sizes_but_a_fixed_f_threshold_is_not() {
        // Child sizes of the demo's false splits ([2, 1, 0, 5]: F(2, 5); [1, 1, 3, 6]: F(3, 7)) and of a
        // well-seen triangle (F(3, 86)).
        let trials = 40_000u64;
        for (stream, sizes) in [[2, 1, 0, 5], [1, 1, 3, 6], [20, 20, 20, 30]].iter().enumerate() {
            let (mut below_1, mut below_10, mut f_above_10) = (0u32, 0u32, 0u32);
            let mut df = (0, 0);
            for trial in 0..trials {
                let a = anova(&noise_groups(sizes, stream as u64, trial, [0.0; 4])).unwrap();
                df = (a.df_between, a.df_within);
                let p = a.p_value();
                below_1 += u32::from(p < 0.01);
                below_10 += u32::from(p < 0.1);
                f_above_10 += u32::from(a.f > 10.0);
            }
            // Binomial counts: 5 standard deviations around the expectation (a seeded test; a fail means the
            // p-value is miscalibrated, not bad luck, at 5σ).
            let check = |count: u32, rate: f64, what: &str| {
                let (mean, sd) = (rate * trials as f64, (rate * (1.0 - rate) * trials as f64).sqrt());
                assert!((f64::from(count) - mean).abs() < 5.0 * sd + 1.0, "{sizes:?} {what}: {count} vs {mean:.1}");
            };
            check(below_1, 0.01, "p < 0.01");
            check(below_10, 0.1, "p < 0.1");
            // The former rule F > 10 fires at the F distribution's own tail rate: ~1.8 % of uniform triangles
            // with 8 pixels in 3 children, ~0.001 % with 90 pixels.
            let rate = f_survival(10.0, df.0 as f64, df.1 as f64);
            check(f_above_10, rate, "F > 10");
        }
        assert!(f_survival(10.0, 2.0, 5.0) > 0.017 && f_survival(10.0, 3.0, 86.0) < 2e-5);
    }

    #[test]
    fn holm_over_many_uniform_triangles_keeps_them_whole_and_finds_a_real_step() {
        // 600 triangles of pure noise with 3 channels each, sizes cycling through small and large children,
        // plus one whose corner child is 3 σ brighter (a texture edge). The uniform ones are all rejected
        // together with probability ≤ 1 % (α = 0.01; seeded, so this run is fixed).
        let sizes = [[2, 1, 0, 5], [1, 1, 3, 6], [5, 5, 5, 10], [20, 20, 20, 30]];
        let step = 600u64;
        let p: Vec<f64> = (0..=step)
            .map(|t| {
                let shift = if t == step { [3.0, 0.0, 0.0, 0.0] } else { [0.0; 4] };
                let sz = &sizes[if t == step { 3 } else { t as usize % 4 }];
                let min = (0..3)
                    .map(|c| anova(&noise_groups(sz, 10 + c, t, shift)).unwrap().p_value())
                    .fold(1.0f64, f64::min);
                (CHANNELS * min).min(1.0)
            })
            .collect();
        let rejected: Vec<usize> = holm(&p, 0.01).iter().enumerate().filter(|(_, r)| **r).map(|(t, _)| t).collect();
        assert_eq!(rejected, vec![step as usize], "smallest p-values {:?}", {
            let mut q = p.clone();
            q.sort_by(f64::total_cmp);
            q.truncate(3);
            q
        });
    }

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
