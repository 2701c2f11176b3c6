//! `truepos fit --report DIR`: the validation as a report — only out-of-fold predictions (a row
//! is shown predicted only by a model that never saw it), the runs end to end, and one table
//! row per held-out run so a pooled figure cannot hide a run the model makes worse.

use std::path::{Path, PathBuf};

use truepos_fit::dataset::{Dataset, InputKind};
use truepos_fit::validate::{Metrics as FitMetrics, Outcome};
use truepos_report::{write_report, Channel, Metrics, ReportData, RunRow};

use crate::error::CliError;

fn metrics(m: &FitMetrics) -> Metrics {
    Metrics {
        rmse_um: m.rmse_um,
        max_abs_um: m.max_abs_um,
        peak_to_peak_um: m.peak_to_peak_um,
        uncompensated_rmse_um: m.uncompensated_rmse_um,
        reduction: m.rmse_reduction_percent / 100.0,
    }
}

/// The runs' times laid end to end: each run starts one median sample interval after the end
/// of the one before, so runs read left to right in the order given.
fn end_to_end(ds: &Dataset) -> Vec<f64> {
    let mut out = Vec::new();
    let mut offset = 0.0;
    for run in &ds.runs {
        let t0 = run.time_s.first().copied().unwrap_or(0.0);
        let mut steps: Vec<f64> = run.time_s.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        let step = steps.get(steps.len() / 2).copied().unwrap_or(1.0);
        out.extend(run.time_s.iter().map(|t| offset + t - t0));
        offset = out.last().copied().unwrap_or(offset) + step;
    }
    out
}

/// Where each run starts on that axis (its first sample) and its name, for the drift plots'
/// run boundaries.
fn run_starts(ds: &Dataset) -> Vec<(usize, String)> {
    let mut start = 0;
    ds.runs
        .iter()
        .map(|run| {
            let here = start;
            start += run.time_s.len();
            (here, run.name.clone())
        })
        .collect()
}

fn channels(ds: &Dataset, outcome: &Outcome) -> Vec<Channel> {
    (0..ds.target_names.len())
        .map(|k| {
            let mut measured = Vec::new();
            let mut predicted = Vec::new();
            for (r, run) in ds.runs.iter().enumerate() {
                measured.extend(run.relative_target(k));
                predicted.extend(
                    outcome.predictions[r][k]
                        .iter()
                        .zip(&outcome.held_out[r])
                        .map(|(&p, &held)| if held { p } else { f64::NAN }),
                );
            }
            Channel {
                name: ds.target_names[k].clone(),
                unit: "µm".into(),
                measured,
                predicted,
            }
        })
        .collect()
}

fn runs(outcome: &Outcome, ds: &Dataset) -> Vec<RunRow> {
    let v = &outcome.validation;
    v.per_run
        .iter()
        .flat_map(|run| {
            run.targets.iter().enumerate().map(|(k, h)| RunRow {
                run: run.run.clone(),
                channel: ds.target_names.get(k).cloned().unwrap_or_default(),
                samples: h.metrics.samples,
                metrics: metrics(&h.metrics),
                family: Some(h.family.clone()),
            })
        })
        .collect()
}

/// A reduction in words: "−84 %", or "22 % worse" for a model that adds error.
fn change(reduction_percent: f64) -> String {
    if reduction_percent >= 0.0 {
        format!("−{reduction_percent:.0} %")
    } else {
        format!("{:.0} % worse", -reduction_percent)
    }
}

fn headline(outcome: &Outcome) -> Vec<(String, String)> {
    let v = &outcome.validation;
    let mut out: Vec<(String, String)> = v
        .metrics
        .iter()
        .map(|m| {
            (
                format!(
                    "{}: held-out RMSE (uncompensated {:.2} µm; {})",
                    m.target,
                    m.uncompensated_rmse_um,
                    change(m.rmse_reduction_percent)
                ),
                format!("{:.2} µm", m.rmse_um),
            )
        })
        .collect();
    if v.per_run.len() > 1 {
        let worse = v
            .per_run
            .iter()
            .filter(|r| {
                r.targets
                    .iter()
                    .any(|t| t.metrics.rmse_reduction_percent < 0.0)
            })
            .count();
        out.push((
            "held-out runs made worse than uncompensated".into(),
            format!("{worse} of {}", v.per_run.len()),
        ));
    }
    out
}

/// Writes the report of a fit into `dir`; returns the HTML file.
pub fn write(
    dir: &Path,
    ds: &Dataset,
    outcome: &Outcome,
    warnings: &[String],
) -> Result<PathBuf, CliError> {
    let v = &outcome.validation;
    let temperatures = ds
        .input_names
        .iter()
        .zip(&ds.input_kinds)
        .enumerate()
        .filter(|(_, (_, kind))| matches!(kind, InputKind::Temperature))
        .map(|(j, (name, _))| {
            (
                name.clone(),
                ds.runs
                    .iter()
                    .flat_map(|r| r.inputs[j].iter().copied())
                    .collect(),
            )
        })
        .collect();
    let mut protocol = vec![
        ("validation".to_string(), v.protocol_text.clone()),
        (
            "predictions shown".to_string(),
            "out of fold only: each row by the model of the fold that held it out; rows no fold held out (a chronological split's training part) show none".to_string(),
        ),
        (
            "runs".to_string(),
            ds.runs.iter().map(|r| r.name.as_str()).collect::<Vec<_>>().join("; ") + " — laid end to end on the time axis",
        ),
        (
            "sign".to_string(),
            "error = actual − nominal, relative to each run's first sample; residual = measured − predicted".to_string(),
        ),
    ];
    protocol.extend(warnings.iter().map(|w| ("warning".to_string(), w.clone())));
    let data = ReportData {
        title: format!(
            "truepos fit: {} on {} run(s)",
            ds.target_names.join(", "),
            ds.runs.len()
        ),
        time_s: end_to_end(ds),
        run_starts: run_starts(ds),
        test_from: Some(0),
        channels: channels(ds, outcome),
        temperatures,
        protocol,
        headline: headline(outcome),
        runs: runs(outcome, ds),
        ..Default::default()
    };
    Ok(write_report(dir, &data)?)
}
