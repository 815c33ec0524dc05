//! Adam (Kingma & Ba 2015) over a flat parameter vector, with a learning rate per parameter group and box
//! domains enforced by clamping after every step (paper §4.5). The state is plain serde data so a checkpoint
//! resumes the exact trajectory.

use serde::{Deserialize, Serialize};

/// Adam's moment decay rates and the denominator guard, the defaults of Kingma & Ba (2015, Alg. 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdamConfig {
    pub beta1: f64,
    pub beta2: f64,
    /// Added to √v̂; 1e-8 is the paper's value and only matters for parameters whose gradient is always ~0.
    pub eps: f64,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig { beta1: 0.9, beta2: 0.999, eps: 1e-8 }
    }
}

/// First and second moment estimates and the step count; one entry per parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdamState {
    pub config: AdamConfig,
    pub m: Vec<f64>,
    pub v: Vec<f64>,
    /// Number of steps taken (t in Kingma & Ba), drives the bias correction.
    pub t: u64,
}

impl AdamState {
    #[must_use]
    pub fn new(n: usize, config: AdamConfig) -> Self {
        AdamState { config, m: vec![0.0; n], v: vec![0.0; n], t: 0 }
    }

    /// One Adam step: `x[i] -= lr[i] · m̂ / (√v̂ + ε)`, then `x[i]` is clamped to `[lo[i], hi[i]]`.
    /// A parameter with `lr[i] == 0` is frozen: neither it nor its moments change.
    ///
    /// # Panics
    /// When the slices do not all have the state's length (a programming error, not bad input).
    pub fn step(&mut self, x: &mut [f64], grad: &[f64], lr: &[f64], lo: &[f64], hi: &[f64]) {
        let n = self.m.len();
        assert!(
            x.len() == n && grad.len() == n && lr.len() == n && lo.len() == n && hi.len() == n,
            "adam: slice lengths differ from the state ({n})"
        );
        self.t += 1;
        let AdamConfig { beta1, beta2, eps } = self.config;
        let t = i32::try_from(self.t).unwrap_or(i32::MAX);
        let c1 = 1.0 - beta1.powi(t);
        let c2 = 1.0 - beta2.powi(t);
        for i in 0..n {
            if lr[i] == 0.0 {
                continue;
            }
            let g = grad[i];
            self.m[i] = beta1 * self.m[i] + (1.0 - beta1) * g;
            self.v[i] = beta2 * self.v[i] + (1.0 - beta2) * g * g;
            let m_hat = self.m[i] / c1;
            let v_hat = self.v[i] / c2;
            x[i] = (x[i] - lr[i] * m_hat / (v_hat.sqrt() + eps)).clamp(lo[i], hi[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_moves_by_exactly_the_learning_rate_against_the_gradient_sign() {
        // With bias correction m̂ = g and v̂ = g², so the first step is lr·sign(g) (up to ε).
        let mut s = AdamState::new(3, AdamConfig::default());
        let mut x = vec![0.5, 0.5, 0.5];
        s.step(&mut x, &[2.0, -0.001, 0.0], &[0.01; 3], &[0.0; 3], &[1.0; 3]);
        assert!((x[0] - 0.49).abs() < 1e-9);
        assert!((x[1] - 0.51).abs() < 1e-6);
        assert_eq!(x[2], 0.5);
    }

    #[test]
    fn minimises_a_badly_scaled_quadratic_and_respects_the_box() {
        // f = 1000 (x0 - 0.3)² + 0.001 (x1 - 0.7)² + (x2 - 2)² with x2 ∈ [0, 1]: Adam's per-coordinate scaling
        // reaches both minima; x2 ends on its bound.
        let mut s = AdamState::new(3, AdamConfig::default());
        let mut x = vec![0.9, 0.1, 0.5];
        for k in 0..4000 {
            let lr = if k < 3000 { 0.01 } else { 0.001 };
            let g = [2000.0 * (x[0] - 0.3), 0.002 * (x[1] - 0.7), 2.0 * (x[2] - 2.0)];
            s.step(&mut x, &g, &[lr; 3], &[0.0; 3], &[1.0; 3]);
        }
        assert!((x[0] - 0.3).abs() < 1e-3, "{x:?}");
        assert!((x[1] - 0.7).abs() < 1e-3, "{x:?}");
        assert_eq!(x[2], 1.0);
    }

    #[test]
    fn frozen_parameters_keep_value_and_moments() {
        let mut s = AdamState::new(2, AdamConfig::default());
        let mut x = vec![0.2, 0.2];
        s.step(&mut x, &[1.0, 1.0], &[0.1, 0.0], &[0.0; 2], &[1.0; 2]);
        assert_eq!(x[1], 0.2);
        assert_eq!((s.m[1], s.v[1]), (0.0, 0.0));
    }

    #[test]
    fn state_round_trips_through_json_bit_exactly() {
        let mut s = AdamState::new(2, AdamConfig::default());
        let mut x = vec![0.2, 0.8];
        s.step(&mut x, &[0.3, -0.7], &[0.01; 2], &[0.0; 2], &[1.0; 2]);
        let back: AdamState = serde_json::from_str(&serde_json::to_string(&s).unwrap()).unwrap();
        assert_eq!(back, s);
    }
}
