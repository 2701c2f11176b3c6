//! Regressors from a run: the candidate features of every input, computed by the real-time
//! crate's own [`FeatureBank`] so that the features fitted offline are exactly those the control
//! computes online.

use std::fmt;
use std::str::FromStr;

use truepos_model::{Feature, FeatureBank, FeatureKind, FeatureSpec};

use crate::dataset::{Dataset, InputKind};

/// Time constants of the candidate features.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TimeConstants {
    /// Low-pass filters of temperature rises (s).
    pub temperature_s: Vec<f64>,
    /// Filtered rates of change of temperature (s).
    pub rate_s: Vec<f64>,
    /// Low-pass filters of operating state and its square (s).
    pub operating_s: Vec<f64>,
}

impl Default for TimeConstants {
    /// Spindle heat reaches a structure over minutes to hours; thermal time constants of machine
    /// tool structures are typically 0.5 … 4 h, and a large casting keeps its heat for longer
    /// (FL_THERMAL: the displacement outlasted the sensors' cooling during a 4 h stop). The
    /// operating grid spans 5 min … 4 h, one point per factor of two to three, so that a sum of
    /// first-order lags can approximate the real response; the temperatures, which already carry
    /// the structure's own lag, get a fast, a medium and a slow lag up to the transfer family's
    /// longest τ (8 h).
    fn default() -> Self {
        Self {
            temperature_s: vec![900.0, 3600.0, 28800.0],
            rate_s: vec![1800.0],
            operating_s: vec![300.0, 900.0, 1800.0, 3600.0, 7200.0, 14400.0],
        }
    }
}

/// Every candidate feature of a dataset: the bank that computes them and their names. The values
/// are never stored (a month of logs at 1 s times a hundred features would not fit in memory):
/// an [`Extended::cursor`] steps the bank over a run wherever they are needed.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// The spec of the bank (temperatures first, then operating inputs).
    pub spec: FeatureSpec,
    /// Dataset input index of each bank input.
    pub bank_inputs: Vec<usize>,
    /// The features (their `input` indexes the bank inputs).
    pub features: Vec<Feature>,
    /// Feature names.
    pub names: Vec<String>,
}

/// The bank spec and input order for a subset of a dataset's inputs.
///
/// `running`: whether the rises while each operating input is non-zero are features too.
pub fn bank_for(
    dataset: &Dataset,
    inputs: &[usize],
    taus: &TimeConstants,
    running: bool,
) -> (FeatureSpec, Vec<usize>) {
    let temps: Vec<usize> = inputs
        .iter()
        .copied()
        .filter(|&i| dataset.input_kinds[i] == InputKind::Temperature)
        .collect();
    let ops: Vec<usize> = inputs
        .iter()
        .copied()
        .filter(|&i| dataset.input_kinds[i] == InputKind::Operating)
        .collect();
    let spec = FeatureSpec {
        temperatures: temps.len(),
        operating: ops.len(),
        temperature_rise: true,
        temperature_taus_s: taus.temperature_s.clone(),
        rate_taus_s: taus.rate_s.clone(),
        operating_taus_s: taus.operating_s.clone(),
        operating_square: true,
        rise_while_running: running,
    };
    (spec, temps.into_iter().chain(ops).collect())
}

/// The candidate features of every input of the dataset (time steps come from the time column).
pub fn candidates(
    dataset: &Dataset,
    taus: &TimeConstants,
) -> Result<Candidates, truepos_model::DynamicError> {
    let all: Vec<usize> = (0..dataset.input_names.len()).collect();
    let (spec, bank_inputs) = bank_for(dataset, &all, taus, true);
    let bank = FeatureBank::new(spec.clone())?;
    let features = bank.features().to_vec();
    let names = features
        .iter()
        .map(|f| f.name(|i| &dataset.input_names[bank_inputs[i]]))
        .collect();
    Ok(Candidates {
        spec,
        bank_inputs,
        features,
        names,
    })
}

/// A candidate set with more temperature low-pass columns after an existing one's: the transfer
/// families' identified τ join the candidates of a fit while the caller's set, shared by every
/// outer fold, stays as it is.
pub struct Extended<'a> {
    /// The dataset the features are computed from.
    pub dataset: &'a Dataset,
    /// The caller's candidates.
    pub base: &'a Candidates,
    /// The features of the whole set — the base's, then the added — with their names and spec.
    pub meta: Candidates,
    /// The bank of the added columns, if any.
    extra: Option<FeatureSpec>,
}

impl<'a> Extended<'a> {
    /// `base` plus LPF_τ of every temperature rise for each τ of `taus_s` (none: `base` alone).
    pub fn new(
        dataset: &'a Dataset,
        base: &'a Candidates,
        taus_s: &[f64],
    ) -> Result<Self, truepos_model::DynamicError> {
        let temps = base.spec.temperatures;
        let mut meta = base.clone();
        if taus_s.is_empty() || temps == 0 {
            return Ok(Self {
                dataset,
                base,
                meta,
                extra: None,
            });
        }
        meta.spec.temperature_taus_s.extend_from_slice(taus_s);
        let spec = FeatureSpec {
            temperatures: temps,
            operating: 0,
            temperature_rise: false,
            temperature_taus_s: taus_s.to_vec(),
            rate_taus_s: Vec::new(),
            operating_taus_s: Vec::new(),
            operating_square: false,
            rise_while_running: false,
        };
        for f in FeatureBank::new(spec.clone())?.features() {
            meta.features.push(*f);
            meta.names
                .push(f.name(|i| &dataset.input_names[base.bank_inputs[i]]));
        }
        Ok(Self {
            dataset,
            base,
            meta,
            extra: Some(spec),
        })
    }

    /// A cursor that steps the banks along the runs.
    pub fn cursor(&self) -> Result<Cursor<'_>, truepos_model::DynamicError> {
        Ok(Cursor {
            ext: self,
            base: FeatureBank::new(self.base.spec.clone())?,
            extra: self.extra.clone().map(FeatureBank::new).transpose()?,
            position: None,
            inputs: vec![0.0; self.base.bank_inputs.len()],
            values: vec![0.0; self.meta.features.len()],
        })
    }
}

/// The candidate features along the runs of a dataset, computed by the real-time bank as the
/// control computes them: every filter from the run's first sample.
pub struct Cursor<'e> {
    ext: &'e Extended<'e>,
    base: FeatureBank,
    extra: Option<FeatureBank>,
    /// (run, row) the banks last stepped to.
    position: Option<(usize, usize)>,
    inputs: Vec<f64>,
    values: Vec<f64>,
}

impl Cursor<'_> {
    /// Every feature of `run` at `row`. Moving forward within a run steps the banks over the rows
    /// between; another run, or a row already passed, starts again from the run's first sample.
    pub fn at(&mut self, run: usize, row: usize) -> Result<&[f64], truepos_model::DynamicError> {
        let from = match self.position {
            Some((r, i)) if r == run && i <= row => {
                if i == row {
                    return Ok(&self.values);
                }
                i + 1
            }
            _ => {
                self.base.reset();
                if let Some(b) = &mut self.extra {
                    b.reset();
                }
                0
            }
        };
        let data = &self.ext.dataset.runs[run];
        let temps = self.ext.base.spec.temperatures;
        let nb = self.ext.base.features.len();
        for i in from..=row {
            for (slot, &d) in self.inputs.iter_mut().zip(&self.ext.base.bank_inputs) {
                *slot = data.inputs[d][i];
            }
            let dt = if i == 0 {
                0.0
            } else {
                data.time_s[i] - data.time_s[i - 1]
            };
            self.values[..nb].copy_from_slice(self.base.step(dt, &self.inputs)?);
            if let Some(b) = &mut self.extra {
                self.values[nb..].copy_from_slice(b.step(dt, &self.inputs[..temps])?);
            }
        }
        self.position = Some((run, row));
        Ok(&self.values)
    }
}

/// A family of models: which kinds of features it may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// The simple reference every richer choice must beat ([`crate::selection`]): each
    /// temperature rise, and each operating input low-passed at the shortest operating time
    /// constant, at a small fixed ridge on per-column scales. Defined by its structure; always
    /// fitted when the selection has more than one family to choose from.
    Baseline,
    /// Temperature rises only: the static reference-sensor regression and the
    /// position-independent prior art.
    Static,
    /// Temperature rises and filtered operating state (spindle speed, its square).
    Operating,
    /// Adds low-pass filtered temperature rises: structures lag their sensors.
    Dynamic,
    /// Adds filtered rates of change of temperature.
    DynamicRates,
    /// [`Family::Dynamic`] plus the rises while the spindle (each operating input) runs: the
    /// error a temperature rise stands for differs between running and standing.
    DynamicRunning,
    /// [`Family::DynamicRates`] plus the rises while running.
    DynamicRatesRunning,
    /// First-order transfer functions from every temperature to the error: the rises and their
    /// low-pass at one time constant identified from the training data ([`crate::transfer`]).
    Transfer,
    /// The reference-sensor regression: Y = Σ k_i·(t_i − t_r) + c, every selected sensor against one
    /// reference sensor (`Settings::reference`); a candidate only when a reference is given.
    Reference,
    /// Second-order transfer functions from every temperature to the error: the rises and their
    /// low-passes at two time constants identified from the training data ([`crate::transfer`]).
    /// Not among the defaults ([`Family::DEFAULT`]).
    Transfer2,
}

impl Family {
    /// Every family, simplest first.
    pub const ALL: [Family; 10] = [
        Family::Baseline,
        Family::Reference,
        Family::Static,
        Family::Transfer,
        Family::Transfer2,
        Family::Operating,
        Family::Dynamic,
        Family::DynamicRates,
        Family::DynamicRunning,
        Family::DynamicRatesRunning,
    ];

    /// The richer families the selection chooses among unless told otherwise; the baseline
    /// ([`Family::Baseline`]) is not listed because it is always fitted as the reference they
    /// must beat. The static family is left out because the baseline already holds its rises;
    /// the second-order transfer functions because they cost FL_THERMAL's ch4 its 2.5 µm bar
    /// wherever they were measured (docs/fitting.md).
    pub const DEFAULT: [Family; 7] = [
        Family::Reference,
        Family::Transfer,
        Family::Operating,
        Family::Dynamic,
        Family::DynamicRates,
        Family::DynamicRunning,
        Family::DynamicRatesRunning,
    ];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Static => "static",
            Self::Operating => "operating",
            Self::Dynamic => "dynamic",
            Self::DynamicRates => "dynamic-rates",
            Self::DynamicRunning => "dynamic-running",
            Self::DynamicRatesRunning => "dynamic-rates-running",
            Self::Reference => "reference",
            Self::Transfer => "transfer",
            Self::Transfer2 => "transfer2",
        }
    }

    /// The family of a [`Family::name`] (or of the earlier name of `reference`, which older files
    /// and scripts carry); [`Family::from_str`] for what a person types.
    pub fn parse(s: &str) -> Option<Self> {
        if s == "seed-c" {
            return Some(Self::Reference);
        }
        Self::ALL.into_iter().find(|f| f.name() == s)
    }

    /// Whether a feature of this kind belongs to the family.
    pub fn includes(self, kind: FeatureKind) -> bool {
        match kind {
            FeatureKind::Rise => true,
            // The baseline keeps only the shortest operating time constant (`Problem::design`).
            FeatureKind::Operating { .. } => !matches!(
                self,
                Self::Static | Self::Reference | Self::Transfer | Self::Transfer2
            ),
            FeatureKind::OperatingSquared { .. } => !matches!(
                self,
                Self::Baseline | Self::Static | Self::Reference | Self::Transfer | Self::Transfer2
            ),
            // The transfer families keep only the low-passes at their identified τ (`train`).
            FeatureKind::LowPass { .. } => !matches!(
                self,
                Self::Baseline | Self::Static | Self::Reference | Self::Operating
            ),
            FeatureKind::Rate { .. } => {
                matches!(self, Self::DynamicRates | Self::DynamicRatesRunning)
            }
            FeatureKind::RiseWhileRunning { .. } => {
                matches!(self, Self::DynamicRunning | Self::DynamicRatesRunning)
            }
        }
    }
}

impl FromStr for Family {
    type Err = String;

    /// A [`Family::name`]; the error lists them all.
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s.trim()).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|f| f.name()).collect();
            let (last, rest) = names.split_last().unwrap_or((&"", &[]));
            format!("expected {} or {last}, got `{s}`", rest.join(", "))
        })
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Run;

    #[test]
    fn candidates_follow_the_bank_and_time_steps() {
        // One temperature rising 1 K at t = 10 s, one spindle at 1000 rpm; τ = 10 s.
        // At t = 20 s (dt = 10): LPF = 1 − e^−1 = 0.632120559 of the 1 K rise.
        let ds = Dataset {
            input_names: vec!["rpm".into(), "t1".into()],
            input_kinds: vec![InputKind::Operating, InputKind::Temperature],
            target_names: vec!["d".into()],
            runs: vec![Run {
                name: "r".into(),
                time_s: vec![0.0, 10.0, 20.0],
                inputs: vec![vec![1000.0; 3], vec![20.0, 21.0, 21.0]],
                targets: vec![vec![0.0; 3]],
            }],
        };
        let taus = TimeConstants {
            temperature_s: vec![10.0],
            rate_s: vec![],
            operating_s: vec![10.0],
        };
        let c = candidates(&ds, &taus).unwrap();
        assert_eq!(c.bank_inputs, vec![1, 0]);
        assert_eq!(
            c.names,
            vec![
                "rise(t1)",
                "lp10(t1)",
                "lp10(rpm)",
                "lp10(rpm^2)",
                "rise(t1)·running(rpm)"
            ]
        );
        let ext = Extended::new(&ds, &c, &[]).unwrap();
        let mut cursor = ext.cursor().unwrap();
        assert_eq!(cursor.at(0, 1).unwrap()[0], 1.0);
        // Step 1: 0.632120559 · 1; step 2: 0.632120559 + 0.632120559·(1 − 0.632120559).
        assert!((cursor.at(0, 1).unwrap()[1] - 0.632_120_558_8).abs() < 1e-9);
        let m = cursor.at(0, 2).unwrap().to_vec();
        assert!((m[1] - 0.864_664_716_8).abs() < 1e-9);
        assert_eq!(m[2], 1000.0);
        assert_eq!(m[3], 1.0e6);
        // The spindle runs throughout: the rise while running is the rise.
        assert_eq!(m[4], 1.0);
        // Back to an earlier row: the banks start again from the run's first sample.
        assert!((cursor.at(0, 1).unwrap()[1] - 0.632_120_558_8).abs() < 1e-9);
    }

    #[test]
    fn families_nest() {
        let lp = FeatureKind::LowPass { tau_s: 1.0 };
        assert!(!Family::Static.includes(lp) && Family::Dynamic.includes(lp));
        assert!(!Family::Static.includes(FeatureKind::Operating { tau_s: 1.0 }));
        assert!(!Family::Dynamic.includes(FeatureKind::Rate { tau_s: 1.0 }));
        assert_eq!(Family::parse("dynamic-rates"), Some(Family::DynamicRates));
        // The defaults are every family but static and the second-order transfer functions.
        let all_but: Vec<Family> = Family::ALL
            .into_iter()
            .filter(|&f| !matches!(f, Family::Transfer2 | Family::Static | Family::Baseline))
            .collect();
        assert_eq!(Family::DEFAULT.to_vec(), all_but);
        assert!(
            Family::Transfer2.includes(lp)
                && !Family::Transfer2.includes(FeatureKind::Operating { tau_s: 1.0 })
        );
        let running = FeatureKind::RiseWhileRunning { running: 1 };
        for f in Family::ALL {
            let with = matches!(f, Family::DynamicRunning | Family::DynamicRatesRunning);
            assert_eq!(f.includes(running), with, "{f:?}");
            assert_eq!(Family::parse(f.name()), Some(f));
        }
        // The running families hold everything their base family holds.
        for (base, run) in [
            (Family::Dynamic, Family::DynamicRunning),
            (Family::DynamicRates, Family::DynamicRatesRunning),
        ] {
            for kind in [lp, FeatureKind::Rate { tau_s: 1.0 }, FeatureKind::Rise] {
                assert!(
                    !base.includes(kind) || run.includes(kind),
                    "{run:?} {kind:?}"
                );
            }
        }
    }
}
