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
use crate::out_of_fold::{cross_validate, Procedure};
use crate::selection::CLEARLY_BETTER;
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
        let all = all_rows(dataset);
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

/// The figures of one target on one run's held-out rows, and what chose its model.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOut {
    /// Figures on the run's held-out rows.
    #[serde(flatten)]
    pub metrics: Metrics,
    /// The family the inner selection chose for this target in the fold that held the run out;
    /// several, joined by " / ", when folds cut the run (blocked k-fold).
    pub family: String,
    /// The baseline's RMSE on the same rows (µm), fitted on the same training rows: the simple
    /// reference the choice is judged against.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_rmse_um: Option<f64>,
}

/// One run's held-out rows, judged on their own: a pooled figure can hide a run the model makes
/// worse.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunFigures {
    /// The run's name (its file, and sheet for workbooks).
    pub run: String,
    /// Per target.
    pub targets: Vec<HeldOut>,
}

/// How well the inner validation predicted the test error of one target: the selection trusts
/// the inner figure, so a ratio far from 1 says the choice rested on a wrong estimate.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InnerVsTest {
    /// Target name.
    pub target: String,
    /// The inner-validation RMSE of the choice, root mean square over the outer folds (µm).
    pub inner_cv_rmse_um: f64,
    /// The pooled test RMSE (µm).
    pub test_rmse_um: f64,
    /// test / inner.
    pub test_to_inner: f64,
}

/// Per target, the outer folds' inner estimates against the pooled test RMSE.
/// `inner[fold][target]` is each outer fold's inner estimate.
pub fn inner_vs_test(metrics: &[Metrics], inner: &[Vec<f64>]) -> Vec<InnerVsTest> {
    metrics
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let folds = inner.len().max(1) as f64;
            let inner = (inner.iter().map(|c| c[k].powi(2)).sum::<f64>() / folds).sqrt();
            InnerVsTest {
                target: m.target.clone(),
                inner_cv_rmse_um: inner,
                test_rmse_um: m.rmse_um,
                test_to_inner: if inner > 0.0 {
                    m.rmse_um / inner
                } else {
                    f64::INFINITY
                },
            }
        })
        .collect()
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
    /// Per run, its held-out rows (every run: leave-one-run-out and blocked k-fold hold out
    /// every row once, a chronological split the end of every run).
    pub per_run: Vec<RunFigures>,
    /// Per outer fold, what the inner selection chose.
    pub choices: Vec<Vec<Choice>>,
    /// Temperature sensors used per outer fold (names).
    pub sensors: Vec<Vec<String>>,
    /// Per target: the inner validation's estimate beside the test error it should predict.
    pub inner_vs_test: Vec<InnerVsTest>,
    /// Per target, the baseline's figures pooled over the same held-out rows (`None` when a fold
    /// could not build it).
    pub baseline_metrics: Option<Vec<Metrics>>,
    /// Held-out rows with an input beyond the widened range their fold's model was trained on:
    /// rows where the figures extrapolate while on the machine the model is clamped.
    pub held_out_rows_beyond_training: usize,
    /// Warnings from the fits, every held-out run the model makes worse than uncompensated, and
    /// every one the baseline would have done better on.
    pub warnings: Vec<String>,
}

/// Predicted errors (µm): per run, per target, per sample.
pub type Predictions = Vec<Vec<Vec<f64>>>;

/// Predictions of a trained model over whole runs (every row), by stepping the real-time model.
pub fn predict(dataset: &Dataset, trained: &Trained) -> Result<Predictions, String> {
    predict_with(dataset, &trained.model, &trained.inputs)
}

/// Predictions of `model`, whose inputs are the dataset's `inputs`, over whole runs.
pub fn predict_with(
    dataset: &Dataset,
    model: &truepos_model::DynamicModel,
    inputs: &[usize],
) -> Result<Predictions, String> {
    let mut model = model.clone();
    let nt = model.output_count();
    let mut out = Vec::new();
    let mut row = vec![0.0; inputs.len()];
    for run in &dataset.runs {
        model.reset();
        let mut pred = vec![Vec::with_capacity(run.len()); nt];
        for i in 0..run.len() {
            for (slot, &d) in row.iter_mut().zip(inputs) {
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

/// Every measured row of every run as (run, row), in time order run after run: a row without
/// a measurement of every target neither trains nor scores (its inputs still step the filters,
/// which run over whole runs).
pub(crate) fn all_rows(dataset: &Dataset) -> Vec<(usize, usize)> {
    dataset
        .runs
        .iter()
        .enumerate()
        .flat_map(|(r, run)| {
            (0..run.len())
                .filter(|&i| run.measured(i))
                .map(move |i| (r, i))
        })
        .collect()
}

/// Runs the protocol: for each outer fold, select and fit on its training rows, predict its test
/// rows. Returns the figures, the model to write (the same selection and fit on every row) and
/// the out-of-fold predictions ([`Outcome::predictions`]).
pub fn validate(
    dataset: &Dataset,
    cand: &Candidates,
    split: Split,
    settings: &Settings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Validation, Trained, Predictions), String> {
    let o = outcome(dataset, cand, split, settings, progress)?;
    Ok((o.validation, o.trained, o.predictions))
}

/// The dynamic fit as the outer loop's procedure: [`train`] on the rows, the real-time model
/// stepped through every run.
struct DynamicFit<'a> {
    dataset: &'a Dataset,
    cand: &'a Candidates,
    settings: &'a Settings,
}

impl Procedure for DynamicFit<'_> {
    type Model = Trained;

    fn fit(&mut self, rows: &[(usize, usize)]) -> Result<Trained, String> {
        train(self.dataset, self.cand, rows, self.settings)
    }

    fn predict(&self, model: &Trained) -> Result<Predictions, String> {
        predict(self.dataset, model)
    }

    fn rows_beyond(
        &self,
        model: &Trained,
        predicted: &Predictions,
        train: &[(usize, usize)],
        rows: &[(usize, usize)],
    ) -> usize {
        let env = crate::export::training_envelope(self.dataset, &model.inputs, predicted, train);
        crate::export::rows_beyond(self.dataset, &env, rows)
    }
}

/// [`validate`], with everything a report or a model file needs.
pub fn outcome(
    dataset: &Dataset,
    cand: &Candidates,
    split: Split,
    settings: &Settings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Outcome, String> {
    let nt = dataset.target_names.len();
    let rel: Vec<Vec<Vec<f64>>> = dataset.targets(settings.absolute_targets);
    let mut procedure = DynamicFit {
        dataset,
        cand,
        settings,
    };
    let cv = cross_validate(dataset, split, &rel, &mut procedure, progress)?;
    let mut baseline = Some(Baseline::new(dataset));
    let mut warnings = Vec::new();
    for fold in &cv.folds {
        baseline = match (baseline, &fold.model.baseline) {
            (Some(mut b), Some(model)) => {
                b.record(
                    &fold.test,
                    &predict_with(dataset, &model.model, &model.inputs)?,
                );
                Some(b)
            }
            _ => None,
        };
        warnings.extend(fold.model.warnings.iter().cloned());
    }
    let choices: Vec<Vec<Choice>> = cv.folds.iter().map(|f| f.model.choices.clone()).collect();
    let sensors: Vec<Vec<String>> = cv
        .folds
        .iter()
        .map(|f| {
            f.model
                .sensors
                .iter()
                .map(|&s| dataset.input_names[s].clone())
                .collect()
        })
        .collect();
    let metrics: Vec<Metrics> = (0..nt)
        .map(|k| Metrics::new(&dataset.target_names[k], &cv.measured[k], &cv.predicted[k]))
        .collect();
    let done = cv.done;
    let chosen: Vec<Vec<String>> = choices
        .iter()
        .map(|c| c.iter().map(|c| c.label()).collect())
        .collect();
    let mut per_run = per_run(dataset, &rel, &done.predictions, &done.fold_of, &chosen);
    warnings.extend(worse_than_uncompensated(&per_run));
    let baseline_metrics = baseline.map(|b| b.judge(dataset, &rel, &done.fold_of, &mut per_run));
    warnings.extend(baseline_better(&per_run));
    let inner: Vec<Vec<f64>> = choices
        .iter()
        .map(|c| c.iter().map(|c| c.cv_rmse_um).collect())
        .collect();
    let inner_vs_test = inner_vs_test(&metrics, &inner);
    Ok(Outcome {
        validation: Validation {
            protocol: split,
            protocol_text: format!(
                "{split}; selection inside each training part: {}",
                settings.describe_selection()
            ),
            metrics,
            per_run,
            choices,
            sensors,
            inner_vs_test,
            baseline_metrics,
            held_out_rows_beyond_training: cv.held_out_beyond,
            warnings,
        },
        trained: cv.model,
        predictions: done.predictions,
        held_out: done.held_out,
        fitted: cv.fitted,
        training_rows: cv.training_rows,
        absolute_targets: settings.absolute_targets,
    })
}

/// Figures of every run's held-out rows, with the family each fold that held them out chose.
pub(crate) fn per_run(
    dataset: &Dataset,
    rel: &[Vec<Vec<f64>>],
    oof: &Predictions,
    fold_of: &[Vec<Option<usize>>],
    chosen: &[Vec<String>],
) -> Vec<RunFigures> {
    let mut out = Vec::new();
    for (r, run) in dataset.runs.iter().enumerate() {
        let rows: Vec<usize> = (0..run.len())
            .filter(|&i| fold_of[r][i].is_some())
            .collect();
        if rows.is_empty() {
            continue;
        }
        let mut folds: Vec<usize> = rows.iter().filter_map(|&i| fold_of[r][i]).collect();
        folds.dedup();
        let targets = (0..dataset.target_names.len())
            .map(|k| {
                // A position-dependent model refuses an input it cannot read (NaN there; the pooled
                // figures say how many); a dynamic model's predictions are always finite.
                let (m, p): (Vec<f64>, Vec<f64>) = rows
                    .iter()
                    .filter(|&&i| oof[r][k][i].is_finite())
                    .map(|&i| (rel[r][k][i], oof[r][k][i]))
                    .unzip();
                let mut families: Vec<&str> = Vec::new();
                for &f in &folds {
                    let name = chosen[f][k].as_str();
                    if !families.contains(&name) {
                        families.push(name);
                    }
                }
                HeldOut {
                    metrics: Metrics::new(&dataset.target_names[k], &m, &p),
                    family: families.join(" / "),
                    baseline_rmse_um: None,
                }
            })
            .collect();
        out.push(RunFigures {
            run: run.name.clone(),
            targets,
        });
    }
    out
}

/// A warning for every run and target whose held-out rows the model makes worse than leaving
/// them uncompensated.
pub fn worse_than_uncompensated(per_run: &[RunFigures]) -> Vec<String> {
    per_run
        .iter()
        .flat_map(|r| {
            r.targets
                .iter()
                .filter(|h| h.metrics.rmse_um > h.metrics.uncompensated_rmse_um)
                .map(move |h| {
                    format!(
                        "run {}, {} held out: the model makes it worse: RMSE {:.2} µm compensated, {:.2} µm uncompensated",
                        r.run, h.metrics.target, h.metrics.rmse_um, h.metrics.uncompensated_rmse_um
                    )
                })
        })
        .collect()
}

/// The baseline's out-of-fold predictions, beside the choice's: each held-out row predicted by
/// the baseline fitted on the same training rows.
struct Baseline {
    predictions: Predictions,
}

impl Baseline {
    fn new(dataset: &Dataset) -> Self {
        let nt = dataset.target_names.len();
        Self {
            predictions: dataset
                .runs
                .iter()
                .map(|r| vec![vec![f64::NAN; r.len()]; nt])
                .collect(),
        }
    }

    fn record(&mut self, test: &[(usize, usize)], pred: &Predictions) {
        for &(r, i) in test {
            for (k, col) in self.predictions[r].iter_mut().enumerate() {
                col[i] = pred[r][k][i];
            }
        }
    }

    /// Per target the pooled figures over every held-out row, and each run's baseline RMSE set
    /// in `per_run`.
    fn judge(
        &self,
        dataset: &Dataset,
        rel: &[Vec<Vec<f64>>],
        fold_of: &[Vec<Option<usize>>],
        per_run: &mut [RunFigures],
    ) -> Vec<Metrics> {
        let nt = dataset.target_names.len();
        let mut pooled = vec![(Vec::new(), Vec::new()); nt];
        for (r, run) in dataset.runs.iter().enumerate() {
            let figures = per_run.iter_mut().find(|f| f.run == run.name);
            let mut each = vec![(Vec::new(), Vec::new()); nt];
            for i in (0..run.len()).filter(|&i| fold_of[r][i].is_some()) {
                for k in 0..nt {
                    let p = self.predictions[r][k][i];
                    if p.is_finite() {
                        each[k].0.push(rel[r][k][i]);
                        each[k].1.push(p);
                    }
                }
            }
            if let Some(figures) = figures {
                for (h, (m, p)) in figures.targets.iter_mut().zip(&each) {
                    h.baseline_rmse_um = Some(Metrics::new("", m, p).rmse_um);
                }
            }
            for (all, (m, p)) in pooled.iter_mut().zip(each) {
                all.0.extend(m);
                all.1.extend(p);
            }
        }
        pooled
            .iter()
            .zip(&dataset.target_names)
            .map(|((m, p), name)| Metrics::new(name, m, p))
            .collect()
    }
}

/// A warning for every run and target whose held-out rows the baseline would have predicted
/// better than the model chosen, by more than a tenth.
pub fn baseline_better(per_run: &[RunFigures]) -> Vec<String> {
    per_run
        .iter()
        .flat_map(|r| {
            r.targets
                .iter()
                .filter(|h| {
                    h.baseline_rmse_um
                        .is_some_and(|b| b < CLEARLY_BETTER * h.metrics.rmse_um)
                })
                .map(move |h| {
                    format!(
                        "run {}, {} held out: the baseline would have done better: RMSE {:.2} µm, the model chosen {:.2} µm",
                        r.run,
                        h.metrics.target,
                        h.baseline_rmse_um.unwrap_or(f64::NAN),
                        h.metrics.rmse_um
                    )
                })
        })
        .collect()
}

/// A fit from a dataset: the validation figures, the model fitted on every row, and the predictions behind the figures.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Figures pooled over the outer folds, and per run.
    pub validation: Validation,
    /// The model to write: the same selection and fit on every row the user gave, whatever the
    /// split (the folds measure the procedure; the figures are theirs).
    pub trained: Trained,
    /// Out-of-fold predictions, per run, target and row: each held-out row predicted by the
    /// model of the fold that held it out (so every row, with leave-one-run-out and blocked
    /// k-fold); a row no fold held out (a chronological split's training part) by [`Self::trained`],
    /// in sample.
    pub predictions: Predictions,
    /// Per run and row, whether a fold held it out (whether its prediction is out of sample).
    pub held_out: Vec<Vec<bool>>,
    /// [`Self::trained`]'s predictions over every row of every run.
    pub fitted: Predictions,
    /// The rows [`Self::trained`] was fitted on, as (run, row).
    pub training_rows: Vec<(usize, usize)>,
    /// Whether targets were taken as measured rather than relative to each run's first sample
    /// ([`Settings::absolute_targets`]).
    pub absolute_targets: bool,
}

/// Candidate features of the dataset, then [`outcome`]: what `truepos fit` runs.
pub fn fit(
    dataset: &Dataset,
    split: Split,
    settings: &Settings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Outcome, String> {
    let cand = candidates(dataset, &settings.taus).map_err(|e| e.to_string())?;
    outcome(dataset, &cand, split, settings, progress)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::dataset::{InputKind, Run};
    use crate::features::Family;

    /// Three runs of one sensor: a and b grow 2 µm/K, c shrinks 1 µm/K, so a model fitted
    /// without c makes c worse than leaving it alone.
    pub(crate) fn three_runs() -> Dataset {
        let run = |name: &str, t0: f64, slope: f64, wobble: f64, k: f64| {
            let n = 60;
            let temp: Vec<f64> = (0..n)
                .map(|i| t0 + slope * i as f64 + wobble * (i % 3) as f64)
                .collect();
            let y = temp.iter().map(|t| k * (t - t0) + 3.0).collect();
            Run {
                name: name.into(),
                time_s: (0..n).map(|i| 60.0 * i as f64).collect(),
                inputs: vec![temp],
                targets: vec![y],
            }
        };
        Dataset {
            input_names: vec!["t1_c".into()],
            input_kinds: vec![InputKind::Temperature],
            target_names: vec!["dz_um".into()],
            runs: vec![
                run("a.csv", 20.0, 0.1, 0.0, 2.0),
                run("b.csv", 22.0, 0.05, 0.2, 2.0),
                run("c.csv", 21.0, 0.08, -0.1, -1.0),
            ],
        }
    }

    pub(crate) fn static_settings() -> Settings {
        Settings {
            families: vec![Family::Static],
            ridges: vec![0.0],
            ..Settings::default()
        }
    }

    fn run_outcome(ds: &Dataset, split: &str) -> Outcome {
        fit(
            ds,
            split.parse().unwrap(),
            &static_settings(),
            &mut |_, _| {},
        )
        .unwrap()
    }

    /// Leave-one-run-out and blocked k-fold: every row's prediction is that of a model fitted
    /// without it: for each fold, a model trained afresh on the fold's training rows predicts
    /// exactly what the outcome holds for the fold's test rows; and no row of a run the final
    /// model saw carries that model's in-sample prediction.
    #[test]
    fn every_row_is_predicted_by_a_model_that_did_not_see_it() {
        let ds = three_runs();
        let settings = static_settings();
        let cand = candidates(&ds, &settings.taus).unwrap();
        for split in ["runs", "kfold:3"] {
            let o = run_outcome(&ds, split);
            assert!(o.held_out.iter().flatten().all(|&h| h), "{split}");
            for (tr, te) in split.parse::<Split>().unwrap().folds(&ds).unwrap() {
                let alone = predict(&ds, &train(&ds, &cand, &tr, &settings).unwrap()).unwrap();
                for &(r, i) in &te {
                    assert!(!tr.contains(&(r, i)));
                    assert_eq!(o.predictions[r][0][i], alone[r][0][i], "{split} {r} {i}");
                }
            }
        }
        // The model to write is fitted on every run, not the last fold's (which never saw c) nor
        // a chronological split's training part (which never saw the ends of the runs): it is
        // what training on all rows gives, and its rows are all of them.
        for split in ["runs", "kfold:3", "chrono:0.6"] {
            let o = run_outcome(&ds, split);
            let all: Vec<(usize, usize)> = (0..3)
                .flat_map(|r| (0..ds.runs[r].len()).map(move |i| (r, i)))
                .collect();
            assert_eq!(o.training_rows, all, "{split}");
            let whole = predict(&ds, &train(&ds, &cand, &all, &settings).unwrap()).unwrap();
            assert_eq!(o.fitted, whole, "{split}");
        }
    }

    /// A run 20 K hotter than the others, held out, lies beyond the range its fold's model was
    /// trained on (widened by the margins) in every row; the others lie inside theirs.
    #[test]
    fn held_out_rows_beyond_their_folds_training_range_are_counted() {
        let mut ds = three_runs();
        for t in &mut ds.runs[1].inputs[0] {
            *t += 20.0;
        }
        let o = run_outcome(&ds, "runs");
        assert_eq!(o.validation.held_out_rows_beyond_training, 60);
    }

    /// A chronological split holds out the end of each run only, and says so.
    #[test]
    fn a_chronological_split_marks_its_training_rows() {
        let o = run_outcome(&three_runs(), "chrono:0.6");
        for run in &o.held_out {
            assert_eq!(run.iter().filter(|&&h| !h).count(), 36);
            assert!(run[..36].iter().all(|&h| !h) && run[36..].iter().all(|&h| h));
        }
        // The rows no fold held out carry the written model's in-sample predictions.
        for (r, run) in o.held_out.iter().enumerate() {
            for (i, _) in run.iter().enumerate().filter(|(_, h)| !**h) {
                assert_eq!(o.predictions[r][0][i], o.fitted[r][0][i]);
            }
        }
    }

    /// Per run: the held-out run c, predicted by the slope of a and b (2 µm/K) where it moves
    /// −1 µm/K, is made worse (residual 3·rise against 1·rise uncompensated), and a warning
    /// names it and both figures.
    #[test]
    fn per_run_figures_and_a_run_made_worse() {
        let ds = three_runs();
        let o = run_outcome(&ds, "runs");
        let v = &o.validation;
        assert_eq!(
            v.per_run.iter().map(|r| r.run.as_str()).collect::<Vec<_>>(),
            ["a.csv", "b.csv", "c.csv"]
        );
        let c = &v.per_run[2].targets[0];
        let rise = ds.runs[2].inputs[0]
            .iter()
            .map(|t| t - 21.0)
            .collect::<Vec<_>>();
        let rms = (rise.iter().map(|r| r * r).sum::<f64>() / rise.len() as f64).sqrt();
        assert!((c.metrics.uncompensated_rmse_um - rms).abs() < 1e-9);
        assert!((c.metrics.rmse_um - 3.0 * rms).abs() < 1e-6, "{c:?}");
        assert!((c.metrics.rmse_reduction_percent + 200.0).abs() < 1e-4);
        assert_eq!(c.family, "static");
        let worse: Vec<&String> = v.warnings.iter().filter(|w| w.contains("worse")).collect();
        assert!(
            worse.iter().any(|w| w.contains("run c.csv, dz_um")
                && w.contains(&format!("{:.2} µm compensated", 3.0 * rms))
                && w.contains(&format!("{rms:.2} µm uncompensated"))),
            "{worse:?}"
        );
        // The pooled figure is over the same rows as the per-run figures together.
        let n: usize = v.per_run.iter().map(|r| r.targets[0].metrics.samples).sum();
        assert_eq!(n, v.metrics[0].samples);
        // The baseline is fitted beside the family named, on the same training rows: on one
        // sensor it is the same regression at a whisper of ridge, so its figures are close.
        let b = c.baseline_rmse_um.unwrap();
        assert!(
            (b - c.metrics.rmse_um).abs() < 0.01 * c.metrics.rmse_um,
            "{b} {c:?}"
        );
        let pooled = &v.baseline_metrics.as_ref().unwrap()[0];
        assert_eq!(pooled.samples, v.metrics[0].samples);
    }

    /// A run the baseline predicts more than a tenth better than the model chosen is named.
    #[test]
    fn a_run_the_baseline_does_better_on_is_named() {
        let figures = |rmse: f64, baseline: f64| RunFigures {
            run: format!("r{rmse}"),
            targets: vec![HeldOut {
                metrics: Metrics::new("dz_um", &[rmse, -rmse], &[0.0, 0.0]),
                family: "dynamic".into(),
                baseline_rmse_um: Some(baseline),
            }],
        };
        let w = baseline_better(&[figures(2.0, 1.5), figures(2.0, 1.9), figures(1.0, 3.0)]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("run r2, dz_um held out: the baseline would have done better"));
        assert!(
            w[0].contains("RMSE 1.50 µm, the model chosen 2.00 µm"),
            "{w:?}"
        );
    }
}
