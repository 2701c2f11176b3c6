//! The default selection ([`Selection::Blend`](crate::settings::Selection::Blend)): every
//! family's out-of-fold predictions at its ridge combined by their honest validation
//! ([`crate::stacking`]), and a guard: no compensation when the blend is not clearly better than
//! none, and — when the static family is among the candidates (named with `--family`; not a
//! default) — the static model alone when the blend is not clearly better than it
//! ([`CLEARLY_BETTER`]); each fallback is a warning naming the figures.

use crate::features::Family;
use crate::selection::{rmse_over, Member, Pick, CLEARLY_BETTER};
use crate::stacking;

/// A family's candidacy for one target: (family, ridge, inner RMSE µm, held-out predictions).
pub(crate) type Blendable = (Family, f64, f64, Vec<f64>);

/// One family named by the user is fitted as it is: nothing to blend, nothing to guard.
pub(crate) fn as_given(m: &Blendable, y: &[f64], n: usize) -> Pick {
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
        baseline_cv_rmse_um: None,
        paired: None,
        fallback: None,
    }
}

/// Blend, guard and fallback for one target.
pub(crate) fn pick(members: &[Blendable], y: &[f64], n: usize) -> Pick {
    let zero = rmse_over(y, None, n);
    let none = |reason: String| Pick {
        members: Vec::new(),
        cv_rmse_um: zero,
        uncompensated_um: zero,
        baseline_cv_rmse_um: None,
        paired: None,
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
                baseline_cv_rmse_um: None,
                paired: None,
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
        baseline_cv_rmse_um: None,
        paired: None,
        fallback: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn member(family: Family, rmse: f64, pred: Vec<f64>) -> Blendable {
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
