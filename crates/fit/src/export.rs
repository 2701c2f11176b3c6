//! A fit as the model description `truepos_io` writes: the trained model of the last training
//! part, its inputs by name and kind, the axis each target compensates, and where it came from
//! (runs, settings, choices) with its validation figures; the check that refuses a model whose
//! predictions are not plausible ([`plausible`]); the predictions behind the figures as CSV
//! ([`predictions_csv`]).

use std::fmt;
use std::str::FromStr;

use truepos_io::model_file::envelope::EnvelopeEntry;
use truepos_io::model_file::filtered::{DynamicModelFile, InputEntry, InputKind};
use truepos_model::envelope::TrainingEnvelope;

use crate::dataset::Dataset;
use crate::settings::Settings;
use crate::train::Trained;
use crate::validate::{Outcome, Predictions};

/// `<target>=<axis>`: the machine axis a target compensates (`ch5_um=Z`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TargetAxis {
    /// Target name.
    pub target: String,
    /// Machine axis name.
    pub axis: String,
}

impl FromStr for TargetAxis {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.split_once('=') {
            Some((target, axis)) => Ok(Self {
                target: target.trim().to_string(),
                axis: axis.trim().to_string(),
            }),
            None => Err(format!(
                "expected <target>=<axis>, e.g. ch5_um=Z, got `{s}`"
            )),
        }
    }
}

/// A model file that cannot be made as asked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExportError {
    /// An axis was given for a target the dataset does not have.
    UnknownTarget {
        /// The name given.
        target: String,
        /// The dataset's targets.
        targets: Vec<String>,
    },
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownTarget { target, targets } => write!(
                f,
                "no target `{target}`; the targets are {}",
                targets.join(", ")
            ),
        }
    }
}

impl std::error::Error for ExportError {}

/// The dynamic model file of a fit for `machine`; `created_by` names the tool and version.
/// A target without an entry in `axes` keeps the axis its name implies, if any (see
/// `truepos_io::model_file::filtered`).
pub fn model_file(
    dataset: &Dataset,
    settings: &Settings,
    outcome: &Outcome,
    machine: &str,
    axes: &[TargetAxis],
    created_by: &str,
) -> Result<DynamicModelFile, ExportError> {
    let mut file = filtered_model_file(
        dataset,
        settings,
        &outcome.trained,
        serde_json::to_value(&outcome.validation).unwrap_or_default(),
        machine,
        axes,
        created_by,
    )?;
    file.training_envelope = Some(training_envelope(
        dataset,
        &outcome.trained.inputs,
        &outcome.fitted,
        &outcome.training_rows,
    ));
    Ok(file)
}

/// Where a model was trained (`truepos_model::envelope`): the range of each input it reads over
/// its training rows and, per target, the largest finite |prediction| there — the figures the
/// runtime's guard clamps and caps by. An input or target without a finite value is left out.
pub fn training_envelope(
    dataset: &Dataset,
    inputs: &[usize],
    fitted: &Predictions,
    training_rows: &[(usize, usize)],
) -> EnvelopeEntry {
    let mut entry = EnvelopeEntry::default();
    for &i in inputs {
        let range = training_rows
            .iter()
            .map(|&(r, row)| dataset.runs[r].inputs[i][row])
            .filter(|v| v.is_finite())
            .fold(None, |acc: Option<(f64, f64)>, v| {
                Some(acc.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
            });
        if let Some((lo, hi)) = range {
            entry
                .inputs
                .insert(dataset.input_names[i].clone(), [lo, hi]);
        }
    }
    for (k, name) in dataset.target_names.iter().enumerate() {
        let max = training_rows
            .iter()
            .filter_map(|&(r, row)| fitted.get(r)?.get(k)?.get(row).copied())
            .filter(|v| v.is_finite())
            .fold(None, |acc: Option<f64>, v| {
                Some(acc.unwrap_or(0.0).max(v.abs()))
            });
        if let Some(m) = max {
            entry.max_abs_prediction_um.insert(name.clone(), m);
        }
    }
    entry
}

/// [`model_file`] of any trained dynamic model with its validation figures (JSON).
pub fn filtered_model_file(
    dataset: &Dataset,
    settings: &Settings,
    trained: &Trained,
    validation: serde_json::Value,
    machine: &str,
    axes: &[TargetAxis],
    created_by: &str,
) -> Result<DynamicModelFile, ExportError> {
    let inputs = trained
        .inputs
        .iter()
        .map(|&i| InputEntry {
            name: dataset.input_names[i].clone(),
            kind: dataset.input_kinds[i],
        })
        .collect();
    let mut file = DynamicModelFile::new(
        machine,
        &trained.model,
        inputs,
        &dataset.target_names,
        serde_json::json!({
            "created_by": created_by,
            "runs": dataset.runs.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
            "fitted_on": "every row of every run; the validation figures are those of the folds",
            "settings": settings,
            "choices": trained.choices,
        }),
        validation,
    );
    for a in axes {
        let output = file
            .outputs
            .iter_mut()
            .find(|o| o.name == a.target)
            .ok_or_else(|| ExportError::UnknownTarget {
                target: a.target.clone(),
                targets: dataset.target_names.clone(),
            })?;
        output.axis = Some(a.axis.clone());
    }
    Ok(file)
}

/// Per dataset input the envelope knows: (input, lower, upper) of its training range widened by
/// the runtime's margins (`truepos_model::envelope`), where the machine clamps it.
pub(crate) fn widened_limits(dataset: &Dataset, env: &EnvelopeEntry) -> Vec<(usize, f64, f64)> {
    use truepos_model::envelope::{OPERATING_MARGIN, TEMPERATURE_MARGIN, TEMPERATURE_MARGIN_MIN_K};
    dataset
        .input_names
        .iter()
        .enumerate()
        .filter_map(|(i, name)| {
            let [lo, hi] = *env.inputs.get(name)?;
            let margin = match dataset.input_kinds[i] {
                InputKind::Temperature => {
                    (TEMPERATURE_MARGIN * (hi - lo)).max(TEMPERATURE_MARGIN_MIN_K)
                }
                InputKind::Operating => OPERATING_MARGIN * (hi - lo),
            };
            Some((i, lo - margin, hi + margin))
        })
        .collect()
}

/// The rows of `rows` (run, row) with an input beyond its widened training range in `env`
/// (the margins of `truepos_model::envelope`): where the model, on the machine, is clamped.
pub fn rows_beyond(dataset: &Dataset, env: &EnvelopeEntry, rows: &[(usize, usize)]) -> usize {
    let limits = widened_limits(dataset, env);
    rows.iter()
        .filter(|&&(r, row)| {
            limits.iter().any(|&(i, lo, hi)| {
                let v = dataset.runs[r].inputs[i][row];
                v < lo || v > hi
            })
        })
        .count()
}

/// Where a model of the machine (position-dependent, reference-sensor) was trained: the
/// range of every temperature channel it reads over the training rows and, per axis, the
/// largest |predicted error| there (the model evaluated at each training row).
pub fn machine_envelope(
    model: &truepos_model::Model,
    data: &crate::machine_fit::MachineData,
    training_rows: &[(usize, usize)],
) -> TrainingEnvelope {
    let m = &data.machine;
    let mut env = TrainingEnvelope {
        temperatures: vec![None; m.temperatures.len()],
        operating: vec![None; m.operating.len()],
        max_abs_um: vec![None; m.axes.len()],
    };
    for &(r, row) in training_rows {
        let run = &data.runs[r];
        for &c in model.used_sensors() {
            let v = run.temperatures_c[row][c];
            if v.is_finite() {
                let slot = &mut env.temperatures[c];
                *slot = Some(slot.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
            }
        }
        let input = truepos_model::CycleInput {
            temperatures_c: &run.temperatures_c[row],
            positions: &run.positions[row],
            operating: &run.operating[row],
        };
        if let Ok(c) = model.evaluate(&input) {
            for (slot, e) in env.max_abs_um.iter_mut().zip(c.error_um()) {
                if e.is_finite() {
                    *slot = Some(slot.unwrap_or(0.0).max(e.abs()));
                }
            }
        }
    }
    env
}

/// How far beyond the largest measured |error| a model's prediction on its own training data may
/// go before the model is refused: a least-squares fit reproduces its training data, so a
/// prediction an order of magnitude beyond everything it was fitted to means the fit broke
/// (an absurd value, overflow), not that the machine moved.
pub const PLAUSIBLE_FACTOR: f64 = 10.0;

/// Measured errors below this (µm) count as this much when judging plausibility: a machine
/// does not resolve less, and rounding noise of a fit to an all-zero target must not count as
/// "beyond".
const RESOLUTION_UM: f64 = 1e-3;

/// A model output whose predictions on its own training data are non-finite or more than
/// [`PLAUSIBLE_FACTOR`] times the largest measured |error| there.
#[derive(Debug, Clone, PartialEq)]
pub struct Implausible {
    /// The output (target) name.
    pub target: String,
    /// The largest |prediction| on the training rows (NaN or infinite when non-finite).
    pub predicted_um: f64,
    /// The largest measured |error| (relative to the run start) on the training rows.
    pub measured_um: f64,
    /// Where: run name and 0-based row of the worst prediction.
    pub run: String,
    /// Row (0-based sample index) of the worst prediction.
    pub row: usize,
}

impl fmt::Display for Implausible {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.predicted_um.is_finite() {
            write!(
                f,
                "output `{}` predicts {:.3e} µm on its own training data ({}, sample {}), more than {} × the largest measured |error| there ({:.3} µm)",
                self.target, self.predicted_um, self.run, self.row, PLAUSIBLE_FACTOR, self.measured_um
            )
        } else {
            write!(
                f,
                "output `{}` predicts {} on its own training data ({}, sample {})",
                self.target, self.predicted_um, self.run, self.row
            )
        }
    }
}

/// Every output of the fitted model ([`Outcome::trained`]) whose predictions on its training
/// rows are non-finite or beyond [`PLAUSIBLE_FACTOR`] × the largest measured |error| there.
pub fn plausible(dataset: &Dataset, outcome: &Outcome) -> Result<(), Vec<Implausible>> {
    plausible_predictions(
        dataset,
        &outcome.fitted,
        &outcome.training_rows,
        outcome.absolute_targets,
    )
}

/// [`plausible`] for the predictions `fitted` of any model (either form) fitted on
/// `training_rows`; targets as measured (`absolute`) or relative to each run's first sample.
pub fn plausible_predictions(
    dataset: &Dataset,
    fitted: &Predictions,
    training_rows: &[(usize, usize)],
    absolute: bool,
) -> Result<(), Vec<Implausible>> {
    let mut bad = Vec::new();
    for (k, target) in dataset.target_names.iter().enumerate() {
        let rel: Vec<Vec<f64>> = dataset.runs.iter().map(|r| r.target(k, absolute)).collect();
        let measured = training_rows
            .iter()
            .fold(0.0_f64, |a, &(r, i)| a.max(rel[r][i].abs()));
        // The worst row: a non-finite prediction first, else the largest.
        let worst = training_rows
            .iter()
            .map(|&(r, i)| (r, i, fitted[r][k][i]))
            .max_by(|a, b| {
                let key = |v: f64| {
                    if v.is_finite() {
                        v.abs()
                    } else {
                        f64::INFINITY
                    }
                };
                key(a.2).total_cmp(&key(b.2))
            });
        if let Some((r, i, p)) = worst {
            if !p.is_finite() || p.abs() > PLAUSIBLE_FACTOR * measured.max(RESOLUTION_UM) {
                bad.push(Implausible {
                    target: target.clone(),
                    predicted_um: if p.is_finite() { p.abs() } else { p },
                    measured_um: measured,
                    run: dataset.runs[r].name.clone(),
                    row: i,
                });
            }
        }
    }
    if bad.is_empty() {
        Ok(())
    } else {
        Err(bad)
    }
}

/// The predictions behind the figures as CSV: per run (by name) and row, time, whether the row
/// was held out (its prediction comes from a model that never saw it; see
/// [`Outcome::predictions`]), and per target the measured error (relative to the run start)
/// and the prediction.
pub fn predictions_csv(dataset: &Dataset, outcome: &Outcome) -> String {
    predictions_csv_of(
        dataset,
        &outcome.predictions,
        &outcome.held_out,
        outcome.absolute_targets,
    )
}

/// [`predictions_csv`] of any model's predictions, with which rows were held out; targets as
/// measured (`absolute`) or relative to each run's first sample.
pub fn predictions_csv_of(
    dataset: &Dataset,
    predictions: &Predictions,
    held_out: &[Vec<bool>],
    absolute: bool,
) -> String {
    let mut out = String::from("run,time_s,held_out");
    for t in &dataset.target_names {
        out += &format!(",{},{}", csv_field(t), csv_field(&format!("{t}_predicted")));
    }
    out.push('\n');
    for (r, run) in dataset.runs.iter().enumerate() {
        let name = csv_field(&run.name);
        let rel: Vec<Vec<f64>> = (0..dataset.target_names.len())
            .map(|k| run.target(k, absolute))
            .collect();
        for i in 0..run.len() {
            out += &format!("{name},{},{}", run.time_s[i], held_out[r][i]);
            for (k, measured) in rel.iter().enumerate() {
                // A row without a measurement has an empty measured cell, not "NaN".
                let m = if measured[i].is_nan() {
                    String::new()
                } else {
                    measured[i].to_string()
                };
                out += &format!(",{m},{}", predictions[r][k][i]);
            }
            out.push('\n');
        }
    }
    out
}

/// A CSV field, quoted when it holds a comma, quote or line break (RFC 4180).
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::tests::{static_settings, three_runs};
    use crate::validate::{fit, predict};

    /// A sound fit passes; the same fit with an intercept of 10⁹ µm is named with its figure and
    /// the largest measured |error|; a non-finite prediction is named too (stepping the model
    /// already refuses one, the check does not rely on that).
    #[test]
    fn an_implausible_model_is_named() {
        let ds = three_runs();
        let split = "chrono:0.6".parse().unwrap();
        let mut o = fit(&ds, split, &static_settings(), &mut |_, _| {}).unwrap();
        assert_eq!(plausible(&ds, &o), Ok(()));
        let bank = o.trained.model.bank().clone();
        let coef = o.trained.model.coefficients().to_vec();
        o.trained.model = truepos_model::DynamicModel::new(bank, vec![1e9], coef).unwrap();
        o.fitted = predict(&ds, &o.trained).unwrap();
        let bad = plausible(&ds, &o).unwrap_err();
        assert_eq!(bad.len(), 1);
        // The written model is trained on every row: the largest measured |error| there is run
        // a's at its last sample, 2 µm/K × 0.1 K × 59 = 11.8 µm; there the prediction is
        // largest too.
        assert_eq!(
            bad[0].to_string(),
            "output `dz_um` predicts 1.000e9 µm on its own training data (a.csv, sample 59), \
             more than 10 × the largest measured |error| there (11.800 µm)"
        );
        o.fitted[1][0][20] = f64::NAN;
        let bad = plausible(&ds, &o).unwrap_err();
        assert_eq!(
            bad[0].to_string(),
            "output `dz_um` predicts NaN on its own training data (b.csv, sample 20)"
        );
    }

    #[test]
    fn a_target_axis_reads_target_equals_axis() {
        assert_eq!(
            " ch5_um = Z".parse(),
            Ok(TargetAxis {
                target: "ch5_um".into(),
                axis: "Z".into()
            })
        );
        assert_eq!(
            "ch5_um".parse::<TargetAxis>().unwrap_err(),
            "expected <target>=<axis>, e.g. ch5_um=Z, got `ch5_um`"
        );
    }
}
