//! The inner estimate that predicts extrapolation: the chosen pick — its members, ridges and
//! weights as the selection fixed them — evaluated forward in time. Each held-out block of the
//! inner validation whose past holds at least two blocks is predicted by the members refitted on the rows
//! before it, beyond the gap ([`crate::inner_cv::Folds::forward`]), and blended with the pick's
//! weights.
//!
//! The selection itself scores the families on the gap-separated blocked folds, which let a
//! block be predicted by rows after it: that is the better basis for choosing (every fold
//! trains on nearly all rows, so the scores are comparable), but as an estimate of the error
//! on a later test part, or on another run, it interpolates and comes out 2–3× too low. A
//! compensation model is always used on data later than everything it learnt from, so its
//! estimate is measured the same way.

use crate::features::Family;
use crate::problem::Problem;
use crate::selection::Pick;

/// A member refitted on every forward fold: per fold, per target, the combination of
/// [1 | features | targets] it predicts.
type Refitted = (Family, f64, Vec<Vec<Vec<f64>>>);

/// Per target, the forward RMSE of the pick and of no compensation (µm), over the held-out
/// rows of the forward folds; `None` when the inner folds leave no forward fold. Everything
/// comes from the problem's triangles ([`crate::problem`]): each fold's members are fitted on
/// the triangle of its past, and the blend's errors are those of one combination of
/// [1 | features | targets] applied to the held-out block's triangle.
pub(crate) fn evaluate(
    p: &Problem<'_>,
    picks: &[Pick],
    sensors: &[usize],
    reference: Option<usize>,
) -> Option<Vec<(f64, f64)>> {
    let folds = p.folds.forward();
    if folds.folds.is_empty() {
        return None;
    }
    let nt = p.nt;
    let width = 1 + p.cand.features.len() + nt;
    let past: Vec<_> = folds.folds.iter().map(|f| p.stack(&f.train)).collect();
    let held: Vec<_> = folds
        .folds
        .iter()
        .map(|f| p.stack_rows(f.held.clone()))
        .collect();
    // Per (family, ridge), refitted once: per fold, per target, the combination it predicts
    // (zero where a fold's fit fails: that fold predicts nothing).
    let mut done: Vec<Refitted> = Vec::new();
    let mut out = Vec::with_capacity(nt);
    for (k, pick) in picks.iter().enumerate() {
        let mut blend = vec![vec![0.0; width]; folds.folds.len()];
        for m in &pick.members {
            let at = match done.iter().position(|d| d.0 == m.family && d.1 == m.ridge) {
                Some(at) => at,
                None => {
                    let design = p.design(m.family, sensors, reference)?;
                    let opts = design.solve_options(m.ridge);
                    let per_fold = past
                        .iter()
                        .map(|t| match p.design_on(t, &design).solve(&opts) {
                            Ok(sol) => (0..nt)
                                .map(|k| p.combination(&design, &sol.coefficients[k], None))
                                .collect(),
                            Err(_) => vec![vec![0.0; width]; nt],
                        })
                        .collect();
                    done.push((m.family, m.ridge, per_fold));
                    done.len() - 1
                }
            };
            for (b, u) in blend.iter_mut().zip(&done[at].2) {
                for (x, y) in b.iter_mut().zip(&u[k]) {
                    *x += m.weight * y;
                }
            }
        }
        let target = width - nt + k;
        let (mut sse, mut zero) = (0.0, 0.0);
        for (t, mut u) in held.iter().zip(blend) {
            let mut e = vec![0.0; width];
            e[target] = 1.0;
            zero += t.apply(&e).iter().map(|v| v * v).sum::<f64>();
            u[target] -= 1.0;
            sse += t.apply(&u).iter().map(|v| v * v).sum::<f64>();
        }
        let n = folds.held_rows().max(1) as f64;
        out.push(((sse / n).sqrt(), (zero / n).sqrt()));
    }
    Some(out)
}
