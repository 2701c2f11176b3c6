//! What a fit may choose from and how it chooses — family, ridge, inner cross-validation,
//! selection rule, sensors, reference sensor — as typed values. Each value a person types has a
//! [`FromStr`] whose error says what was expected, so the command line (as clap value parsers),
//! scripts and tests read them the same way; lists are comma-separated ([`crate::family::Families`],
//! [`Ridges`]). The outer validation protocol is [`crate::validate::Split`].

use std::fmt;
use std::str::FromStr;

use crate::features::{Family, TimeConstants};

/// What the automatic selection may choose from; fix anything by giving one choice.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Candidate time constants.
    pub taus: TimeConstants,
    /// Candidate families.
    pub families: Vec<Family>,
    /// Candidate ridge parameters (relative, on scaled columns: one scale per unit with the
    /// blend, one per sensor with the paired selection, `SolveOptions::shared_scale`).
    pub ridges: Vec<f64>,
    /// Blocks of the inner cross-validation.
    pub folds: usize,
    /// Which blocks train the model that predicts a held-out block.
    #[serde(default)]
    pub inner: InnerCv,
    /// How the CV scores pick a family's ridge.
    pub rule: Rule,
    /// How the families are decided between: blended ([`Selection::Blend`], the default) or the
    /// best one only where it beats the baseline fold by fold ([`Selection::Paired`]).
    #[serde(default)]
    pub selection: Selection,
    /// Candidate ridge parameters of the position-dependent families (`truepos fit --machine`):
    /// their structures are fixed by the machine, not chosen from the data, so their ridge keeps
    /// its long grid and the one-standard-error rule ([`POSITION_RIDGES`]).
    #[serde(default = "position_ridges")]
    pub position_ridges: Vec<f64>,
    /// How the CV scores pick a position-dependent family's ridge.
    #[serde(default = "position_rule")]
    pub position_rule: Rule,
    /// Run with at most this many temperature sensors (chosen by correlation ranking and greedy
    /// forward selection); `None` = all.
    pub max_sensors: Option<usize>,
    /// The reference sensor of the reference-sensor regression (dataset input index): with it,
    /// [`Family::Reference`] is a candidate and the reference is always among the sensors.
    #[serde(default)]
    pub reference: Option<usize>,
    /// Targets as measured (error = actual − nominal, what a machine's position-dependent model
    /// predicts at a position) rather than relative to each run's first sample (what a model
    /// started with the run predicts). `truepos fit --machine FILE` sets it: a position-dependent
    /// error at the first sample is part of what the model must learn, not an offset to remove.
    #[serde(default)]
    pub absolute_targets: bool,
}

/// The paired selection's ridge grid: short, and it stops at 0.1 — with few, unlike folds the
/// lowest inner error is noisy, and a long grid of heavy ridges lets the choice walk into
/// shrinking exactly the small sensor differences that tell a quiet run from a loud one.
pub const PAIRED_RIDGES: [f64; 4] = [1e-4, 1e-3, 1e-2, 0.1];

/// How the families are decided between (docs/fitting.md, "How the selection chooses").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// Every family's ridge by the rule, the families blended by their out-of-fold predictions,
    /// guarded against no compensation (the module `blend`). The default: the development gate
    /// has not shown the paired selection better (docs/fitting.md).
    #[default]
    Blend,
    /// The fixed baseline, replaced by the best richer family only where that family beats it
    /// fold by fold ([`crate::selection`]); one scale per sensor, identified time constants on
    /// their bound dropped and kept out of the inner gap, the ridge from [`PAIRED_RIDGES`] by
    /// the lowest inner error.
    Paired,
}

impl Settings {
    /// The defaults with the paired selection and its own grid and rule.
    pub fn paired() -> Self {
        Self {
            selection: Selection::Paired,
            ridges: PAIRED_RIDGES.to_vec(),
            rule: Rule::MinimumCv,
            ..Self::default()
        }
    }
}

impl FromStr for Selection {
    type Err = String;

    /// `blend` or `paired`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "blend" => Ok(Self::Blend),
            "paired" => Ok(Self::Paired),
            _ => Err(format!("expected blend or paired, got `{s}`")),
        }
    }
}

impl fmt::Display for Selection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Blend => "blend",
            Self::Paired => "paired",
        })
    }
}

/// The position-dependent families' ridge grid (see [`Settings::position_ridges`]).
pub const POSITION_RIDGES: [f64; 11] =
    [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0];

fn position_ridges() -> Vec<f64> {
    POSITION_RIDGES.to_vec()
}

fn position_rule() -> Rule {
    Rule::OneStandardError
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            taus: TimeConstants::default(),
            families: Family::DEFAULT.to_vec(),
            ridges: POSITION_RIDGES.to_vec(),
            folds: 8,
            inner: InnerCv::Blocked,
            rule: Rule::OneStandardError,
            selection: Selection::Blend,
            position_ridges: position_ridges(),
            position_rule: position_rule(),
            max_sensors: None,
            reference: None,
            absolute_targets: false,
        }
    }
}

/// Which blocks of the training rows fit the model that predicts a held-out block.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InnerCv {
    /// Every other block, before and after it (k-fold on contiguous blocks). The default: every
    /// fold trains on nearly all rows, so the per-fold errors are comparable and the
    /// one-standard-error rule is meaningful.
    #[default]
    Blocked,
    /// Only the blocks before it (rolling origin); the first [`ROLLING_FIRST_HELD_OUT`] blocks
    /// only train. Scores the model as it is used, forward in time; but the early folds train on
    /// little data, their large errors widen the standard error, and the one-standard-error rule
    /// then leans towards heavy ridge (docs/fitting.md has both on FL_THERMAL).
    Rolling,
}

/// Index of the first block a rolling-origin CV predicts: two blocks at least train every fold,
/// so that no score comes from a model fitted on a single stretch of operation.
pub const ROLLING_FIRST_HELD_OUT: usize = 2;

impl InnerCv {
    /// Whether block `g` trains the model that predicts held-out block `f`.
    pub(crate) fn trains(self, g: usize, f: usize) -> bool {
        match self {
            Self::Blocked => g != f,
            Self::Rolling => g < f,
        }
    }

    /// The fewest blocks that leave a fold to score: two for blocked, one more than the
    /// blocks that only train for rolling origin.
    pub(crate) fn min_blocks(self) -> usize {
        match self {
            Self::Blocked => 2,
            Self::Rolling => ROLLING_FIRST_HELD_OUT + 1,
        }
    }

    /// Whether block `f` is scored at all.
    pub(crate) fn holds_out(self, f: usize) -> bool {
        match self {
            Self::Blocked => true,
            Self::Rolling => f >= ROLLING_FIRST_HELD_OUT,
        }
    }
}

impl Settings {
    /// The selection protocol in words, for reports and `--json`.
    pub fn describe_selection(&self) -> String {
        let cv = match self.inner {
            InnerCv::Blocked => format!("blocked {}-fold CV (contiguous blocks)", self.folds),
            InnerCv::Rolling => format!(
                "rolling-origin CV ({} contiguous blocks, each from block {} on predicted by a model fitted on the blocks before it)",
                self.folds,
                ROLLING_FIRST_HELD_OUT + 1
            ),
        };
        let rule = match self.rule {
            Rule::MinimumCv => "lowest CV error",
            Rule::OneStandardError => "one-standard-error rule",
        };
        match self.selection {
            Selection::Blend => format!("{cv}, {rule}"),
            Selection::Paired => format!(
                "{cv}, {rule}, the best family kept only where it beats the baseline fold by fold"
            ),
        }
    }
}

/// How the inner cross-validation scores choose among candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Rule {
    /// The candidate with the lowest CV RMSE (the paired selection's: its grid is short, and
    /// the comparison with the baseline guards against a lucky pick).
    MinimumCv,
    /// The most regularised candidate of the best family within one standard error of the best
    /// (the blend's). With whole runs as folds the standard error holds the run-to-run
    /// differences, and the rule can walk to heavy ridges.
    OneStandardError,
}

impl FromStr for InnerCv {
    type Err = String;

    /// `blocked` or `rolling`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "blocked" => Ok(Self::Blocked),
            "rolling" => Ok(Self::Rolling),
            _ => Err(format!("expected blocked or rolling, got `{s}`")),
        }
    }
}

impl FromStr for Rule {
    type Err = String;

    /// `simplest` ([`Rule::OneStandardError`]) or `lowest` ([`Rule::MinimumCv`]); the earlier
    /// names `1se` and `min` are still read.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "simplest" | "1se" => Ok(Self::OneStandardError),
            "lowest" | "min" => Ok(Self::MinimumCv),
            _ => Err(format!("expected simplest or lowest, got `{s}`")),
        }
    }
}

/// The items of a comma-separated list, trimmed, empty items dropped (`dynamic, static,`).
fn items(s: &str) -> impl Iterator<Item = &str> {
    s.split(',').map(str::trim).filter(|p| !p.is_empty())
}

/// The largest ridge parameter a person may give: relative to unit-norm columns, 10¹² already
/// shrinks every coefficient to nothing.
pub const MAX_RIDGE: f64 = 1e12;

/// Candidate ridge parameters, comma-separated, each finite in [0, [`MAX_RIDGE`]].
#[derive(Debug, Clone, PartialEq)]
pub struct Ridges(pub Vec<f64>);

impl FromStr for Ridges {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        items(s)
            .map(truepos_io::limits::finite_in(0.0, MAX_RIDGE))
            .collect::<Result<_, _>>()
            .map(Self)
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::OneStandardError => "simplest",
            Self::MinimumCv => "lowest",
        })
    }
}

impl fmt::Display for InnerCv {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Blocked => "blocked",
            Self::Rolling => "rolling",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_settings_parse_and_say_what_they_expect() {
        for rule in [Rule::OneStandardError, Rule::MinimumCv] {
            assert_eq!(rule.to_string().parse::<Rule>(), Ok(rule));
        }
        for inner in [InnerCv::Blocked, InnerCv::Rolling] {
            assert_eq!(inner.to_string().parse::<InnerCv>(), Ok(inner));
        }
        assert_eq!(
            "median".parse::<Rule>().unwrap_err(),
            "expected simplest or lowest, got `median`"
        );
        assert!("random"
            .parse::<InnerCv>()
            .unwrap_err()
            .contains("blocked or rolling"));
        assert_eq!("0, 1e-3".parse::<Ridges>(), Ok(Ridges(vec![0.0, 1e-3])));
        for bad in ["-1", "1e13", "nan", "x"] {
            assert!(
                bad.parse::<Ridges>()
                    .unwrap_err()
                    .contains("[0, 1000000000000]"),
                "{bad}"
            );
        }
    }
}
