//! Significance of the split test: the tail of the F distribution (p-value of an ANOVA F statistic with its
//! degrees of freedom) and Holm's step-down correction for testing many triangles at once. See the module docs
//! of [`crate::triangle`].

/// Relative convergence tolerance of the incomplete beta continued fraction: near f64 resolution, so the
/// p-values are exact to the precision the split decision can use (they are compared with α/m ≥ ~1e-9).
const CF_EPS: f64 = 1e-15;

/// Iteration cap of the continued fraction. It converges in O(√max(a, b)) terms (Numerical Recipes §6.4); the
/// F test's a, b are at most half the pixel count of a triangle (≤ a few 10⁵ in practice), so 10⁴ terms are
/// ample; a non-converged value is still a valid bound-free estimate, never a panic.
const CF_MAX_ITER: usize = 10_000;

/// Smallest magnitude the Lentz recurrence lets a denominator take (avoids division by zero; NR §5.2).
const LENTZ_TINY: f64 = 1e-300;

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9; relative error < 1e-13).
#[must_use]
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    // Below ½ the reflection formula keeps the series in its accurate range.
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Continued fraction of the incomplete beta function (modified Lentz; Numerical Recipes §6.4, `betacf`).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let clamp = |v: f64| if v.abs() < LENTZ_TINY { LENTZ_TINY } else { v };
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / clamp(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..=CF_MAX_ITER {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / clamp(1.0 + aa * d);
        c = clamp(1.0 + aa / c);
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / clamp(1.0 + aa * d);
        c = clamp(1.0 + aa / c);
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() < CF_EPS {
            break;
        }
    }
    h
}

/// The regularised incomplete beta function I_x(a, b) for a, b > 0, x ∈ [0, 1] (x outside is clamped).
#[must_use]
pub fn regularized_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (-x).ln_1p();
    let front = ln_front.exp();
    // The continued fraction converges fast for x < (a + 1)/(a + b + 2); above, the symmetry
    // I_x(a, b) = 1 − I_(1−x)(b, a) brings x below it (NR §6.4).
    if x < (a + 1.0) / (a + b + 2.0) { front * beta_cf(a, b, x) / a } else { 1.0 - front * beta_cf(b, a, 1.0 - x) / b }
}

/// P(X > f) for X ~ F(d1, d2): the p-value of an F statistic with d1 (between) and d2 (within) degrees of
/// freedom. 1 for f ≤ 0 (or NaN), 0 for f = ∞.
#[must_use]
pub fn f_survival(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    if f.is_infinite() {
        return 0.0;
    }
    // X = (d2/d1)·B/(1 − B) with B ~ Beta(d1/2, d2/2), so P(X > f) = I_(d2/(d2 + d1·f))(d2/2, d1/2).
    regularized_beta(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f)).clamp(0.0, 1.0)
}

/// Holm's step-down procedure: which of the hypotheses with p-values `p` are rejected at family-wise error
/// rate `alpha` (the probability of rejecting any true null hypothesis is ≤ α, whatever the dependence
/// between the tests). Sorted ascending, p_(i) is rejected while p_(j) ≤ α/(m − j + 1) for every j ≤ i.
/// Uniformly more powerful than Bonferroni (every p ≤ α/m) at the same guarantee. NaN p-values are never
/// rejected but count as tests.
#[must_use]
pub fn holm(p: &[f64], alpha: f64) -> Vec<bool> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| p[i].total_cmp(&p[j]).then(i.cmp(&j)));
    let mut out = vec![false; m];
    for (rank, &i) in order.iter().enumerate() {
        if p[i] <= alpha / (m - rank) as f64 {
            out[i] = true;
        } else {
            break;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_beta_matches_closed_forms() {
        for &x in &[1e-6f64, 0.01, 0.3, 0.5, 0.77, 0.999] {
            for &b in &[0.5f64, 1.0, 2.5, 40.0] {
                // I_x(1, b) = 1 − (1 − x)^b and I_x(a, 1) = x^a.
                let want = 1.0 - (1.0 - x).powf(b);
                assert!((regularized_beta(1.0, b, x) - want).abs() < 1e-12, "I_{x}(1, {b})");
                assert!((regularized_beta(b, 1.0, x) - x.powf(b)).abs() < 1e-12, "I_{x}({b}, 1)");
                // Symmetry I_x(a, b) = 1 − I_(1−x)(b, a).
                let (a, bb) = (3.5, b);
                let s = regularized_beta(a, bb, x) + regularized_beta(bb, a, 1.0 - x);
                assert!((s - 1.0).abs() < 1e-12, "symmetry at {x}, {b}: {s}");
            }
        }
        // Γ(n) = (n − 1)!.
        assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-12);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
    }

    #[test]
    fn f_tail_matches_closed_forms() {
        for &f in &[0.1f64, 1.0, 3.0, 10.0, 30.1, 1e4] {
            // F(2, d2): P(X > f) = (1 + 2f/d2)^(−d2/2).
            for &d2 in &[1.0f64, 5.0, 17.0, 400.0] {
                let want = (1.0 + 2.0 * f / d2).powf(-0.5 * d2);
                let got = f_survival(f, 2.0, d2);
                assert!((got - want).abs() <= 1e-12 + 1e-9 * want, "F(2, {d2}) at {f}: {got} vs {want}");
            }
            // F(1, 1) is the square of a standard Cauchy variable: P(X > f) = 1 − (2/π)·atan(√f).
            let want = 1.0 - 2.0 / std::f64::consts::PI * f.sqrt().atan();
            assert!((f_survival(f, 1.0, 1.0) - want).abs() < 1e-12);
        }
        assert_eq!(f_survival(0.0, 3.0, 10.0), 1.0);
        assert_eq!(f_survival(f64::INFINITY, 3.0, 10.0), 0.0);
        assert_eq!(f_survival(f64::NAN, 3.0, 10.0), 1.0);
    }

    #[test]
    fn holm_steps_down_and_stops_at_the_first_acceptance() {
        // m = 4, α = 0.05: thresholds 0.0125, 0.0167, 0.025, 0.05 for the sorted p-values.
        let p = [0.04, 0.001, 0.015, 0.03];
        assert_eq!(holm(&p, 0.05), vec![false, true, true, false]);
        // Bonferroni alone (0.0125) would have rejected only 0.001; the 4th (0.04 ≤ 0.05) is not reached.
        assert_eq!(holm(&[0.2, 0.3], 0.05), vec![false, false]);
        assert!(holm(&[], 0.05).is_empty());
        assert_eq!(holm(&[f64::NAN, 0.001], 0.01), vec![false, true]);
    }
}
