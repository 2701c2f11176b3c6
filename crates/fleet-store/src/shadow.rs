//! The judgement of a model run in shadow, and of a model just activated, on probe residuals
//! (docs/fleet.md, "The service follows the store"). Pure: the numbers in, a decision out.
//!
//! A *residual* is one axis of one accepted probe event: measured − predicted (µm), the
//! measured error being actual − nominal and a model predicting that error (the sign of
//! `truepos reidentify` and of the service's probe log). Each [`Pair`] holds one measurement
//! with the predictions of the two models compared on it.
//!
//! - [`judge_shadow`]: with at least [`Rule::min_probes`] residuals, a shadow whose RMS
//!   residual is below `(1 − margin)` × the active model's on the same probes is activated;
//!   one that has not got there by `2 × min_probes` residuals is retired.
//! - [`judge_rollback`]: after an activation, with at least `min_probes` residuals, the new
//!   model is rolled back when its RMS residual exceeds `(1 + margin)` × its parent's on the
//!   same probes, else kept — a decision either way: the watch of the new model ends there
//!   (`truepos fleet follow` evaluates its parent no further).
//!
//! ```
//! use truepos_fleet_store::shadow::{judge_shadow, Pair, Rule, ShadowDecision};
//! let rule = Rule { min_probes: 2, margin: 0.1 };
//! // The active model predicts 0, the shadow 9: measured 10 and 10.
//! let p = Pair { measured_um: 10.0, active_um: 0.0, other_um: 9.0 };
//! assert!(matches!(judge_shadow(&rule, &[p, p]), ShadowDecision::Activate(_)));
//! ```

/// The rule's two numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rule {
    /// Residuals (probe events × measured axes) needed before anything is decided.
    pub min_probes: usize,
    /// Relative margin: a shadow must be below `(1 − margin)` × the active model's RMS; a new
    /// model is rolled back above `(1 + margin)` × its parent's.
    pub margin: f64,
}

impl Rule {
    /// The defaults of `truepos fleet follow`: 8 residuals, 10 %.
    pub const DEFAULT: Rule = Rule {
        min_probes: 8,
        margin: 0.1,
    };

    /// Refuses a rule that cannot decide: no residual needed, or a margin outside [0, 1).
    pub fn check(&self) -> Result<(), String> {
        if self.min_probes == 0 || self.min_probes > 1_000_000 {
            return Err(format!("min-probes {}: give 1 to 1000000", self.min_probes));
        }
        if !(self.margin.is_finite() && (0.0..1.0).contains(&self.margin)) {
            return Err(format!("margin {}: give 0 to below 1", self.margin));
        }
        Ok(())
    }
}

/// One residual's numbers: the measured error and two predictions of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Measured error, actual − nominal (µm).
    pub measured_um: f64,
    /// What the model the service ran predicted (its log's `predicted_d<axis>_um`).
    pub active_um: f64,
    /// What the other model predicts at the same inputs: the shadow, or after an activation
    /// the parent.
    pub other_um: f64,
}

/// RMS residuals of both models over the same measurements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    /// Residuals counted (pairs with a non-finite number are left out).
    pub n: usize,
    /// RMS of measured − active (µm).
    pub active_rms_um: f64,
    /// RMS of measured − other (µm).
    pub other_rms_um: f64,
}

/// RMS of measured − prediction for both models; pairs with a NaN or ∞ are left out.
pub fn figures(pairs: &[Pair]) -> Figures {
    let (mut n, mut a, mut o) = (0usize, 0.0, 0.0);
    for p in pairs {
        let ra = p.measured_um - p.active_um;
        let ro = p.measured_um - p.other_um;
        if ra.is_finite() && ro.is_finite() {
            n += 1;
            a += ra * ra;
            o += ro * ro;
        }
    }
    let rms = |s: f64| {
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    };
    Figures {
        n,
        active_rms_um: rms(a),
        other_rms_um: rms(o),
    }
}

impl std::fmt::Display for Figures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} residuals: RMS {:.3} µm (active) vs {:.3} µm",
            self.n, self.active_rms_um, self.other_rms_um
        )
    }
}

/// What to do with a shadow model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ShadowDecision {
    /// Too few residuals yet, or better but not by the margin with fewer than twice the
    /// minimum: keep shadowing.
    Wait(Figures),
    /// Better than the active model by the margin: activate it.
    Activate(Figures),
    /// Not better by the margin after twice the minimum: retire it.
    Retire(Figures),
}

/// The shadow rule on the residuals since the shadow arrived (`other` = the shadow).
pub fn judge_shadow(rule: &Rule, pairs: &[Pair]) -> ShadowDecision {
    let f = figures(pairs);
    if f.n < rule.min_probes {
        return ShadowDecision::Wait(f);
    }
    if f.other_rms_um < (1.0 - rule.margin) * f.active_rms_um {
        ShadowDecision::Activate(f)
    } else if f.n >= 2 * rule.min_probes {
        ShadowDecision::Retire(f)
    } else {
        ShadowDecision::Wait(f)
    }
}

/// What to do with a model just activated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WatchDecision {
    /// Too few residuals yet.
    Wait(Figures),
    /// Not worse than its parent by the margin: keep it; the watch ends.
    Keep(Figures),
    /// Worse than its parent by the margin: roll back.
    Rollback(Figures),
}

/// The rollback rule on the residuals since the activation (`active` = the new model, `other`
/// = its parent).
pub fn judge_rollback(rule: &Rule, pairs: &[Pair]) -> WatchDecision {
    let f = figures(pairs);
    if f.n < rule.min_probes {
        WatchDecision::Wait(f)
    } else if f.active_rms_um > (1.0 + rule.margin) * f.other_rms_um {
        WatchDecision::Rollback(f)
    } else {
        WatchDecision::Keep(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RULE: Rule = Rule {
        min_probes: 4,
        margin: 0.1,
    };

    /// `n` pairs: measured 10, the active model 10 − `active_off`, the other 10 − `other_off`.
    fn pairs(n: usize, active_off: f64, other_off: f64) -> Vec<Pair> {
        vec![
            Pair {
                measured_um: 10.0,
                active_um: 10.0 - active_off,
                other_um: 10.0 - other_off,
            };
            n
        ]
    }

    #[test]
    fn rms_leaves_out_what_is_not_a_number() {
        let mut p = pairs(2, 3.0, 4.0);
        p.push(Pair {
            measured_um: f64::NAN,
            ..p[0]
        });
        p.push(Pair {
            other_um: f64::INFINITY,
            ..p[0]
        });
        let f = figures(&p);
        assert_eq!(f.n, 2);
        assert!((f.active_rms_um - 3.0).abs() < 1e-12);
        assert!((f.other_rms_um - 4.0).abs() < 1e-12);
        // RMS, not the mean: residuals 3 and −4 give 3.536.
        let mixed = [
            Pair {
                measured_um: 3.0,
                active_um: 0.0,
                other_um: 0.0,
            },
            Pair {
                measured_um: -4.0,
                active_um: 0.0,
                other_um: 0.0,
            },
        ];
        assert!((figures(&mixed).active_rms_um - 12.5f64.sqrt()).abs() < 1e-12);
        assert!(figures(&[]).active_rms_um.is_nan());
    }

    #[test]
    fn a_shadow_waits_for_the_minimum() {
        assert!(matches!(
            judge_shadow(&RULE, &pairs(3, 5.0, 0.1)),
            ShadowDecision::Wait(f) if f.n == 3
        ));
        assert!(matches!(
            judge_shadow(&RULE, &[]),
            ShadowDecision::Wait(f) if f.n == 0
        ));
    }

    #[test]
    fn a_shadow_better_by_the_margin_is_activated() {
        assert!(matches!(
            judge_shadow(&RULE, &pairs(4, 5.0, 1.0)),
            ShadowDecision::Activate(_)
        ));
        // 4.4 < 0.9 × 5 = 4.5.
        assert!(matches!(
            judge_shadow(&RULE, &pairs(4, 5.0, 4.4)),
            ShadowDecision::Activate(_)
        ));
    }

    #[test]
    fn a_shadow_better_but_not_by_the_margin_waits_then_is_retired() {
        // 4.6 ≥ 4.5: not by the margin.
        assert!(matches!(
            judge_shadow(&RULE, &pairs(4, 5.0, 4.6)),
            ShadowDecision::Wait(_)
        ));
        assert!(matches!(
            judge_shadow(&RULE, &pairs(7, 5.0, 4.6)),
            ShadowDecision::Wait(_)
        ));
        assert!(matches!(
            judge_shadow(&RULE, &pairs(8, 5.0, 4.6)),
            ShadowDecision::Retire(f) if f.n == 8
        ));
    }

    #[test]
    fn a_worse_shadow_is_retired_after_twice_the_minimum() {
        assert!(matches!(
            judge_shadow(&RULE, &pairs(5, 1.0, 3.0)),
            ShadowDecision::Wait(_)
        ));
        assert!(matches!(
            judge_shadow(&RULE, &pairs(8, 1.0, 3.0)),
            ShadowDecision::Retire(_)
        ));
        // A perfect active model cannot be beaten: 0 < 0.9 × 0 is false.
        assert!(matches!(
            judge_shadow(&RULE, &pairs(8, 0.0, 0.0)),
            ShadowDecision::Retire(_)
        ));
    }

    #[test]
    fn a_new_model_worse_by_the_margin_is_rolled_back() {
        assert!(matches!(
            judge_rollback(&RULE, &pairs(3, 9.0, 1.0)),
            WatchDecision::Wait(_)
        ));
        assert!(matches!(
            judge_rollback(&RULE, &pairs(4, 9.0, 1.0)),
            WatchDecision::Rollback(f) if f.n == 4
        ));
        // 1.11 > 1.1 × 1.
        assert!(matches!(
            judge_rollback(&RULE, &pairs(4, 1.11, 1.0)),
            WatchDecision::Rollback(_)
        ));
    }

    #[test]
    fn a_new_model_within_the_margin_is_kept() {
        assert!(matches!(
            judge_rollback(&RULE, &pairs(4, 1.09, 1.0)),
            WatchDecision::Keep(_)
        ));
        assert!(matches!(
            judge_rollback(&RULE, &pairs(40, 0.5, 1.0)),
            WatchDecision::Keep(_)
        ));
        // Both perfect: kept.
        assert!(matches!(
            judge_rollback(&RULE, &pairs(4, 0.0, 0.0)),
            WatchDecision::Keep(_)
        ));
    }

    #[test]
    fn rules_that_cannot_decide_are_refused() {
        assert!(RULE.check().is_ok());
        assert!(Rule::DEFAULT.check().is_ok());
        for bad in [
            Rule {
                min_probes: 0,
                ..RULE
            },
            Rule {
                margin: 1.0,
                ..RULE
            },
            Rule {
                margin: -0.1,
                ..RULE
            },
            Rule {
                margin: f64::NAN,
                ..RULE
            },
        ] {
            assert!(bad.check().is_err(), "{bad:?}");
        }
    }
}
