//! Honest validation: the model is chosen and fitted on the training rows only and judged on
//! rows it never saw, split in time or by run — never at random (neighbouring samples are nearly
//! identical, so a random split leaks the answer).
//!
//! Predictions on the test rows come from the exported real-time [`truepos_model::DynamicModel`]
//! stepped through each run from its start, exactly as the control would run it.

use std::fmt;
use std::str::FromStr;

use crate::dataset::Dataset;
use crate::features::{candidates, Candidates};
use crate::settings::Settings;
use crate::train::{train, Choice, Trained};

/// How rows are split into training and test parts.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "protocol")]
pub enum Split {
    /// The first `train_fraction` of every run trains, the rest tests.
    Chronological {
        /// 0 < f < 1.
        train_fraction: f64,
    },
    /// Each run is held out in turn; the others train.
    LeaveOneRunOut,
    /// The rows (run after run, in time order) are cut into `k` contiguous blocks; each is held
    /// out in turn.
    BlockedKFold {
        /// Number of blocks.
        k: usize,
    },
}

impl FromStr for Split {
    type Err = String;

    /// `chrono:0.6`, `runs` or `kfold:5`.
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || {
            format!("expected chrono:<fraction 0…1>, runs (leave one run out) or kfold:<k ≥ 2>, got `{s}`")
        };
        match s.trim().split_once(':') {
            Some(("chrono", f)) => match f.parse::<f64>() {
                Ok(f) if f > 0.0 && f < 1.0 => Ok(Self::Chronological { train_fraction: f }),
                _ => Err(bad()),
            },
            Some(("kfold", k)) => match k.parse::<usize>() {
                Ok(k) if k >= 2 => Ok(Self::BlockedKFold { k }),
                _ => Err(bad()),
            },
            None if s.trim() == "runs" => Ok(Self::LeaveOneRunOut),
            _ => Err(bad()),
        }
    }
}

impl Split {
    /// (train rows, test rows) per outer fold, as (run, row) pairs in time order.
    #[allow(clippy::type_complexity)]
    pub fn folds(
        &self,
        dataset: &Dataset,
    ) -> Result<Vec<(Vec<(usize, usize)>, Vec<(usize, usize)>)>, String> {
        let all: Vec<(usize, usize)> = dataset
            .runs
            .iter()
            .enumerate()
            .flat_map(|(r, run)| (0..run.len()).map(move |i| (r, i)))
            .collect();
        Ok(match *self {
            Self::Chronological { train_fraction } => {
                let (tr, te) = all.iter().partition(|&&(r, i)| {
                    (i as f64) < (train_fraction * dataset.runs[r].len() as f64).floor()
                });
                vec![(tr, te)]
            }
            Self::LeaveOneRunOut => {
                if dataset.runs.len() < 2 {
                    return Err("leave-one-run-out needs at least two runs".into());
                }
                (0..dataset.runs.len())
                    .map(|held| all.iter().partition(|&&(r, _)| r != held))
                    .collect()
            }
            Self::BlockedKFold { k } => {
                let n = all.len();
                (0..k)
                    .map(|b| {
                        let range = b * n / k..(b + 1) * n / k;
                        let (te, tr): (Vec<_>, Vec<_>) =
                            all.iter().enumerate().partition(|(i, _)| range.contains(i));
                        (
                            tr.into_iter().map(|(_, p)| *p).collect(),
                            te.into_iter().map(|(_, p)| *p).collect(),
                        )
                    })
                    .collect()
            }
        })
    }
}

impl fmt::Display for Split {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Chronological { train_fraction } => write!(
                f,
                "chronological: first {:.0} % of every run trains, the rest tests",
                train_fraction * 100.0
            ),
            Self::LeaveOneRunOut => write!(f, "leave one run out"),
            Self::BlockedKFold { k } => write!(f, "blocked {k}-fold (contiguous blocks in time)"),
        }
    }
}

/// Figures of one target channel on the test rows (µm).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    /// Target name.
    pub target: String,
    /// Root mean square of the residual error (measured − predicted).
    pub rmse_um: f64,
    /// Largest absolute residual.
    pub max_abs_um: f64,
    /// Peak-to-peak of the residual.
    pub peak_to_peak_um: f64,
    /// RMS of the uncompensated error: displacement relative to each run's first sample.
    pub uncompensated_rmse_um: f64,
    /// Largest absolute uncompensated error.
    pub uncompensated_max_abs_um: f64,
    /// 100·(1 − rmse / uncompensated rmse).
    pub rmse_reduction_percent: f64,
    /// Test samples.
    pub samples: usize,
}

impl Metrics {
    /// Figures from measured (relative to the run start) and predicted values.
    pub fn new(target: &str, measured: &[f64], predicted: &[f64]) -> Self {
        let n = measured.len().max(1) as f64;
        let res: Vec<f64> = measured.iter().zip(predicted).map(|(m, p)| m - p).collect();
        let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let max_abs = |v: &[f64]| v.iter().fold(0.0_f64, |a, e| a.max(e.abs()));
        let hi = res.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lo = res.iter().copied().fold(f64::INFINITY, f64::min);
        let rmse = rms(&res);
        let unc = rms(measured);
        Self {
            target: target.into(),
            rmse_um: rmse,
            max_abs_um: max_abs(&res),
            peak_to_peak_um: if res.is_empty() { 0.0 } else { hi - lo },
            uncompensated_rmse_um: unc,
            uncompensated_max_abs_um: max_abs(measured),
            rmse_reduction_percent: if unc > 0.0 {
                100.0 * (1.0 - rmse / unc)
            } else {
                0.0
            },
            samples: measured.len(),
        }
    }
}

/// The outcome of a validation.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Validation {
    /// The protocol.
    pub protocol: Split,
    /// Human-readable protocol.
    pub protocol_text: String,
    /// Per target, pooled over the outer folds.
    pub metrics: Vec<Metrics>,
    /// Per outer fold, what the inner selection chose.
    pub choices: Vec<Vec<Choice>>,
    /// Temperature sensors used per outer fold (names).
    pub sensors: Vec<Vec<String>>,
    /// Warnings from the fits.
    pub warnings: Vec<String>,
}

/// Predicted errors (µm): per run, per target, per sample.
pub type Predictions = Vec<Vec<Vec<f64>>>;

/// Predictions of a trained model over whole runs (every row), by stepping the real-time model.
pub fn predict(dataset: &Dataset, trained: &Trained) -> Result<Predictions, String> {
    let mut model = trained.model.clone();
    let nt = model.output_count();
    let mut out = Vec::new();
    let mut row = vec![0.0; trained.inputs.len()];
    for run in &dataset.runs {
        model.reset();
        let mut pred = vec![Vec::with_capacity(run.len()); nt];
        for i in 0..run.len() {
            for (slot, &d) in row.iter_mut().zip(&trained.inputs) {
                *slot = run.inputs[d][i];
            }
            let dt = if i == 0 {
                0.0
            } else {
                run.time_s[i] - run.time_s[i - 1]
            };
            let y = model
                .step(dt, &row)
                .map_err(|e| format!("{}: sample {i}: {e}", run.name))?;
            for (k, v) in y.iter().enumerate() {
                pred[k].push(*v);
            }
        }
        out.push(pred);
    }
    Ok(out)
}

/// Runs the protocol: for each outer fold, select and fit on its training rows, predict its test
/// rows. Returns the figures and the model of the last fold (for `chrono`, the only one).
pub fn validate(
    dataset: &Dataset,
    cand: &Candidates,
    split: Split,
    settings: &Settings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Validation, Trained, Predictions), String> {
    let folds = split.folds(dataset)?;
    let nt = dataset.target_names.len();
    let rel: Vec<Vec<Vec<f64>>> = dataset
        .runs
        .iter()
        .map(|r| (0..nt).map(|k| r.relative_target(k)).collect())
        .collect();
    let mut measured = vec![Vec::new(); nt];
    let mut predicted = vec![Vec::new(); nt];
    let mut choices = Vec::new();
    let mut sensors = Vec::new();
    let mut warnings = Vec::new();
    let mut last = None;
    for (f, (tr, te)) in folds.iter().enumerate() {
        progress(f, folds.len());
        if te.is_empty() {
            return Err(format!("fold {}: no test rows", f + 1));
        }
        let trained = train(dataset, cand, tr, settings)?;
        let pred = predict(dataset, &trained)?;
        for &(r, i) in te {
            for k in 0..nt {
                measured[k].push(rel[r][k][i]);
                predicted[k].push(pred[r][k][i]);
            }
        }
        choices.push(trained.choices.clone());
        sensors.push(
            trained
                .sensors
                .iter()
                .map(|&s| dataset.input_names[s].clone())
                .collect(),
        );
        warnings.extend(trained.warnings.iter().cloned());
        last = Some((trained, pred));
    }
    progress(folds.len(), folds.len());
    let metrics = (0..nt)
        .map(|k| Metrics::new(&dataset.target_names[k], &measured[k], &predicted[k]))
        .collect();
    let (trained, pred) = last.ok_or("no folds")?;
    Ok((
        Validation {
            protocol: split,
            protocol_text: format!(
                "{split}; selection inside each training part: {}",
                settings.describe_selection()
            ),
            metrics,
            choices,
            sensors,
            warnings,
        },
        trained,
        pred,
    ))
}

/// A fit from a dataset: the validation figures, the model fitted on the (last) training part
/// and its predictions over every run.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Figures pooled over the outer folds.
    pub validation: Validation,
    /// The model of the last outer fold's training part (for `chrono`, the only one).
    pub trained: Trained,
    /// Its predictions over whole runs.
    pub predictions: Predictions,
}

/// Candidate features of the dataset, then [`validate`]: what `truepos fit` runs.
pub fn fit(
    dataset: &Dataset,
    split: Split,
    settings: &Settings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Outcome, String> {
    let cand = candidates(dataset, &settings.taus).map_err(|e| e.to_string())?;
    let (validation, trained, predictions) = validate(dataset, &cand, split, settings, progress)?;
    Ok(Outcome {
        validation,
        trained,
        predictions,
    })
}
