//! Significance of the split test: the tail of the F distribution (p-value of an ANOVA F statistic with its
//! degrees of freedom) and Holm's step-down correction for testing many triangles at once. See the module docs
//! of [`crate::triangle`]. The distribution itself comes from `statrs` (one implementation of the special
//! functions for the workspace; tracer's χ² sampling tests use it too).

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

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
    // statrs computes it as I_(d2/(d2 + d1·f))(d2/2, d1/2), the regularised incomplete beta function.
    match FisherSnedecor::new(d1, d2) {
        Ok(dist) => dist.sf(f).clamp(0.0, 1.0),
        // Degrees of freedom ≤ 0 or not finite: no evidence at all.
        Err(_) => 1.0,
    }
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
