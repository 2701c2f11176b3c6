//! The automatic selection of one target's model: every family scored by the gap-separated inner
//! validation ([`crate::inner_cv`]), its ridge chosen within the family, the families combined
//! by their out-of-fold predictions ([`crate::stacking`]), and a guard that writes no
//! compensation when the result is not clearly better than none.

use crate::features::Family;
use crate::least_squares::{Accumulator, SolveOptions};
use crate::settings::{Rule, Settings};
use crate::stacking;
use crate::train::{Design, FamilyScore, Problem};

/// A blend must beat "no compensation" by this factor in the inner validation (RMSE ratio)
/// to be written: a model that removes less than a tenth of the error is not worth an axis'
/// risk, and the inner estimate itself is uncertain by more than that.
pub const CLEARLY_BETTER: f64 = 0.9;

/// One member of a blend.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Member {
    /// Its family.
    pub family: Family,
    /// Its ridge parameter.
    pub ridge: f64,
    /// Its weight in the blend (the weights sum to at most 1; the rest is "no compensation").
    pub weight: f64,
    /// Its own inner-validation RMSE (µm).
    pub cv_rmse_um: f64,
    /// The identified time constant of the transfer family (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_s: Option<f64>,
}

/// What the selection chose for one target.
#[derive(Debug, Clone, PartialEq)]
pub struct Pick {
    /// The members with a weight above zero (empty: no compensation).
    pub members: Vec<Member>,
    /// The inner-validation RMSE of the pick itself, its weights fitted out of fold (µm).
    pub cv_rmse_um: f64,
    /// The inner-validation RMSE of no compensation (µm).
    pub uncompensated_um: f64,
    /// Why the pick is not the blend, if it is not.
    pub fallback: Option<String>,
}

/// The inner validation of one design: per ridge, per target, the RMSE over all held-out rows
/// with the standard error of the per-fold RMSEs, and the held-out predictions (fold order).
pub(crate) struct FamilyCv {
    pub scores: Vec<Vec<(f64, f64)>>,
    pub oof: Vec<Vec<Vec<f64>>>,
}

/// Scores a design by the problem's folds (each trains on whole segments, one accumulator each).
pub(crate) fn cv(p: &Problem<'_>, d: &Design, ridges: &[f64]) -> FamilyCv {
    let nt = p.y.ncols();
    let folds = &p.folds;
    let parts: Vec<Accumulator> = folds
        .segments
        .iter()
        .map(|r| p.accumulate(d, r.clone()))
        .collect();
    let held_n = folds.held_rows();
    let mut oof = vec![vec![vec![0.0; held_n]; nt]; ridges.len()];
    let mut sse = vec![vec![vec![0.0; folds.folds.len()]; nt]; ridges.len()];
    let mut offset = 0;
    for (f, fold) in folds.folds.iter().enumerate() {
        let mut acc = Accumulator::new(d.cols.len() + 1, nt);
        for &s in &fold.train {
            let _ = acc.merge(parts[s].clone());
        }
        let tri = acc.finish();
        for (ri, &ridge) in ridges.iter().enumerate() {
            let opts = SolveOptions {
                ridge,
                unpenalized: vec![0],
                rcond: None,
            };
            let sol = tri.solve(&opts).ok();
            for (o, i) in fold.held.clone().enumerate() {
                for k in 0..nt {
                    let pred = match &sol {
                        Some(sol) => p.predict(d, &sol.coefficients[k], i),
                        None => f64::INFINITY,
                    };
                    oof[ri][k][offset + o] = pred;
                    sse[ri][k][f] += (p.y[(i, k)] - pred).powi(2);
                }
            }
        }
        offset += fold.held.len();
    }
    let used = folds.folds.len() as f64;
    let scores = sse
        .into_iter()
        .map(|per_target| {
            per_target
                .into_iter()
                .map(|per_fold| {
                    let total: f64 = per_fold.iter().sum();
                    let rmse: Vec<f64> = per_fold
                        .iter()
                        .zip(&folds.folds)
                        .map(|(s, fold)| (s / fold.held.len().max(1) as f64).sqrt())
                        .collect();
                    let m = rmse.iter().sum::<f64>() / used;
                    let var =
                        rmse.iter().map(|r| (r - m).powi(2)).sum::<f64>() / (used - 1.0).max(1.0);
                    ((total / held_n.max(1) as f64).sqrt(), (var / used).sqrt())
                })
                .collect()
        })
        .collect();
    FamilyCv { scores, oof }
}

/// The ridge index a family keeps for target `k`: the lowest CV RMSE, or with
/// [`Rule::OneStandardError`] the largest ridge within one standard error of it (Hastie,
/// Tibshirani & Friedman, *The Elements of Statistical Learning*, 2nd ed., §7.10: among models
/// the CV cannot tell apart, the most regularised one, which extrapolates more gently).
fn ridge_index(scores: &[Vec<(f64, f64)>], ridges: &[f64], k: usize, rule: Rule) -> usize {
    let best = (0..ridges.len())
        .min_by(|&a, &b| scores[a][k].0.total_cmp(&scores[b][k].0))
        .unwrap_or(0);
    match rule {
        Rule::MinimumCv => best,
        Rule::OneStandardError => {
            let bound = scores[best][k].0 + scores[best][k].1;
            (0..ridges.len())
                .filter(|&r| scores[r][k].0 <= bound)
                .max_by(|&a, &b| ridges[a].total_cmp(&ridges[b]))
                .unwrap_or(best)
        }
    }
}

/// Per target the pick, and every family's figures (lowest CV RMSE over the ridges, per target).
pub(crate) fn select(
    p: &Problem<'_>,
    settings: &Settings,
    sensors: &[usize],
) -> (Vec<Pick>, Vec<FamilyScore>) {
    let nt = p.y.ncols();
    let reference = p.reference(settings);
    // Per target, the candidate members: (family, ridge, rmse, held-out predictions).
    let mut members: Vec<Vec<(Family, f64, f64, Vec<f64>)>> = vec![Vec::new(); nt];
    let mut families = Vec::new();
    for &family in &settings.families {
        let Some(design) = p.design(family, sensors, reference) else {
            continue;
        };
        let mut fam = cv(p, &design, &settings.ridges);
        let mut per_target = vec![(f64::INFINITY, 0.0); nt];
        for k in 0..nt {
            for (ri, row) in fam.scores.iter().enumerate() {
                if row[k].0 < per_target[k].0 {
                    per_target[k] = (row[k].0, settings.ridges[ri]);
                }
            }
            let ri = ridge_index(&fam.scores, &settings.ridges, k, settings.rule);
            let rmse = fam.scores[ri][k].0;
            if rmse.is_finite() {
                let pred = std::mem::take(&mut fam.oof[ri][k]);
                members[k].push((family, settings.ridges[ri], rmse, pred));
            }
        }
        families.push(FamilyScore { family, per_target });
    }
    let held = p.held_targets();
    let ranges = p.held_ranges();
    let picks = (0..nt)
        .map(|k| {
            let mut pick = pick(&members[k], &held[k], &ranges);
            for m in &mut pick.members {
                m.tau_s = (m.family == Family::Transfer).then_some(p.transfer_tau).flatten();
            }
            pick
        })
        .collect();
    (picks, families)
}

/// Blend, guard and fallback for one target.
fn pick(
    members: &[(Family, f64, f64, Vec<f64>)],
    y: &[f64],
    ranges: &[std::ops::Range<usize>],
) -> Pick {
    let zero = stacking::rmse(y, &vec![0.0; y.len()]);
    let none = |reason: String| Pick {
        members: Vec::new(),
        cv_rmse_um: zero,
        uncompensated_um: zero,
        fallback: Some(reason),
    };
    if members.is_empty() {
        return none("no family could be fitted: no compensation".into());
    }
    let preds: Vec<Vec<f64>> = members.iter().map(|m| m.3.clone()).collect();
    let w = stacking::weights(&preds, y);
    let blended: Vec<f64> = (0..y.len())
        .map(|i| preds.iter().zip(&w).map(|(p, wm)| wm * p[i]).sum())
        .collect();
    let score = if std::env::var("TRUEPOS_XFIT").is_ok() {
        stacking::rmse(y, &stacking::cross_fitted(&preds, y, ranges))
    } else {
        stacking::rmse(y, &blended)
    };
    if std::env::var("TRUEPOS_DEBUG_SELECT").is_ok() {
        let per: Vec<String> = members.iter().zip(&w).map(|(m, wm)| format!("{}@{:e}={:.3} w{:.2}", m.0, m.1, m.2, wm)).collect();
        eprintln!("zero {zero:.3} stack {score:.3} in-sample {:.3} | {}", stacking::rmse(y, &(0..y.len()).map(|i| preds.iter().zip(&w).map(|(p, wm)| wm * p[i]).sum()).collect::<Vec<f64>>()), per.join(" "));
    }
    let single = |i: usize, why: Option<String>| Pick {
        members: vec![Member {
            family: members[i].0,
            ridge: members[i].1,
            weight: 1.0,
            cv_rmse_um: members[i].2,
            tau_s: None,
        }],
        cv_rmse_um: members[i].2,
        uncompensated_um: zero,
        fallback: why,
    };
    let mode = std::env::var("TRUEPOS_SEL").unwrap_or_default();
    if mode == "single" {
        let b = (0..members.len()).min_by(|&a, &b| members[a].2.total_cmp(&members[b].2)).unwrap();
        return single(b, None);
    }
    if score > CLEARLY_BETTER * zero {
        return none(format!(
            "no compensation: the best blend's inner-validation RMSE {score:.3} µm is not clearly below no compensation's {zero:.3} µm"
        ));
    }
    if let Some(s) = members.iter().position(|m| m.0 == Family::Static) {
        if members[s].2 <= CLEARLY_BETTER * score {
            return single(
                s,
                Some(format!(
                    "static: its inner-validation RMSE {:.3} µm is clearly below the blend's {score:.3} µm (the blend's weights do not hold up out of fold)",
                    members[s].2
                )),
            );
        }
    }
    let chosen: Vec<Member> = members
        .iter()
        .zip(&w)
        .filter(|(_, &wm)| wm > 0.0)
        .map(|(m, &wm)| Member {
            family: m.0,
            ridge: m.1,
            weight: wm,
            cv_rmse_um: m.2,
            tau_s: None,
        })
        .collect();
    if chosen.is_empty() {
        return none("no compensation: every family's weight is zero".into());
    }
    Pick {
        members: chosen,
        cv_rmse_um: score,
        uncompensated_um: zero,
        fallback: None,
    }
}

/// A design fitted on every training row (each member of the final blend once).
pub(crate) fn fit_all(p: &Problem<'_>, d: &Design, ridge: f64) -> Result<crate::least_squares::Solution, String> {
    p.accumulate(d, 0..p.x.nrows())
        .finish()
        .solve(&SolveOptions {
            ridge,
            unpenalized: vec![0],
            rcond: None,
        })
        .map_err(|e| e.to_string())
}
