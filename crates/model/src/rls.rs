//! On-line re-identification of a model's parameters: recursive least squares with a forgetting
//! factor: probing re-identification (docs/glossary.md: re-identification).
//!
//! Each probe measurement of an axis' error y, with the model's regressors φ at that instant,
//! updates θ:
//!
//! ```text
//! e = y − φᵀθ                      prediction error before the update
//! k = P·φ / (λ + φᵀ·P·φ)           gain
//! θ ← θ + k·e
//! P ← (P − k·φᵀ·P) / λ             λ < 1 forgets old data with time constant ≈ 1/(1 − λ) updates
//! ```
//!
//! [`SwitchRule`] decides when the re-estimated parameters should replace the running ones:
//! when the running model's recent error exceeds a threshold and the candidate's recent error is
//! clearly smaller.

use alloc::vec;
use alloc::vec::Vec;

/// Recursive least squares over `n` parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Rls {
    n: usize,
    theta: Vec<f64>,
    p: Vec<f64>,
    lambda: f64,
    scratch: Vec<f64>,
}

impl Rls {
    /// Starts from θ₀ with covariance P₀ = `p0`·I and forgetting factor `lambda` (0.9 … 1).
    pub fn new(theta0: &[f64], p0: f64, lambda: f64) -> Self {
        let n = theta0.len();
        let mut p = vec![0.0; n * n];
        for i in 0..n {
            p[i * n + i] = p0;
        }
        Self {
            n,
            theta: theta0.to_vec(),
            p,
            lambda: lambda.clamp(0.5, 1.0),
            scratch: vec![0.0; 2 * n],
        }
    }

    /// The current estimate θ.
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// One measurement y with regressors φ; returns the prediction error before the update.
    /// Non-finite inputs are ignored (returns `None`); allocates nothing.
    pub fn update(&mut self, phi: &[f64], y: f64) -> Option<f64> {
        let n = self.n;
        if phi.len() != n || !y.is_finite() || phi.iter().any(|v| !v.is_finite()) {
            return None;
        }
        if n == 0 {
            // Nothing to estimate: the error is the measurement (and `chunks_exact(0)` panics).
            return Some(y);
        }
        let e = y - dot(phi, &self.theta);
        let (pphi, _) = self.scratch.split_at_mut(n);
        for (pi, row) in pphi.iter_mut().zip(self.p.chunks_exact(n)) {
            *pi = dot(row, phi);
        }
        let denom = self.lambda + dot(phi, pphi);
        if denom.is_nan() || denom <= 0.0 {
            return None;
        }
        for (t, pi) in self.theta.iter_mut().zip(pphi.iter()) {
            *t += pi / denom * e;
        }
        // P is symmetric, so φᵀP = (Pφ)ᵀ.
        for (row, pi) in self.p.chunks_exact_mut(n).zip(pphi.iter()) {
            for (v, pj) in row.iter_mut().zip(pphi.iter()) {
                *v = (*v - pi * pj / denom) / self.lambda;
            }
        }
        Some(e)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Exponentially weighted RMS of recent prediction errors of the running and the candidate
/// parameters, and the rule to switch (re-learn when the difference between estimated and measured
/// values is not below a threshold).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchRule {
    /// Weight of the newest squared error, 0 … 1 (0.1 ≈ the last 10 measurements).
    pub weight: f64,
    /// RMS error of the running model (µm) above which a switch is considered.
    pub threshold_um: f64,
    /// The candidate must be better by this factor (0.8: 20 % smaller RMS).
    pub margin: f64,
    /// Measurements needed before any decision.
    pub min_samples: u32,
    running_ms: f64,
    candidate_ms: f64,
    samples: u32,
}

impl SwitchRule {
    /// A rule with the given threshold; weight 0.1, margin 0.8, 10 measurements at least.
    pub fn new(threshold_um: f64) -> Self {
        Self {
            weight: 0.1,
            threshold_um,
            margin: 0.8,
            min_samples: 10,
            running_ms: 0.0,
            candidate_ms: 0.0,
            samples: 0,
        }
    }

    /// Records one measurement's errors of the running and the candidate parameters.
    pub fn record(&mut self, running_error_um: f64, candidate_error_um: f64) {
        if !(running_error_um.is_finite() && candidate_error_um.is_finite()) {
            return;
        }
        let w = if self.samples == 0 { 1.0 } else { self.weight };
        self.running_ms += w * (running_error_um * running_error_um - self.running_ms);
        self.candidate_ms += w * (candidate_error_um * candidate_error_um - self.candidate_ms);
        self.samples = self.samples.saturating_add(1);
    }

    /// Recent RMS errors (running, candidate) in µm.
    pub fn recent_rms_um(&self) -> (f64, f64) {
        (libm::sqrt(self.running_ms), libm::sqrt(self.candidate_ms))
    }

    /// Whether to switch to the candidate now.
    pub fn should_switch(&self) -> bool {
        let (run, cand) = self.recent_rms_um();
        self.samples >= self.min_samples && run > self.threshold_um && cand < self.margin * run
    }

    /// Starts afresh after a switch: the candidate is now the running model.
    pub fn switched(&mut self) {
        self.running_ms = self.candidate_ms;
        self.samples = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model with no parameters (a zero model re-identified) has nothing to update: the
    /// measurement is the error, and nothing panics.
    #[test]
    fn no_parameters_returns_the_measurement() {
        let mut r = Rls::new(&[], 1e3, 0.99);
        assert_eq!(r.update(&[], 4.5), Some(4.5));
        assert_eq!(r.update(&[], f64::NAN), None);
    }

    /// y = 2·x₁ − 3·x₂ without noise: RLS from zero reaches θ = (2, −3).
    #[test]
    fn rls_finds_exact_parameters() {
        let mut r = Rls::new(&[0.0, 0.0], 1e6, 1.0);
        for i in 0..50 {
            let x = [1.0 + 0.1 * i as f64, libm::sin(i as f64)];
            r.update(&x, 2.0 * x[0] - 3.0 * x[1]).unwrap();
        }
        assert!((r.theta()[0] - 2.0).abs() < 1e-6);
        assert!((r.theta()[1] + 3.0).abs() < 1e-6);
    }

    /// The gain drifts from 2 to 3 half way: with forgetting (λ = 0.9) the estimate follows.
    #[test]
    fn forgetting_follows_drift() {
        let mut r = Rls::new(&[0.0], 1e3, 0.9);
        for i in 0..200 {
            let x = [1.0 + (i % 7) as f64];
            let k = if i < 100 { 2.0 } else { 3.0 };
            r.update(&x, k * x[0]);
        }
        // The 100 old samples still weigh 0.9^100 ≈ 2.7e-5 of the new ones: θ is within 1e-3.
        assert!((r.theta()[0] - 3.0).abs() < 1e-3, "{}", r.theta()[0]);
        // Without forgetting the estimate stays between the two gains.
        let mut stiff = Rls::new(&[0.0], 1e3, 1.0);
        for i in 0..200 {
            let x = [1.0 + (i % 7) as f64];
            stiff.update(&x, if i < 100 { 2.0 } else { 3.0 } * x[0]);
        }
        assert!((stiff.theta()[0] - 2.5).abs() < 0.1);
        assert_eq!(r.update(&[f64::NAN], 1.0), None);
    }

    #[test]
    fn switch_rule() {
        let mut s = SwitchRule::new(5.0);
        for _ in 0..9 {
            s.record(8.0, 1.0);
        }
        assert!(!s.should_switch(), "too few samples");
        s.record(8.0, 1.0);
        assert!(s.should_switch());
        let mut quiet = SwitchRule::new(5.0);
        for _ in 0..20 {
            quiet.record(3.0, 1.0);
        }
        assert!(
            !quiet.should_switch(),
            "below the threshold: keep the running model"
        );
    }
}
