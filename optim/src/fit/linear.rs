//! Small linear solves used by the fit: a symmetric positive definite system by Cholesky ([`solve_spd`]), a
//! box-constrained quadratic by projected coordinate descent, and an
//! L1, per-group Huber or L2 data fit (with optional row weights) with per-variable linear penalties, box
//! bounds and a proximal (Levenberg–Marquardt) term, by iteratively reweighted least squares (IRLS).

/// Which data term [`solve`] minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DataLoss {
    /// (1/M) Σ_j |r_j| — the paper's loss (Eq. 3).
    L1,
    /// (1/M) Σ_j r_j² / 2.
    L2,
    /// (1/M) Σ_j H_g(r_j): Huber's loss in the units of L1 (r²/(2δ_g) within the corner δ_g, |r| − δ_g/2
    /// beyond), with one corner per group of rows ([`Problem::groups`], an object's pixels), δ_g = the
    /// interquartile range of the group's current residuals. For Gaussian residuals that is 1.349 σ, Huber's
    /// classic c = 1.345 (95 % of least squares' efficiency, residuals beyond ~2σ weighed as in L1); for an
    /// object whose residuals have two modes (a textured object fitted with one colour) the range spans both,
    /// so the object's fit is the mean of its pixels — where L1's minimum is flat anywhere between the modes.
    GroupHuber,
}

/// Minimise `(1/M) Σ_j w_j ρ(t_j − Σ_i cols[i][j] x_i) + Σ_i penalty_i x_i + ½ Σ_i prox_i (x_i − anchor_i)²`
/// subject to `lo ≤ x ≤ hi`, where ρ is the data loss and w_j the row weights (1 when none are given).
/// `cols` holds one column (M values) per variable.
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    pub cols: &'a [Vec<f64>],
    pub target: &'a [f64],
    /// A second, independent estimate of the columns and the target (instrumental variables). When given,
    /// the normal equations use the cross products ½(C₁ᵀWC₂ + C₂ᵀWC₁) and ½(C₁ᵀWt₂ + C₂ᵀWt₁), whose
    /// expectations are those of the noise-free columns: a least-squares fit on noisy Monte Carlo columns is
    /// otherwise biased towards zero (errors in variables; measured −4.7 % on the hidden light at 32 paths).
    pub second: Option<(&'a [Vec<f64>], &'a [f64])>,
    /// Per-row weights w_j (M values, mean 1 by convention), e.g. the inverse inclusion probabilities of a
    /// stratified draw ([`super::pixels::draw_stratified`]), so that the data term stays an unbiased estimate
    /// of the mean loss over the population the rows were drawn from. `None`: every row weighs 1.
    pub weights: Option<&'a [f64]>,
    /// Group of each row for [`DataLoss::GroupHuber`] (M values); `None`: one group.
    pub groups: Option<&'a [u32]>,
    pub penalty: &'a [f64],
    pub prox: &'a [f64],
    pub anchor: &'a [f64],
    pub lo: &'a [f64],
    pub hi: &'a [f64],
}

/// The lower Cholesky factor L (row-major n×n, A = LLᵀ) of a symmetric positive definite `a`. `None` when a
/// pivot falls to 1e-12 of the largest diagonal entry or below: `a` is singular to double precision (e.g.
/// normal equations of samples that do not span the model).
fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    if a.len() != n * n {
        return None;
    }
    let scale = (0..n).map(|i| a[i * n + i]).fold(0.0f64, f64::max);
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s = a[i * n + j] - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            if i == j {
                if s <= 1e-12 * scale {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// y = L⁻¹ b for the lower triangular factor `l` (row-major n×n).
fn forward_substitute(l: &[f64], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|k| l[i * n + k] * y[k]).sum::<f64>()) / l[i * n + i];
    }
    y
}

/// x = L⁻ᵀ y for the lower triangular factor `l` (row-major n×n).
fn back_substitute(l: &[f64], y: &[f64]) -> Vec<f64> {
    let n = y.len();
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        x[i] = (y[i] - (i + 1..n).map(|k| l[k * n + i] * x[k]).sum::<f64>()) / l[i * n + i];
    }
    x
}

/// Solves `a x = b` for a symmetric positive definite `a` (row-major n×n) by Cholesky. `None` when `a` is
/// singular to double precision (`cholesky`), and the caller falls back to a smaller model.
#[must_use]
pub fn solve_spd(a: &[f64], b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    let l = cholesky(a, n)?;
    let x = back_substitute(&l, &forward_substitute(&l, b));
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The diagonal entries `wanted` of the sandwich A⁻¹BA⁻¹ for a symmetric positive definite `a` (the bread) and
/// a symmetric `b` (the meat), both row-major n×n: (A⁻¹BA⁻¹)_kk = u_kᵀ B u_k with u_k = A⁻¹e_k, one
/// factorisation of A. `None` when `a` is singular to double precision. The variances of a few parameters of a
/// weighted least-squares fit whose weights are not the rows' precisions (sampling weights), with B = Σ w²σ²
/// J Jᵀ the rows' weighted noise.
#[must_use]
pub fn sandwich_diagonal(a: &[f64], b: &[f64], n: usize, wanted: &[usize]) -> Option<Vec<f64>> {
    let l = cholesky(a, n)?;
    let out: Vec<f64> = wanted
        .iter()
        .map(|&k| {
            let mut e = vec![0.0; n];
            e[k] = 1.0;
            let u = back_substitute(&l, &forward_substitute(&l, &e));
            (0..n).map(|p| u[p] * (0..n).map(|q| b[p * n + q] * u[q]).sum::<f64>()).sum()
        })
        .collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Minimises ½ xᵀAx − bᵀx over the box by cyclic exact coordinate minimisation with projection. A is
/// symmetric positive semi-definite, row-major n×n; coordinates with A_ii = 0 are left unchanged.
pub fn box_qp(a: &[f64], b: &[f64], lo: &[f64], hi: &[f64], x: &mut [f64], sweeps: usize) {
    let n = b.len();
    for _ in 0..sweeps {
        let mut max_change: f64 = 0.0;
        for i in 0..n {
            let aii = a[i * n + i];
            if aii <= 0.0 {
                continue;
            }
            let ax = dot(&a[i * n..(i + 1) * n], x);
            let new = (x[i] - (ax - b[i]) / aii).clamp(lo[i], hi[i]);
            max_change = max_change.max((new - x[i]).abs() * aii.sqrt());
            x[i] = new;
        }
        // Converged when no coordinate moves by more than 1e-12 in the metric of A (well below f32 precision
        // of the tracer's parameters).
        if max_change < 1e-12 {
            break;
        }
    }
}

/// Σ aᵢbᵢ over the common length, in eight partial sums (lane i mod 8) added pairwise at the end: the
/// additions of one running sum wait on each other, those of eight lanes do not, and the compiler vectorises
/// them. The order is fixed, so the result is the same on every CPU (no fused multiply-add is formed).
#[must_use]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let len = a.len().min(b.len());
    let (a, b) = (&a[..len], &b[..len]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    (((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))) + tail
}

/// A weighted L1 fit of `x` (starting there) within the box [`lo`, `hi`], nothing else: [`solve`] of a
/// [`Problem`] without penalties, proximal terms or a second estimate.
pub fn solve_box_l1(
    cols: &[Vec<f64>],
    target: &[f64],
    weights: Option<&[f64]>,
    (lo, hi): (&[f64], &[f64]),
    x: &mut [f64],
    irls_iters: usize,
) {
    let zeros = vec![0.0; cols.len()];
    let problem = Problem {
        cols,
        target,
        second: None,
        weights,
        groups: None,
        penalty: &zeros,
        prox: &zeros,
        anchor: &zeros,
        lo,
        hi,
    };
    solve(&problem, DataLoss::L1, x, irls_iters);
}

/// Solves a [`Problem`] starting from `x`; L1 and Huber by `irls_iters` reweighting rounds.
pub fn solve(p: &Problem<'_>, loss: DataLoss, x: &mut [f64], irls_iters: usize) {
    let n = p.cols.len();
    let m = p.target.len();
    if n == 0 || m == 0 {
        return;
    }
    let row_weight = |j: usize| p.weights.map_or(1.0, |w| w[j]);
    let floor = corner_floor((0..m).map(|j| row_weight(j) * p.target[j].abs()).sum::<f64>() / m as f64);
    let rounds = if loss == DataLoss::L2 { 1 } else { irls_iters.max(1) };
    let (cols2, target2) = p.second.unwrap_or((p.cols, p.target));
    // The variables the box leaves free: one fixed at 0 (an emission pinned off) stays there and adds nothing.
    let active: Vec<usize> = (0..n).filter(|&i| !(p.lo[i] == 0.0 && p.hi[i] == 0.0 && x[i] == 0.0)).collect();
    let na = active.len();
    // Each row's non-zero entries among them (sparse rows: an object's columns vanish on most pixels of a
    // large scan). The normal equations are summed row by row over these only, which adds exactly the terms
    // the dense sums add (the others are 0) in the same order, at Σ_j nnz_j² instead of n²·m per round:
    // a 213-object house spent 60 % of its Gauss–Newton steps in the dense sums.
    let mut row_start = Vec::with_capacity(m + 1);
    let mut entries: Vec<(usize, f64, f64)> = Vec::new();
    for j in 0..m {
        row_start.push(entries.len());
        for (ai, &i) in active.iter().enumerate() {
            let (c, d) = (p.cols[i][j], cols2[i][j]);
            if c != 0.0 || d != 0.0 {
                entries.push((ai, c, d));
            }
        }
    }
    row_start.push(entries.len());
    let mut w: Vec<f64> = (0..m).map(row_weight).collect();
    let mut a = vec![0.0; na * na];
    let mut b = vec![0.0; na];
    let lo: Vec<f64> = active.iter().map(|&i| p.lo[i]).collect();
    let hi: Vec<f64> = active.iter().map(|&i| p.hi[i]).collect();
    let mut xa: Vec<f64> = active.iter().map(|&i| x[i]).collect();
    for _ in 0..rounds {
        if loss != DataLoss::L2 {
            // Over the row's non-zero entries: the terms left out are 0 (a zero entry, or a variable held at 0),
            // and the rest are added in the same order as over all n.
            let r: Vec<f64> = (0..m)
                .map(|j| {
                    let row = &entries[row_start[j]..row_start[j + 1]];
                    let pred: f64 = row.iter().map(|&(ii, c, d)| 0.5 * (c + d) * x[active[ii]]).sum();
                    0.5 * (p.target[j] + target2[j]) - pred
                })
                .collect();
            let corner = if loss == DataLoss::GroupHuber { group_corners(&r, p.groups, floor) } else { vec![floor; m] };
            for j in 0..m {
                // |r| ≈ r² / (2|r_old|) + const: weight 1/|r_old| on the squared residual of ½ r² (within the
                // corner the loss is quadratic: weight 1/corner).
                w[j] = row_weight(j) / r[j].abs().max(corner[j]);
            }
        }
        a.iter_mut().for_each(|v| *v = 0.0);
        b.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..m {
            let row = &entries[row_start[j]..row_start[j + 1]];
            for (e, &(ii, ci, di)) in row.iter().enumerate() {
                b[ii] += 0.5 * w[j] * (ci * target2[j] + di * p.target[j]);
                for &(kk, ck, dk) in &row[e..] {
                    a[ii * na + kk] += 0.5 * w[j] * (ci * dk + di * ck);
                }
            }
        }
        for ii in 0..na {
            let i = active[ii];
            b[ii] = b[ii] / m as f64 - p.penalty[i] + p.prox[i] * p.anchor[i];
            for kk in ii..na {
                let v = a[ii * na + kk] / m as f64;
                a[ii * na + kk] = v;
                a[kk * na + ii] = v;
            }
            a[ii * na + ii] += p.prox[i];
        }
        box_qp(&a, &b, &lo, &hi, &mut xa, 20_000);
        for (ii, &i) in active.iter().enumerate() {
            x[i] = xa[ii];
        }
    }
}

/// The smallest corner of the IRLS weights (L1 and Huber) for a data term whose weighted mean |target| is
/// `mean_abs_target`: residuals below 1 % of it are weighted as if they were that size (a Huber corner), which
/// keeps the weights bounded when a residual vanishes and is far below the 5–10 % noise of a pixel estimated
/// with tens of paths.
#[must_use]
pub fn corner_floor(mean_abs_target: f64) -> f64 {
    (0.01 * mean_abs_target).max(f64::MIN_POSITIVE)
}

/// Huber's loss of residual `r` with corner `delta`, in the units of L1 ([`DataLoss::GroupHuber`]):
/// r²/(2δ) within the corner, |r| − δ/2 beyond.
#[must_use]
pub fn huber(r: f64, delta: f64) -> f64 {
    let a = r.abs();
    if a <= delta { r * r / (2.0 * delta) } else { a - 0.5 * delta }
}

/// Per row, the Huber corner of its group ([`DataLoss::GroupHuber`]): the interquartile range of the group's
/// residuals, at least `floor`. A group of fewer than 4 rows has no quartiles and keeps `floor` (L1).
pub fn group_corners(r: &[f64], groups: Option<&[u32]>, floor: f64) -> Vec<f64> {
    let group = |j: usize| groups.map_or(0, |g| g[j]);
    let mut members: std::collections::BTreeMap<u32, Vec<f64>> = std::collections::BTreeMap::new();
    for (j, v) in r.iter().enumerate() {
        members.entry(group(j)).or_default().push(*v);
    }
    let corners: std::collections::BTreeMap<u32, f64> = members
        .into_iter()
        .map(|(g, mut v)| {
            if v.len() < 4 {
                return (g, floor);
            }
            v.sort_by(f64::total_cmp);
            let q = |f: f64| v[((f * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
            (g, (q(0.75) - q(0.25)).max(floor))
        })
        .collect();
    (0..r.len()).map(|j| corners[&group(j)]).collect()
}

/// Mean and t-statistic of paired differences.
#[must_use]
pub fn paired_t(d: &[f64]) -> (f64, f64) {
    if d.len() < 2 {
        return (d.first().copied().unwrap_or(0.0), 0.0);
    }
    let (mean, se) = mean_se(d);
    (mean, t_statistic(mean, se))
}

/// `mean / se`, with a zero standard error giving +∞ for a positive mean (every difference equal and
/// positive) and 0 otherwise (no evidence).
#[must_use]
pub fn t_statistic(mean: f64, se: f64) -> f64 {
    if se > 0.0 {
        mean / se
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// Mean and t-statistic of the population mean of `d` from two strata sampled at different rates: rows with
/// `in_a[j]` stand for `w_a` of the population each, the others for `w_b` (the weights sum to 1 over the
/// rows). Var = Σ_h W_h² s_h² / n_h with W_h = n_h·w_h the stratum's share.
#[must_use]
pub fn stratified_t(d: &[f64], in_a: &[bool], w_a: f64, w_b: f64) -> (f64, f64) {
    let (mean, se) = stratified_mean_se(d, in_a, w_a, w_b);
    (mean, t_statistic(mean, se))
}

/// [`stratified_t`]'s mean and its standard error.
#[must_use]
pub fn stratified_mean_se(d: &[f64], in_a: &[bool], w_a: f64, w_b: f64) -> (f64, f64) {
    let mut mean = 0.0;
    let mut var = 0.0;
    for (flag, w) in [(true, w_a), (false, w_b)] {
        let x: Vec<f64> = d.iter().zip(in_a).filter(|(_, a)| **a == flag).map(|(v, _)| *v).collect();
        if x.is_empty() {
            continue;
        }
        let n = x.len() as f64;
        let share = w * n;
        let m = x.iter().sum::<f64>() / n;
        mean += share * m;
        if x.len() > 1 {
            let s2 = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
            var += share * share * s2 / n;
        }
    }
    (mean, var.sqrt())
}

/// The root of an unbiased mean square (a mean of products of two independent residuals): 0 where noise leaves
/// the estimate negative.
#[must_use]
pub fn root_mean_square(mean_square: f64) -> f64 {
    mean_square.max(0.0).sqrt()
}

/// Mean and standard error of the mean of `d` (the paired test's; 0 for fewer than 2 values).
#[must_use]
pub fn mean_se(d: &[f64]) -> (f64, f64) {
    let n = d.len() as f64;
    if d.len() < 2 {
        return (d.first().copied().unwrap_or(0.0), 0.0);
    }
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The median of `v` (reordered; NaN sorts last): the mean of the two middle values for an even count, 0 for
/// none.
#[must_use]
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solve_spd_solves_and_refuses_a_singular_system() {
        // A = [[4,2,0],[2,5,1],[0,1,3]], x = (1, −2, 3) → b = A x.
        let a = [4.0, 2.0, 0.0, 2.0, 5.0, 1.0, 0.0, 1.0, 3.0];
        let x = [1.0, -2.0, 3.0];
        let b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum()).collect();
        let got = solve_spd(&a, &b).unwrap();
        for (g, w) in got.iter().zip(x) {
            assert!((g - w).abs() < 1e-12, "{got:?}");
        }
        // Rank 1: the second row is twice the first.
        assert!(solve_spd(&[1.0, 2.0, 2.0, 4.0], &[1.0, 2.0]).is_none());
        assert!(solve_spd(&[1.0, 0.0, 0.0], &[1.0, 2.0]).is_none());
    }

    #[test]
    fn the_sandwich_diagonal_matches_its_definition() {
        // A = [[4, 2, 0], [2, 3, 1], [0, 1, 2]]: det 12, A⁻¹ diagonal (5, 8, 8) / 12. With the meat equal to
        // the bread the sandwich A⁻¹AA⁻¹ is A⁻¹.
        let a = [4.0, 2.0, 0.0, 2.0, 3.0, 1.0, 0.0, 1.0, 2.0];
        let d = sandwich_diagonal(&a, &a, 3, &[0, 1, 2]).unwrap();
        for (got, want) in d.iter().zip([5.0 / 12.0, 8.0 / 12.0, 8.0 / 12.0]) {
            assert!((got - want).abs() < 1e-12, "{d:?}");
        }
        assert!(sandwich_diagonal(&[1.0, 2.0, 2.0, 4.0], &[1.0, 0.0, 0.0, 1.0], 2, &[0]).is_none());
        // Weighted least squares of one mean: rows x_j = θ + e_j, Var e_j = 1, weights w_j. The estimate
        // Σw x / Σw has variance Σw² / (Σw)², whatever the weights; A⁻¹ alone (1/Σw) is right only for w = 1.
        let w = [0.1, 1.0, 4.0];
        let (sw, sw2): (f64, f64) = (w.iter().sum(), w.iter().map(|v| v * v).sum());
        let v = sandwich_diagonal(&[sw], &[sw2], 1, &[0]).unwrap()[0];
        assert!((v - sw2 / (sw * sw)).abs() < 1e-15);
    }

    #[test]
    fn dot_sums_every_product_whatever_the_length() {
        for len in [0, 1, 7, 8, 9, 16, 23, 426] {
            let a: Vec<f64> = (0..len).map(|i| 1.0 + i as f64).collect();
            let b: Vec<f64> = (0..len).map(|i| if i % 2 == 0 { 0.5 } else { -0.25 }).collect();
            let expect: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            // Small integers and halves: every partial sum is exact, so any order gives the same value.
            assert_eq!(dot(&a, &b), expect, "length {len}");
        }
        assert_eq!(dot(&[1.0, 2.0, 3.0], &[1.0, 1.0]), 3.0);
    }

    #[test]
    fn box_qp_matches_the_unconstrained_solution_and_clamps() {
        // A = [[2,1],[1,2]], b = [1,1] → x = (1/3, 1/3); with x1 ≤ 0.1 → x1 = 0.1, x0 = (1 − 0.1)/2.
        let a = [2.0, 1.0, 1.0, 2.0];
        let mut x = [0.0, 0.0];
        box_qp(&a, &[1.0, 1.0], &[-10.0; 2], &[10.0; 2], &mut x, 1000);
        assert!((x[0] - 1.0 / 3.0).abs() < 1e-9 && (x[1] - 1.0 / 3.0).abs() < 1e-9);
        let mut x = [0.0, 0.0];
        box_qp(&a, &[1.0, 1.0], &[-10.0; 2], &[10.0, 0.1], &mut x, 1000);
        assert!((x[1] - 0.1).abs() < 1e-12 && (x[0] - 0.45).abs() < 1e-9);
    }

    #[test]
    fn l1_fit_ignores_outliers_and_penalty_zeroes_useless_columns() {
        // t = 2·c0 exactly on 95 % of rows, wild outliers on the rest; c1 is unrelated noise-free structure.
        let m = 200;
        let c0: Vec<f64> = (0..m).map(|j| 1.0 + (j % 7) as f64 * 0.1).collect();
        let c1: Vec<f64> = (0..m).map(|j| ((j * 37) % 11) as f64 * 0.05).collect();
        let t: Vec<f64> = (0..m).map(|j| if j % 20 == 0 { 50.0 } else { 2.0 * c0[j] }).collect();
        let cols = vec![c0, c1];
        let p = Problem {
            cols: &cols,
            target: &t,
            second: None,
            weights: None,
            groups: None,
            penalty: &[0.0, 0.01],
            prox: &[0.0; 2],
            anchor: &[0.0; 2],
            lo: &[0.0; 2],
            hi: &[1e6; 2],
        };
        let mut x = vec![1.0, 1.0];
        solve(&p, DataLoss::L1, &mut x, 50);
        assert!((x[0] - 2.0).abs() < 0.02, "{x:?}");
        assert!(x[1] < 0.02, "{x:?}");
        // L2 is pulled by the outliers.
        let mut y = vec![1.0, 1.0];
        solve(&p, DataLoss::L2, &mut y, 1);
        assert!((y[0] - 2.0).abs() > 0.1 || y[1] > 0.1, "{y:?}");
    }

    /// One unknown (a colour) fitted to two groups: group 0's rows are two-mode (a checker under one colour),
    /// 26 rows at 0.8 and 24 at 0.2 (mean 0.512); group 1 is uniform at 0.5 ± 0.01 with 3 wild outliers. L1's
    /// fit sits on group 0's larger mode's side (the data term is flat between the modes, so the balance of the
    /// drawn rows decides); the per-group Huber fit is the mean of the two-mode group and ignores the outliers.
    #[test]
    fn group_huber_fits_a_two_mode_group_by_its_mean_and_stays_robust_elsewhere() {
        let mut target: Vec<f64> = (0..50).map(|j| if j < 26 { 0.8 } else { 0.2 }).collect();
        let mut groups = vec![0u32; 50];
        target.extend((0..50).map(|j| if j < 3 { 40.0 } else { 0.5 + 0.01 * ((j % 5) as f64 - 2.0) }));
        groups.extend([1u32; 50]);
        let solve_one = |rows: std::ops::Range<usize>, loss: DataLoss| {
            let cols = vec![vec![1.0; rows.len()]];
            let p = Problem {
                cols: &cols,
                target: &target[rows.clone()],
                second: None,
                weights: None,
                groups: Some(&groups[rows]),
                penalty: &[0.0],
                prox: &[0.0],
                anchor: &[0.0],
                lo: &[0.0],
                hi: &[100.0],
            };
            let mut x = vec![0.5];
            solve(&p, loss, &mut x, 50);
            x[0]
        };
        let (l1, huber) = (solve_one(0..50, DataLoss::L1), solve_one(0..50, DataLoss::GroupHuber));
        // L1: any point between the modes is near-optimal; IRLS ends far from the mean.
        assert!((l1 - 0.512).abs() > 0.1, "L1 {l1}");
        // Huber: the two-mode group's mean, to the IRLS tolerance.
        assert!((huber - 0.512).abs() < 1e-3, "Huber {huber}");
        // The uniform group with outliers: L2 is dragged to ≈ 2.9, Huber stays within the group's spread.
        let huber = solve_one(50..100, DataLoss::GroupHuber);
        assert!((huber - 0.5).abs() < 0.01, "Huber with outliers {huber}");
        assert!((solve_one(50..100, DataLoss::L2) - 0.5).abs() > 1.0);
    }

    #[test]
    fn paired_t_matches_the_textbook_formula() {
        // d = 1, 2, 3, 4: mean 2.5, sample sd √(5/3), se = sd/2 → t = 2.5 / 0.6455 = 3.873.
        let (mean, t) = paired_t(&[1.0, 2.0, 3.0, 4.0]);
        assert!((mean - 2.5).abs() < 1e-12);
        assert!((t - 2.5 / ((5.0f64 / 3.0).sqrt() / 2.0)).abs() < 1e-12);
        // Symmetric differences: no evidence either way.
        assert_eq!(paired_t(&[-1.0, 1.0, -2.0, 2.0]).1, 0.0);
        // Too few samples: no t.
        assert_eq!(paired_t(&[5.0]).1, 0.0);
    }

    #[test]
    fn the_stratified_t_is_the_paired_t_when_both_strata_are_sampled_alike() {
        let d = [0.3, -0.1, 0.5, 0.2, 0.0, 0.4, -0.2, 0.6];
        let a = [true, false, true, false, true, false, true, false];
        let w = 1.0 / d.len() as f64;
        let (m, t) = stratified_t(&d, &a, w, w);
        let (m0, _) = paired_t(&d);
        assert!((m - m0).abs() < 1e-12);
        // Strata a = (0.3, 0.5, 0.0, −0.2), b = (−0.1, 0.2, 0.4, 0.6), each half the population: means 0.15 and
        // 0.275, sample variances 0.29/3 and 0.2675/3, Var = ¼·(0.29/3)/4 + ¼·(0.2675/3)/4.
        let se = (0.25 * (0.29 / 3.0) / 4.0 + 0.25 * (0.2675 / 3.0) / 4.0f64).sqrt();
        assert!((t - 0.2125 / se).abs() < 1e-9, "t {t}");
        // A stratum drawn at 10× the rate of its share: its rows count 1/10 as much in the mean.
        let d2 = [10.0, 10.0, 0.0, 0.0];
        let a2 = [true, true, false, false];
        // Stratum a is 1/11 of the population (2 rows drawn at 10× the rate), b 10/11.
        let (wa, wb) = (1.0 / 11.0 / 2.0, 10.0 / 11.0 / 2.0);
        assert!((stratified_t(&d2, &a2, wa, wb).0 - 10.0 / 11.0).abs() < 1e-12);
    }
}
