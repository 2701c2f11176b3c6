//! The automatic selection of one target's model: every family scored by the gap-separated inner
//! validation ([`crate::inner_cv`]), its ridge chosen within the family, the families combined
//! by their out-of-fold predictions ([`crate::stacking`]), and a guard: no compensation when the
//! blend is not clearly better than none, and — when the static family is among the candidates
//! (named with `--family`; not a default) — the static model alone when the blend is not clearly
//! better than it ([`CLEARLY_BETTER`]); each fallback is a warning naming the figures.

use crate::features::Family;
use crate::least_squares::Triangle;
use crate::problem::{Design, Problem};
use crate::settings::{Rule, Settings};
use crate::stacking;
use crate::train::FamilyScore;

/// A blend must beat "no compensation" — and, when the static family is a candidate (named
/// with `--family`; not a default), the static model — by this factor in the inner
/// validation (RMSE ratio) to be written: a model that removes less than a tenth of the error
/// is not worth an axis' risk, a dynamic blend that is not a tenth better than the static model
/// does not earn the extrapolation risk of its filters, and the inner estimate itself (its
/// weights fitted on the same out-of-fold predictions) is uncertain by about that much.
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
    /// The identified time constant of the transfer family (s); τ1 of the second-order one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_s: Option<f64>,
    /// τ2 of the second-order transfer family (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau2_s: Option<f64>,
}

/// A family's candidacy for one target: (family, ridge, inner RMSE µm, held-out predictions).
type Candidate = (Family, f64, f64, Vec<f64>);

/// What the selection chose for one target.
#[derive(Debug, Clone, PartialEq)]
pub struct Pick {
    /// The members with a weight above zero (empty: no compensation).
    pub members: Vec<Member>,
    /// The inner-validation RMSE of the pick itself, its weights fitted out of fold (µm): here
    /// on the blocked folds that chose it; [`crate::train::train`] reports its forward
    /// evaluation instead (the `forward` module).
    pub cv_rmse_um: f64,
    /// The inner-validation RMSE of no compensation (µm), on the same rows.
    pub uncompensated_um: f64,
    /// Why the pick is not the blend, if it is not.
    pub fallback: Option<String>,
}

/// The inner validation of one design: per ridge, per target, the RMSE over all held-out rows
/// with the standard error of the per-fold RMSEs; and each fold's triangle, to predict the
/// held-out rows again at the one ridge kept.
pub(crate) struct FamilyCv {
    pub scores: Vec<Vec<(f64, f64)>>,
    tris: Vec<Triangle>,
}

impl FamilyCv {
    /// Target `k`'s held-out predictions at `ridge`, in the held triangles' coordinates
    /// ([`Problem::held_prediction`], folds concatenated).
    fn predictions(&self, p: &Problem<'_>, d: &Design, k: usize, ridge: f64) -> Vec<f64> {
        let opts = d.solve_options(ridge);
        let mut out = Vec::with_capacity(p.folds.folds.len() * p.held_width());
        for (f, tri) in self.tris.iter().enumerate() {
            match tri.solve(&opts) {
                Ok(sol) => out.extend(p.held_prediction(f, d, &sol.coefficients[k])),
                Err(_) => out.extend(std::iter::repeat_n(f64::INFINITY, p.held_width())),
            }
        }
        out
    }
}

/// Scores a design by the problem's folds: each fold's model from its training triangle, its
/// squared errors from its held-out triangle.
pub(crate) fn cv(p: &Problem<'_>, d: &Design, ridges: &[f64]) -> FamilyCv {
    let nt = p.nt;
    let folds = &p.folds;
    let held_n = folds.held_rows();
    let mut sse = vec![vec![vec![0.0; folds.folds.len()]; nt]; ridges.len()];
    let mut tris = Vec::with_capacity(folds.folds.len());
    for f in 0..folds.folds.len() {
        let tri = p.design_triangle(d, Some(f));
        for (ri, &ridge) in ridges.iter().enumerate() {
            let sol = tri.solve(&d.solve_options(ridge)).ok();
            for (k, per_fold) in sse[ri].iter_mut().enumerate() {
                per_fold[f] = match &sol {
                    Some(sol) => p.held_sse(f, d, &sol.coefficients[k], k),
                    None => f64::INFINITY,
                };
            }
        }
        tris.push(tri);
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
    FamilyCv { scores, tris }
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
    let nt = p.nt;
    let reference = p.reference(settings);
    // Per target, the candidate members: (family, ridge, rmse, held-out predictions).
    let mut members: Vec<Vec<Candidate>> = vec![Vec::new(); nt];
    let mut families = Vec::new();
    for &family in &settings.families {
        let Some(design) = p.design(family, sensors, reference) else {
            continue;
        };
        let fam = cv(p, &design, &settings.ridges);
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
                let pred = fam.predictions(p, &design, k, settings.ridges[ri]);
                members[k].push((family, settings.ridges[ri], rmse, pred));
            }
        }
        families.push(FamilyScore { family, per_target });
    }
    let held = p.held_targets();
    let n = p.folds.held_rows();
    let picks = (0..nt)
        .map(|k| {
            let mut pick = if settings.families.len() == 1 && members[k].len() == 1 {
                as_given(&members[k][0], &held[k], n)
            } else {
                pick(&members[k], &held[k], n)
            };
            for m in &mut pick.members {
                let taus = p.transfer.of(m.family);
                (m.tau_s, m.tau2_s) = (taus.first().copied(), taus.get(1).copied());
            }
            pick
        })
        .collect();
    (picks, families)
}

/// One family named by the user is fitted as it is: nothing to blend, nothing to guard.
fn as_given(m: &Candidate, y: &[f64], n: usize) -> Pick {
    Pick {
        members: vec![Member {
            family: m.0,
            ridge: m.1,
            weight: 1.0,
            cv_rmse_um: m.2,
            tau_s: None,
            tau2_s: None,
        }],
        cv_rmse_um: m.2,
        uncompensated_um: rmse_over(y, None, n),
        fallback: None,
    }
}

/// Blend, guard and fallback for one target.
fn pick(members: &[Candidate], y: &[f64], n: usize) -> Pick {
    let zero = rmse_over(y, None, n);
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
    let score = rmse_over(y, Some(&blended), n);
    if score > CLEARLY_BETTER * zero {
        return none(format!(
            "no compensation: the blend's blocked inner-validation RMSE {score:.3} µm is not clearly below no compensation's {zero:.3} µm"
        ));
    }
    if let Some(s) = members.iter().position(|m| m.0 == Family::Static) {
        if score > CLEARLY_BETTER * members[s].2 {
            return Pick {
                members: vec![Member {
                    family: Family::Static,
                    ridge: members[s].1,
                    weight: 1.0,
                    cv_rmse_um: members[s].2,
                    tau_s: None,
                    tau2_s: None,
                }],
                cv_rmse_um: members[s].2,
                uncompensated_um: zero,
                fallback: Some(format!(
                    "static: the blend's blocked inner-validation RMSE {score:.3} µm is not clearly below the static model's {:.3} µm",
                    members[s].2
                )),
            };
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
            tau2_s: None,
        })
        .collect();
    Pick {
        members: chosen,
        cv_rmse_um: score,
        uncompensated_um: zero,
        fallback: None,
    }
}

/// The RMSE of `b` (zero if `None`) as a prediction of `a` over `n` rows. `a` and `b` may be the
/// rows themselves or their coordinates in a triangle ([`Problem::held_prediction`]): both
/// give the same sum of squares, only `n` counts the rows.
fn rmse_over(a: &[f64], b: Option<&[f64]>, n: usize) -> f64 {
    let sum: f64 = match b {
        Some(b) => a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum(),
        None => a.iter().map(|x| x * x).sum(),
    };
    (sum / n.max(1) as f64).sqrt()
}

/// A design fitted on every training row (each member of the final blend once).
pub(crate) fn fit_all(
    p: &Problem<'_>,
    d: &Design,
    ridge: f64,
) -> Result<crate::least_squares::Solution, String> {
    p.design_triangle(d, None)
        .solve(&d.solve_options(ridge))
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn member(family: Family, rmse: f64, pred: Vec<f64>) -> Candidate {
        (family, 1e-3, rmse, pred)
    }

    #[test]
    fn a_good_blend_is_kept_and_its_weights_sum_to_at_most_one() {
        let y: Vec<f64> = (0..100).map(|i| (i as f64 / 9.0).sin() * 5.0).collect();
        let good: Vec<f64> = y.iter().map(|v| 0.95 * v).collect();
        let flat = vec![0.5; 100];
        let p = pick(
            &[
                member(Family::Static, 3.0, flat),
                member(Family::Dynamic, 0.2, good),
            ],
            &y,
            y.len(),
        );
        assert_eq!(p.fallback, None);
        assert_eq!(p.members.len(), 1);
        assert_eq!(p.members[0].family, Family::Dynamic);
        assert!(p.members[0].weight <= 1.0 + 1e-12);
        assert!(p.cv_rmse_um < 0.3 && p.uncompensated_um > 3.0);
    }

    #[test]
    fn nothing_clearly_better_than_none_gives_no_compensation() {
        let y: Vec<f64> = (0..100).map(|i| (i as f64 / 9.0).sin()).collect();
        let noise: Vec<f64> = (0..100)
            .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5)
            .collect();
        let p = pick(&[member(Family::Dynamic, 1.2, noise)], &y, y.len());
        assert!(p.members.is_empty());
        assert!(p.fallback.unwrap().starts_with("no compensation"));
    }

    #[test]
    fn a_blend_hardly_better_than_static_falls_back_to_static() {
        let y: Vec<f64> = (0..100).map(|i| (i as f64 / 9.0).sin() * 5.0).collect();
        let stat: Vec<f64> = y.iter().map(|v| 0.8 * v).collect();
        let dynamic: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(i, v)| 0.81 * v + 0.001 * (i % 3) as f64)
            .collect();
        let static_rmse = stacking::rmse(&y, &stat);
        let p = pick(
            &[
                member(Family::Static, static_rmse, stat),
                member(Family::Dynamic, 0.9, dynamic),
            ],
            &y,
            y.len(),
        );
        assert_eq!(p.members.len(), 1);
        assert_eq!(p.members[0].family, Family::Static);
        assert!(p.fallback.unwrap().starts_with("static"));
    }
}
