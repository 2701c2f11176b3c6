//! The automatic selection of one target's model. Every family is scored by the same
//! gap-separated inner folds ([`crate::inner_cv`]); the simple baseline ([`Family::Baseline`]:
//! the temperature rises and the operating state at a small fixed ridge, [`BASELINE_RIDGE`]) is
//! always fitted beside them and its figure reported. Two ways to decide
//! ([`crate::settings::Selection`]):
//!
//! - **`blend`** (the default, in the module `blend`): every family's ridge by the rule, the families
//!   blended by their out-of-fold predictions, guarded against no compensation.
//! - **`paired`**: the best richer candidate (lowest pooled inner RMSE, its ridge from a short
//!   grid) replaces the baseline only when it is better fold by fold — lower RMSE on more than
//!   half of the held-out blocks, and a mean gain above [`MARGIN_SE`] standard errors of the
//!   per-fold gains. Differences between blocks (a loud run, a quiet one) are the same for both
//!   models and cancel in the pairs; what is left is the evidence that the extra lags, rates
//!   and operating terms earn their extrapolation risk. Then the guard against no compensation
//!   ([`CLEARLY_BETTER`]).

use crate::blend::Blendable;
use crate::features::Family;
use crate::least_squares::Triangle;
use crate::problem::{Design, Problem};
use crate::settings::{Rule, Selection, Settings};
use crate::train::FamilyScore;

/// The model kept must beat "no compensation" by this factor in the inner validation (RMSE
/// ratio) to be written: a model that removes less than a tenth of the error is not worth an
/// axis' risk.
pub const CLEARLY_BETTER: f64 = 0.9;

/// The baseline's ridge, relative to each column's own norm: a whisper that keeps collinear
/// sensors solvable without shrinking a real gain (on a column of unit norm, λ = 10⁻³ shrinks
/// its coefficient by 0.1 %).
pub const BASELINE_RIDGE: f64 = 1e-3;

/// A richer candidate must gain more than this many standard errors of its per-fold gains over
/// the baseline: about a one-sided 5 % paired test at the usual 5 to 10 folds — the candidate
/// was the best of many, so a lucky one must not pass on a coin flip.
pub const MARGIN_SE: f64 = 2.0;

/// One member of a blend (the paired selection keeps one, of weight 1).
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

/// The paired comparison of the best richer candidate with the baseline, over the inner folds.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Paired {
    /// The richer candidate compared.
    pub family: Family,
    /// Its ridge.
    pub ridge: f64,
    /// Held-out blocks compared.
    pub folds: usize,
    /// Blocks where the candidate's RMSE is below the baseline's.
    pub wins: usize,
    /// Mean over the blocks of (baseline RMSE − candidate RMSE), µm: positive, the candidate
    /// is better.
    pub mean_gain_um: f64,
    /// The standard error of that mean (µm).
    pub se_um: f64,
    /// Whether the candidate replaced the baseline.
    pub accepted: bool,
}

impl Paired {
    /// In words, for the screen and reports.
    pub fn describe(&self) -> String {
        format!(
            "{} beat the baseline on {} of {} inner folds, by {:.3} ± {:.3} µm: {}",
            self.family,
            self.wins,
            self.folds,
            self.mean_gain_um,
            self.se_um,
            if self.accepted {
                "kept"
            } else {
                "not clearly, the baseline is kept"
            }
        )
    }
}

/// A candidate for one target: its family, ridge, pooled inner RMSE and RMSE per fold (µm).
#[derive(Debug, Clone)]
struct Candidate {
    family: Family,
    ridge: f64,
    rmse: f64,
    per_fold: Vec<f64>,
}

/// What the selection chose for one target.
#[derive(Debug, Clone, PartialEq)]
pub struct Pick {
    /// The members with a weight above zero (empty: no compensation).
    pub members: Vec<Member>,
    /// The inner-validation RMSE of the pick (µm): here on the blocked folds that chose it;
    /// [`crate::train::train`] reports its forward evaluation instead (the `forward` module).
    pub cv_rmse_um: f64,
    /// The inner-validation RMSE of no compensation (µm), on the same rows.
    pub uncompensated_um: f64,
    /// The baseline's inner-validation RMSE (µm), when it could be built.
    pub baseline_cv_rmse_um: Option<f64>,
    /// The comparison that decided between the baseline and the best richer candidate.
    pub paired: Option<Paired>,
    /// Why the pick is not the blend (no compensation, or static alone), if it is not.
    pub fallback: Option<String>,
}

/// The inner validation of one design: per ridge, per target, the RMSE over all held-out rows
/// with the standard error of the per-fold RMSEs, and the RMSE of every fold; and each fold's
/// triangle, to predict the held-out rows again at the one ridge kept.
pub(crate) struct FamilyCv {
    pub scores: Vec<Vec<(f64, f64)>>,
    pub per_fold: Vec<Vec<Vec<f64>>>,
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
    let per_fold: Vec<Vec<Vec<f64>>> = sse
        .iter()
        .map(|per_target| {
            per_target
                .iter()
                .map(|per_fold| {
                    per_fold
                        .iter()
                        .zip(&folds.folds)
                        .map(|(s, fold)| (s / fold.held.len().max(1) as f64).sqrt())
                        .collect()
                })
                .collect()
        })
        .collect();
    let scores = sse
        .iter()
        .zip(&per_fold)
        .map(|(per_target, rmses)| {
            per_target
                .iter()
                .zip(rmses)
                .map(|(per_fold, rmse)| {
                    let total: f64 = per_fold.iter().sum();
                    let m = rmse.iter().sum::<f64>() / used;
                    let var =
                        rmse.iter().map(|r| (r - m).powi(2)).sum::<f64>() / (used - 1.0).max(1.0);
                    ((total / held_n.max(1) as f64).sqrt(), (var / used).sqrt())
                })
                .collect()
        })
        .collect();
    FamilyCv {
        scores,
        per_fold,
        tris,
    }
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
    let mut richer: Vec<Vec<Candidate>> = vec![Vec::new(); nt];
    let mut blendable: Vec<Vec<Blendable>> = vec![Vec::new(); nt];
    let mut families = Vec::new();
    for &family in settings.families.iter().filter(|&&f| f != Family::Baseline) {
        let Some(design) = p.design(family, sensors, reference) else {
            continue;
        };
        let (score, fam, kept) = scored(p, family, &design, &settings.ridges, settings.rule);
        families.push(score);
        for (k, c) in kept.into_iter().enumerate() {
            let Some(c) = c else { continue };
            if settings.selection == Selection::Blend {
                let pred = fam.predictions(p, &design, k, c.ridge);
                blendable[k].push((c.family, c.ridge, c.rmse, pred));
            }
            richer[k].push(c);
        }
    }
    let baseline: Vec<Option<Candidate>> = match p.design(Family::Baseline, sensors, None) {
        Some(design) => {
            let (score, _, kept) = scored(
                p,
                Family::Baseline,
                &design,
                &[BASELINE_RIDGE],
                settings.rule,
            );
            families.push(score);
            kept
        }
        None => vec![None; nt],
    };
    let held = p.held_targets();
    let n = p.folds.held_rows();
    let alone = settings.families.len() == 1;
    let picks = (0..nt)
        .map(|k| {
            let zero = rmse_over(&held[k], None, n);
            let base = baseline[k].as_ref();
            let mut pick = match settings.selection {
                Selection::Paired => pick(&richer[k], base, zero, alone),
                Selection::Blend if alone && blendable[k].len() == 1 => {
                    crate::blend::as_given(&blendable[k][0], &held[k], n)
                }
                Selection::Blend if alone && base.is_some() && richer[k].is_empty() => {
                    pick(&[], base, zero, true)
                }
                Selection::Blend => crate::blend::pick(&blendable[k], &held[k], n),
            };
            pick.baseline_cv_rmse_um = base.map(|b| b.rmse);
            for m in &mut pick.members {
                let taus = p.transfer.of(m.family);
                (m.tau_s, m.tau2_s) = (taus.first().copied(), taus.get(1).copied());
            }
            pick
        })
        .collect();
    (picks, families)
}

/// A family's inner validation over `ridges`: its figures, and per target the candidate at the
/// ridge the rule keeps (`None` if no fold could be fitted).
fn scored(
    p: &Problem<'_>,
    family: Family,
    design: &Design,
    ridges: &[f64],
    rule: Rule,
) -> (FamilyScore, FamilyCv, Vec<Option<Candidate>>) {
    let fam = cv(p, design, ridges);
    let mut per_target = vec![(f64::INFINITY, 0.0); p.nt];
    let mut kept = Vec::with_capacity(p.nt);
    for k in 0..p.nt {
        for (ri, row) in fam.scores.iter().enumerate() {
            if row[k].0 < per_target[k].0 {
                per_target[k] = (row[k].0, ridges[ri]);
            }
        }
        let ri = ridge_index(&fam.scores, ridges, k, rule);
        let rmse = fam.scores[ri][k].0;
        kept.push(rmse.is_finite().then(|| Candidate {
            family,
            ridge: ridges[ri],
            rmse,
            per_fold: fam.per_fold[ri][k].clone(),
        }));
    }
    (FamilyScore { family, per_target }, fam, kept)
}

/// [`Selection::Paired`]: baseline, best richer candidate, paired comparison and guard for one
/// target (`zero`: the
/// inner RMSE of no compensation). `alone`: one family was named, and is fitted as it is.
fn pick(richer: &[Candidate], baseline: Option<&Candidate>, zero: f64, alone: bool) -> Pick {
    let best = richer.iter().min_by(|a, b| a.rmse.total_cmp(&b.rmse));
    let paired = match (best, baseline) {
        (Some(c), Some(b)) if !alone => Some(compare(c, b)),
        _ => None,
    };
    let kept = match (best, baseline) {
        (Some(c), _) if alone => Some(c),
        (Some(c), Some(_)) if paired.is_some_and(|p| p.accepted) => Some(c),
        (_, Some(b)) => Some(b),
        (c, None) => c,
    };
    let mut out = Pick {
        members: Vec::new(),
        cv_rmse_um: zero,
        uncompensated_um: zero,
        baseline_cv_rmse_um: baseline.map(|b| b.rmse),
        paired,
        fallback: None,
    };
    let Some(kept) = kept else {
        out.fallback = Some("no family could be fitted: no compensation".into());
        return out;
    };
    if !alone && kept.rmse > CLEARLY_BETTER * zero {
        out.fallback = Some(format!(
            "no compensation: the {} model's blocked inner-validation RMSE {:.3} µm is not clearly below no compensation's {zero:.3} µm",
            kept.family, kept.rmse
        ));
        return out;
    }
    out.members = vec![Member {
        family: kept.family,
        ridge: kept.ridge,
        weight: 1.0,
        cv_rmse_um: kept.rmse,
        tau_s: None,
        tau2_s: None,
    }];
    out.cv_rmse_um = kept.rmse;
    out
}

/// The paired comparison of `c` with the baseline `b` over the folds both scored.
fn compare(c: &Candidate, b: &Candidate) -> Paired {
    let gains: Vec<f64> = b
        .per_fold
        .iter()
        .zip(&c.per_fold)
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(x, y)| x - y)
        .collect();
    let folds = gains.len();
    let wins = gains.iter().filter(|&&g| g > 0.0).count();
    let f = folds.max(1) as f64;
    let mean = gains.iter().sum::<f64>() / f;
    let var = gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (f - 1.0).max(1.0);
    let se = (var / f).sqrt();
    Paired {
        family: c.family,
        ridge: c.ridge,
        folds,
        wins,
        mean_gain_um: mean,
        se_um: se,
        accepted: folds >= 2 && 2 * wins > folds && mean > MARGIN_SE * se && c.rmse < b.rmse,
    }
}

/// The RMSE of `b` (zero if `None`) as a prediction of `a` over `n` rows. `a` and `b` may be the
/// rows themselves or their coordinates in a triangle ([`Problem::held_prediction`]): both
/// give the same sum of squares, only `n` counts the rows.
pub(crate) fn rmse_over(a: &[f64], b: Option<&[f64]>, n: usize) -> f64 {
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

    fn candidate(family: Family, per_fold: &[f64]) -> Candidate {
        let n = per_fold.len() as f64;
        Candidate {
            family,
            ridge: 1e-3,
            rmse: (per_fold.iter().map(|r| r * r).sum::<f64>() / n).sqrt(),
            per_fold: per_fold.to_vec(),
        }
    }

    #[test]
    fn a_candidate_better_on_every_fold_replaces_the_baseline() {
        let base = candidate(Family::Baseline, &[2.0, 3.0, 1.5, 2.5, 4.0, 2.0]);
        let dynamic = candidate(Family::Dynamic, &[1.0, 2.1, 0.9, 1.4, 3.2, 1.1]);
        let p = pick(&[dynamic], Some(&base), 10.0, false);
        assert_eq!(p.members.len(), 1);
        assert_eq!(p.members[0].family, Family::Dynamic);
        let paired = p.paired.unwrap();
        assert_eq!((paired.wins, paired.folds, paired.accepted), (6, 6, true));
        assert!((paired.mean_gain_um - 0.8833333).abs() < 1e-6, "{paired:?}");
        assert_eq!(p.baseline_cv_rmse_um, Some(base.rmse));
    }

    /// Better pooled, better on most folds, but by a gain the folds' spread does not support:
    /// one large win among small losses. The baseline stays.
    #[test]
    fn a_gain_the_spread_does_not_support_keeps_the_baseline() {
        let base = candidate(Family::Baseline, &[2.0, 2.0, 2.0, 2.0, 9.0]);
        let lucky = candidate(Family::DynamicRates, &[2.1, 1.9, 1.95, 2.05, 4.0]);
        assert!(lucky.rmse < base.rmse);
        let p = pick(&[lucky], Some(&base), 10.0, false);
        assert_eq!(p.members[0].family, Family::Baseline);
        let paired = p.paired.unwrap();
        assert!(!paired.accepted);
        assert!(paired.mean_gain_um < MARGIN_SE * paired.se_um, "{paired:?}");
        assert!(paired.describe().contains("baseline is kept"));
        // A majority of wins is needed too: one fold's gain alone never decides.
        let one = candidate(Family::Dynamic, &[2.2, 2.2, 2.2, 2.2, 1.0]);
        let p = pick(&[one], Some(&base), 10.0, false);
        assert_eq!(p.members[0].family, Family::Baseline);
    }

    #[test]
    fn nothing_clearly_better_than_none_gives_no_compensation() {
        let base = candidate(Family::Baseline, &[1.0, 0.95, 1.0]);
        let p = pick(&[], Some(&base), 1.0, false);
        assert!(p.members.is_empty());
        assert!(p.fallback.unwrap().starts_with("no compensation"));
    }

    #[test]
    fn a_family_named_alone_is_fitted_as_given() {
        let base = candidate(Family::Baseline, &[1.0, 1.0, 1.0]);
        let stat = candidate(Family::Static, &[3.0, 3.0, 3.0]);
        let p = pick(&[stat], Some(&base), 2.0, true);
        assert_eq!(p.members[0].family, Family::Static);
        assert_eq!((p.paired, p.fallback), (None, None));
    }
}
