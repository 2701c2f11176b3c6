//! Combining candidate models by their honest validation (stacking, Wolpert 1992; Breiman,
//! *Stacked regressions*, Machine Learning 24, 1996): instead of trusting the one candidate with
//! the lowest — noisy — cross-validation score, the prediction is a weighted sum of the
//! candidates' out-of-fold predictions with non-negative weights that sum to at most one. The
//! weight left over goes to "no compensation" (a prediction of zero), so a blend that
//! extrapolates badly is shrunk towards doing nothing rather than amplified. Every family is
//! linear in the same candidate features, so the blend is itself one linear model: its
//! coefficients are the weighted sums of the members'.
//!
//! ```
//! use truepos_fit::stacking::weights;
//! // Candidate 0 predicts y exactly, candidate 1 is noise: all weight on candidate 0.
//! let y = vec![1.0, -2.0, 3.0, 0.5];
//! let p = vec![y.clone(), vec![0.3, 0.1, -0.2, 0.4]];
//! let w = weights(&p, &y);
//! assert!((w[0] - 1.0).abs() < 1e-9 && w[1].abs() < 1e-9);
//! ```

use faer::linalg::solvers::Solve;
use faer::Mat;

/// Candidates beyond this many are not combined (2^m faces are searched).
pub const MAX_MEMBERS: usize = 12;

/// Weights w ≥ 0, Σw ≤ 1 minimising ‖y − Σ_m w_m·p_m‖²; `p[m]` is candidate m's prediction of
/// `y`. Exact: the optimum of this convex quadratic programme lies on one face of the feasible
/// set (some weights zero, the sum constraint active or not), and every face is solved.
/// Candidates past [`MAX_MEMBERS`] get weight zero.
pub fn weights(p: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let m = p.len().min(MAX_MEMBERS);
    let gram = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let g: Vec<Vec<f64>> = (0..m)
        .map(|i| (0..m).map(|j| gram(&p[i], &p[j])).collect())
        .collect();
    let b: Vec<f64> = (0..m).map(|i| gram(&p[i], y)).collect();
    // A tiny ridge: two families that predict almost alike make the Gram matrix singular.
    let tiny = 1e-10 * (0..m).map(|i| g[i][i]).sum::<f64>().max(1e-300) / m.max(1) as f64;
    let objective = |w: &[f64]| {
        let mut f = 0.0;
        for i in 0..m {
            f -= 2.0 * b[i] * w[i];
            for j in 0..m {
                f += w[i] * g[i][j] * w[j];
            }
        }
        f
    };
    let mut best = vec![0.0; p.len()];
    let mut best_f = 0.0;
    for subset in 1u32..(1u32 << m) {
        let idx: Vec<usize> = (0..m).filter(|&i| subset & (1 << i) != 0).collect();
        for sum_active in [false, true] {
            let Some(ws) = face(&g, &b, &idx, sum_active, tiny) else {
                continue;
            };
            let total: f64 = ws.iter().sum();
            if ws.iter().any(|&w| w < -1e-12) || total > 1.0 + 1e-9 {
                continue;
            }
            let mut w = vec![0.0; p.len()];
            for (&i, &wi) in idx.iter().zip(&ws) {
                w[i] = wi.max(0.0);
            }
            let f = objective(&w);
            if f < best_f {
                best_f = f;
                best = w;
            }
        }
    }
    best
}

/// The minimiser on one face: weights of `idx` free (or summing to one), the others zero.
fn face(g: &[Vec<f64>], b: &[f64], idx: &[usize], sum_active: bool, tiny: f64) -> Option<Vec<f64>> {
    let s = idx.len();
    let n = s + usize::from(sum_active);
    let mut a = Mat::<f64>::zeros(n, n);
    let mut rhs = Mat::<f64>::zeros(n, 1);
    for (r, &i) in idx.iter().enumerate() {
        for (c, &j) in idx.iter().enumerate() {
            a[(r, c)] = g[i][j] + if r == c { tiny } else { 0.0 };
        }
        rhs[(r, 0)] = b[i];
    }
    if sum_active {
        for r in 0..s {
            a[(r, s)] = 1.0;
            a[(s, r)] = 1.0;
        }
        rhs[(s, 0)] = 1.0;
    }
    let x = a.partial_piv_lu().solve(&rhs);
    let w: Vec<f64> = (0..s).map(|r| x[(r, 0)]).collect();
    w.iter().all(|v| v.is_finite()).then_some(w)
}

/// Root mean square of `a − b`.
pub fn rmse(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(1) as f64;
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn an_overshooting_candidate_is_shrunk_towards_zero() {
        // The candidate predicts twice the truth: the best weight is 1/2.
        let y: Vec<f64> = (0..50).map(|i| (i as f64 * 0.3).sin()).collect();
        let p = vec![y.iter().map(|v| 2.0 * v).collect::<Vec<_>>()];
        let w = weights(&p, &y);
        assert!((w[0] - 0.5).abs() < 1e-9, "{w:?}");
    }

    #[test]
    fn the_sum_constraint_binds_and_mixes_two_halves() {
        // y = a + b; candidates a+b+noise-ish pieces: p0 = y + d, p1 = y − d → w = ½, ½.
        let y: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let d: Vec<f64> = (0..40)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let p0: Vec<f64> = y.iter().zip(&d).map(|(a, b)| a + b).collect();
        let p1: Vec<f64> = y.iter().zip(&d).map(|(a, b)| a - b).collect();
        let w = weights(&[p0, p1], &y);
        assert!(
            (w[0] - 0.5).abs() < 1e-6 && (w[1] - 0.5).abs() < 1e-6,
            "{w:?}"
        );
    }

    proptest! {
        /// The weights are feasible and no worse than any single candidate at its best scale
        /// within [0, 1], nor than zero.
        #[test]
        fn weights_are_feasible_and_optimal_among_simple_rivals(
            rows in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0), 3..30),
        ) {
            let y: Vec<f64> = rows.iter().map(|r| r.0).collect();
            let p: Vec<Vec<f64>> = vec![
                rows.iter().map(|r| r.1).collect(),
                rows.iter().map(|r| r.2).collect(),
                rows.iter().map(|r| r.3).collect(),
            ];
            let w = weights(&p, &y);
            prop_assert!(w.iter().all(|v| *v >= 0.0) && w.iter().sum::<f64>() <= 1.0 + 1e-9);
            let sse = |w: &[f64]| -> f64 {
                (0..y.len()).map(|i| {
                    let q: f64 = p.iter().zip(w).map(|(v, wm)| wm * v[i]).sum();
                    (y[i] - q).powi(2)
                }).sum()
            };
            let ours = sse(&w);
            prop_assert!(ours <= sse(&[0.0, 0.0, 0.0]) + 1e-9);
            for m in 0..3 {
                for s in [0.25, 0.5, 1.0] {
                    let mut r = vec![0.0; 3];
                    r[m] = s;
                    prop_assert!(ours <= sse(&r) + 1e-6 * (1.0 + sse(&r)));
                }
            }
        }
    }
}
