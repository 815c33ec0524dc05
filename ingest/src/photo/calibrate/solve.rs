//! Robust weighted least squares with the per-point unknowns eliminated.
//!
//! Every row `j` is one observation of one channel of one scene point, with residual
//! `e_j = y_j + u_j·θ − l_g`, where `θ` are the global unknowns (log gains, vignetting coefficients, response
//! knots), `u_j` a sparse row (at most [`MAX_ENTRIES`] entries) and `l_g` the log radiance of the row's group
//! (point × channel). For fixed `θ` the best `l_g` is the weighted mean of `y_j + u_j·θ` over the group, so the
//! normal equations of `θ` are the Schur complement `Σ_j w_j u_j u_jᵀ − s_g s_gᵀ / W_g` (with `s_g = Σ w_j u_j`,
//! `W_g = Σ w_j`) and the right-hand side likewise: exact block elimination, never an explicit `l`. Soft
//! penalties (smoothness, ridges) are added to the normal matrix; hard linear constraints (the gauges) enter
//! through a KKT system solved by LU.
//!
//! Robustness: iteratively reweighted least squares, Huber weights for the first iterations (convex, so the start does
//! not matter) and Tukey's biweight after (rejects gross outliers — highlights, occlusions — completely), or Huber
//! throughout when the caller asks (a gauge that is not a symmetry of the biweight). The robust weights compare each
//! residual with one scale for all rows (the base-weighted median absolute residual): a low-weight row is not excused a
//! large residual. The base weights say how much a row's noise is amplified (quantisation in a steep part of the
//! curve), not that it may be biased, and rows that are biased — a film's fog floor, which does not move with exposure
//! at all — are exactly the low-weight ones; excusing them lets them drag the curve flat.

use std::ops::Range;

use nalgebra::{DMatrix, DVector};

/// Largest number of global unknowns one row touches: two response knots, one gain, three vignetting terms.
pub(super) const MAX_ENTRIES: usize = 6;

/// One observation of one channel.
#[derive(Debug, Clone, Copy)]
pub(super) struct Row {
    pub y: f64,
    /// Inverse-variance weight of the observation before robust reweighting (positive).
    pub w: f64,
    pub idx: [u32; MAX_ENTRIES],
    pub coef: [f64; MAX_ENTRIES],
    pub len: u8,
}

impl Row {
    pub fn new(y: f64, w: f64) -> Self {
        Self { y, w, idx: [0; MAX_ENTRIES], coef: [0.0; MAX_ENTRIES], len: 0 }
    }

    /// Adds `coef · θ[idx]`; a caller bug (more than [`MAX_ENTRIES`]) panics.
    pub fn push(&mut self, idx: usize, coef: f64) {
        let k = usize::from(self.len);
        self.idx[k] = idx as u32;
        self.coef[k] = coef;
        self.len += 1;
    }

    fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..usize::from(self.len)).map(|k| (self.idx[k] as usize, self.coef[k]))
    }

    fn predict(&self, theta: &[f64]) -> f64 {
        self.y + self.entries().map(|(i, c)| c * theta[i]).sum::<f64>()
    }
}

/// `weight · (Σ coef·θ − target)²` added to the objective.
#[derive(Debug, Clone)]
pub(super) struct Penalty {
    pub entries: Vec<(usize, f64)>,
    pub target: f64,
    pub weight: f64,
}

/// `Σ coef·θ = target`, exactly.
#[derive(Debug, Clone)]
pub(super) struct Constraint {
    pub entries: Vec<(usize, f64)>,
    pub target: f64,
}

/// The problem: rows grouped by point × channel (`groups` are contiguous ranges of `rows`).
#[derive(Debug, Default)]
pub(super) struct Problem {
    pub n_params: usize,
    pub rows: Vec<Row>,
    pub groups: Vec<Range<usize>>,
    pub penalties: Vec<Penalty>,
    pub constraints: Vec<Constraint>,
    /// 0/1 mask of the rows that take part (empty = all): it multiplies the robust weights throughout.
    pub start: Vec<f64>,
    /// Huber iterations before Tukey's (`usize::MAX`: Huber only).
    pub huber_iterations: usize,
}

#[derive(Debug, Clone)]
pub(super) struct Solution {
    pub theta: Vec<f64>,
    /// Final robust weight of every row, in [0, 1].
    pub robust: Vec<f64>,
    /// Residual of every row (log units).
    pub residual: Vec<f64>,
}

/// Huber's tuning constant: 95 % efficiency under Gaussian noise.
const HUBER_K: f64 = 1.345;
/// Tukey's biweight constant: 95 % efficiency under Gaussian noise; residuals beyond 4.685 σ get weight 0.
const TUKEY_C: f64 = 4.685;
/// Huber iterations before switching to Tukey when starting from all rows: enough for the convex Huber fit
/// to settle near the inlier solution, so that the non-convex biweight starts inside the right basin.
pub(super) const HUBER_ITERATIONS: usize = 4;
/// Upper bound on IRLS iterations; the weights stop changing after a handful.
const MAX_ITERATIONS: usize = 16;
/// IRLS stops when no unknown moves by more than this (log units: 1e-7 is a 0.00001 % gain change).
const STEP_TOLERANCE: f64 = 1e-7;
/// Floor of the robust scale (standardised units): noise-free synthetic data would otherwise give σ = 0 and
/// reject every row that is not exact to rounding.
const SIGMA_FLOOR: f64 = 1e-6;
/// MAD → standard deviation for Gaussian noise.
const MAD_TO_SIGMA: f64 = 1.4826;
/// Relative ridge on the normal matrix diagonal: keeps an unknown that no row reaches (its column is zero)
/// solvable at 0 without measurably biasing the others (1e-10 of the mean diagonal).
const RIDGE: f64 = 1e-10;

/// Solves `problem` by IRLS (see the module docs). `None` when the linear system is singular.
pub(super) fn solve(problem: &Problem) -> Option<Solution> {
    let mut robust = if problem.start.is_empty() { vec![1.0; problem.rows.len()] } else { problem.start.clone() };
    let mut theta = vec![0.0; problem.n_params];
    let mut residual = vec![0.0; problem.rows.len()];
    for iteration in 0..MAX_ITERATIONS {
        let next = solve_weighted(problem, &robust)?;
        let step = next.iter().zip(&theta).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        theta = next;
        residuals(problem, &theta, &robust, &mut residual);
        let sigma = robust_scale(problem, &residual);
        let tukey = iteration.saturating_add(1) >= problem.huber_iterations;
        for (r, e) in robust.iter_mut().zip(&residual) {
            let t = if e.is_finite() { (e / sigma).abs() } else { 0.0 };
            *r = if tukey {
                if t < TUKEY_C { (1.0 - (t / TUKEY_C).powi(2)).powi(2) } else { 0.0 }
            } else if t <= HUBER_K {
                1.0
            } else {
                HUBER_K / t
            };
        }
        if !problem.start.is_empty() {
            for (r, s) in robust.iter_mut().zip(&problem.start) {
                *r *= s;
            }
        }
        let settled = !tukey || iteration >= problem.huber_iterations;
        if settled && iteration > 0 && step < STEP_TOLERANCE {
            break;
        }
    }
    residuals(problem, &theta, &robust, &mut residual);
    Some(Solution { theta, robust, residual })
}

/// Leave-one-out residuals for `theta`: each row against the weighted mean log radiance of the *other* rows
/// of its group (their plain mean when all of them are rejected; NaN for a row alone in its group). Ordinary
/// residuals shrink as a group loses rows — to exactly 0 for the last one kept — so a robust scale computed
/// from them falls as rows are rejected, which rejects more rows: a collapse onto a few self-consistent rows.
/// Leave-one-out residuals do not shrink.
fn residuals(problem: &Problem, theta: &[f64], robust: &[f64], out: &mut [f64]) {
    for g in &problem.groups {
        let (mut sw, mut swp, mut sp) = (0.0, 0.0, 0.0);
        for j in g.clone() {
            let w = problem.rows[j].w * robust[j];
            let p = problem.rows[j].predict(theta);
            sw += w;
            swp += w * p;
            sp += p;
        }
        let n = g.len() as f64;
        for j in g.clone() {
            let w = problem.rows[j].w * robust[j];
            let p = problem.rows[j].predict(theta);
            // A relative threshold: below 1e-9 of the group's weight, the others hold no weight.
            out[j] = if sw - w > 1e-9 * sw {
                p - (swp - w * p) / (sw - w)
            } else if n > 1.0 {
                p - (sp - p) / (n - 1.0)
            } else {
                f64::NAN
            };
        }
    }
}

/// Scale of the residuals: the base-weighted median of their absolute (leave-one-out) values, × 1.4826. Weighting by
/// the base weight lets the rows the model trusts set the scale even when many low-weight rows (a film toe, say) are
/// far off.
fn robust_scale(problem: &Problem, residual: &[f64]) -> f64 {
    let mut abs: Vec<(f64, f64)> = problem
        .groups
        .iter()
        .flat_map(|g| g.clone())
        .filter(|&j| residual[j].is_finite())
        .map(|j| (residual[j].abs(), problem.rows[j].w))
        .collect();
    let total: f64 = abs.iter().map(|a| a.1).sum();
    if abs.is_empty() || total <= 0.0 {
        return 1.0;
    }
    abs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut acc = 0.0;
    let median = abs.iter().find(|a| {
        acc += a.1;
        acc >= 0.5 * total
    });
    (MAD_TO_SIGMA * median.map_or(0.0, |a| a.0)).max(SIGMA_FLOOR)
}

/// One weighted least-squares solve with the group unknowns eliminated.
pub(super) fn solve_weighted(problem: &Problem, robust: &[f64]) -> Option<Vec<f64>> {
    let n = problem.n_params;
    let mut normal = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    // Dense scratch for s_g with the list of touched entries, so each group costs O(touched²).
    let mut s = vec![0.0; n];
    let mut touched: Vec<usize> = Vec::new();
    for g in &problem.groups {
        let (mut sw, mut swy) = (0.0, 0.0);
        for j in g.clone() {
            let row = &problem.rows[j];
            let w = row.w * robust[j];
            if w <= 0.0 {
                continue;
            }
            sw += w;
            swy += w * row.y;
            for (a, ca) in row.entries() {
                if s[a] == 0.0 && !touched.contains(&a) {
                    touched.push(a);
                }
                s[a] += w * ca;
                rhs[a] -= w * ca * row.y;
                for (b, cb) in row.entries() {
                    normal[(a, b)] += w * ca * cb;
                }
            }
        }
        if sw > 0.0 {
            for &a in &touched {
                rhs[a] += s[a] * swy / sw;
                for &b in &touched {
                    normal[(a, b)] -= s[a] * s[b] / sw;
                }
            }
        }
        for &a in &touched {
            s[a] = 0.0;
        }
        touched.clear();
    }
    for p in &problem.penalties {
        for &(a, ca) in &p.entries {
            rhs[a] += p.weight * ca * p.target;
            for &(b, cb) in &p.entries {
                normal[(a, b)] += p.weight * ca * cb;
            }
        }
    }
    let mean_diag = (0..n).map(|i| normal[(i, i)].abs()).sum::<f64>() / n.max(1) as f64;
    let ridge = RIDGE * mean_diag.max(f64::MIN_POSITIVE);
    for i in 0..n {
        normal[(i, i)] += ridge;
    }
    let m = problem.constraints.len();
    let mut kkt = DMatrix::<f64>::zeros(n + m, n + m);
    kkt.view_mut((0, 0), (n, n)).copy_from(&normal);
    let mut b = DVector::<f64>::zeros(n + m);
    b.rows_mut(0, n).copy_from(&rhs);
    // Constraint rows scaled to the normal matrix's magnitude keep the KKT system well balanced for LU.
    let scale = mean_diag.max(1.0);
    for (k, c) in problem.constraints.iter().enumerate() {
        for &(a, ca) in &c.entries {
            kkt[(n + k, a)] += scale * ca;
            kkt[(a, n + k)] += scale * ca;
        }
        b[n + k] = scale * c.target;
    }
    let x = kkt.lu().solve(&b)?;
    let theta: Vec<f64> = x.rows(0, n).iter().copied().collect();
    theta.iter().all(|v| v.is_finite()).then_some(theta)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two "photos" with log gains θ0, θ1 seeing 50 points; θ0 + θ1 = 0 fixed by a constraint.
    fn two_photo_problem(outlier: bool) -> Problem {
        let truth = [0.3, -0.3];
        let mut p = Problem { n_params: 2, huber_iterations: HUBER_ITERATIONS, ..Problem::default() };
        for i in 0..50 {
            let l = f64::from(i) * 0.1;
            let start = p.rows.len();
            for (k, g) in truth.iter().enumerate() {
                // Model y = g + l, residual e = y − θ_k − l.
                let bad = outlier && i % 10 == 3 && k == 0;
                let mut row = Row::new(g + l + if bad { 2.0 } else { 0.0 }, 1.0);
                row.push(k, -1.0);
                p.rows.push(row);
            }
            p.groups.push(start..p.rows.len());
        }
        p.constraints.push(Constraint { entries: vec![(0, 1.0), (1, 1.0)], target: 0.0 });
        p
    }

    #[test]
    fn exact_data_recovers_the_gains() {
        let s = solve(&two_photo_problem(false)).unwrap();
        assert!((s.theta[0] - 0.3).abs() < 1e-9 && (s.theta[1] + 0.3).abs() < 1e-9, "{:?}", s.theta);
    }

    #[test]
    fn gross_outliers_are_rejected() {
        let s = solve(&two_photo_problem(true)).unwrap();
        assert!((s.theta[0] - 0.3).abs() < 1e-6, "{:?}", s.theta);
        let rejected = s.robust.iter().filter(|&&r| r == 0.0).count();
        assert!(rejected >= 10, "{rejected}");
    }
}
