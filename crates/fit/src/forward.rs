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
use crate::inner_cv::Folds;
use crate::least_squares::{Accumulator, SolveOptions};
use crate::selection::Pick;
use crate::stacking;
use crate::train::{Design, Problem};

/// One member's forward predictions: per target, the held-out rows in fold order.
type Predictions = Vec<Vec<f64>>;

/// The forward evaluation of every pick: per target, the held-out targets and the pick's
/// forward predictions of them (fold order).
pub(crate) struct Forward {
    /// Per target, the held-out rows' targets.
    pub y: Vec<Vec<f64>>,
    /// Per target, the pick's forward predictions.
    pub pred: Vec<Vec<f64>>,
}

impl Forward {
    /// Target `k`'s forward RMSE of the pick and of no compensation (µm).
    pub fn rmse(&self, k: usize) -> (f64, f64) {
        let zero = vec![0.0; self.y[k].len()];
        (
            stacking::rmse(&self.y[k], &self.pred[k]),
            stacking::rmse(&self.y[k], &zero),
        )
    }
}

/// Evaluates `picks` forward; `None` when the inner folds leave no forward fold.
pub(crate) fn evaluate(
    p: &Problem<'_>,
    picks: &[Pick],
    sensors: &[usize],
    reference: Option<usize>,
) -> Option<Forward> {
    let folds = p.folds.forward();
    if folds.folds.is_empty() {
        return None;
    }
    let nt = p.y.ncols();
    let held: Vec<usize> = folds.folds.iter().flat_map(|f| f.held.clone()).collect();
    // Each (family, ridge) is refitted once for every target that has it as a member.
    let mut done: Vec<(Family, f64, Predictions)> = Vec::new();
    let mut pred = vec![vec![0.0; held.len()]; nt];
    for (k, pick) in picks.iter().enumerate() {
        for m in &pick.members {
            let at = match done.iter().position(|d| d.0 == m.family && d.1 == m.ridge) {
                Some(at) => at,
                None => {
                    let design = p.design(m.family, sensors, reference)?;
                    done.push((m.family, m.ridge, predictions(p, &folds, &design, m.ridge)));
                    done.len() - 1
                }
            };
            for (out, v) in pred[k].iter_mut().zip(&done[at].2[k]) {
                *out += m.weight * v;
            }
        }
    }
    let y = (0..nt)
        .map(|k| held.iter().map(|&i| p.y[(i, k)]).collect())
        .collect();
    Some(Forward { y, pred })
}

/// A design's predictions of every forward fold's held-out rows, per target, each fold fitted
/// at `ridge` on its own past (a fold whose fit fails predicts nothing: zero).
fn predictions(p: &Problem<'_>, folds: &Folds, d: &Design, ridge: f64) -> Predictions {
    let nt = p.y.ncols();
    let opts = SolveOptions {
        ridge,
        unpenalized: vec![0],
        rcond: None,
    };
    let needed = |s: usize| folds.folds.iter().any(|f| f.train.contains(&s));
    let parts: Vec<Option<Accumulator>> = (0..folds.segments.len())
        .map(|s| needed(s).then(|| p.accumulate(d, folds.segments[s].clone())))
        .collect();
    let mut out = vec![Vec::with_capacity(folds.held_rows()); nt];
    for fold in &folds.folds {
        let mut acc = Accumulator::new(d.cols.len() + 1, nt);
        for part in fold.train.iter().filter_map(|&s| parts[s].as_ref()) {
            let _ = acc.merge(part.clone());
        }
        let sol = acc.finish().solve(&opts).ok();
        for (k, col) in out.iter_mut().enumerate() {
            col.extend(fold.held.clone().map(|i| match &sol {
                Some(sol) => p.predict(d, &sol.coefficients[k], i),
                None => 0.0,
            }));
        }
    }
    out
}
