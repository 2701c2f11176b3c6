//! The outer validation, one loop for the dynamic fit ([`crate::validate`]) and the machine fit
//! ([`crate::machine_fit`]): [`cross_validate`] selects and fits on each fold's training rows,
//! predicts its test rows, and then fits the model to write on every row. Its bookkeeping
//! ([`OutOfFold`]): which fold held each row out, every held-out row's measured and predicted
//! value per target (the pooled figures), and the prediction each row of every run gets — its
//! own fold's when a fold held it out or owns it, else the final model's.

use crate::dataset::Dataset;
use crate::validate::{all_rows, Predictions, Split};

/// Rows as (run, row).
pub(crate) type Rows = Vec<(usize, usize)>;

/// What the outer loop asks of a fit procedure.
pub(crate) trait Procedure {
    /// What a selection and fit on some rows gives.
    type Model;
    /// Selects and fits on `rows`.
    fn fit(&mut self, rows: &[(usize, usize)]) -> Result<Self::Model, String>;
    /// The model's predictions of every row of every run.
    fn predict(&self, model: &Self::Model) -> Result<Predictions, String>;
    /// How many of `rows` have an input beyond the widened range the model saw on `train`
    /// (`predicted`: its predictions of every row): rows where, on the machine, it is clamped.
    fn rows_beyond(
        &self,
        model: &Self::Model,
        predicted: &Predictions,
        train: &[(usize, usize)],
        rows: &[(usize, usize)],
    ) -> usize;
}

/// One outer fold: its test rows and the model fitted on its training rows.
pub(crate) struct Fold<M> {
    pub test: Rows,
    pub model: M,
}

/// What [`cross_validate`] returns.
pub(crate) struct CrossValidated<M> {
    /// Every outer fold in order.
    pub folds: Vec<Fold<M>>,
    /// Per target, every held-out row's measured value and its fold's prediction.
    pub measured: Vec<Vec<f64>>,
    /// See `measured`.
    pub predicted: Vec<Vec<f64>>,
    /// The predictions of every row ([`OutOfFold::finish`]).
    pub done: Finished,
    /// Held-out rows with an input beyond what their fold's model was trained on.
    pub held_out_beyond: usize,
    /// The model to write: the same procedure on every row the user gave, whatever the split —
    /// the folds measure the procedure, and a model fitted on a part would leave the rest of
    /// the data unused on the machine.
    pub model: M,
    /// [`Self::model`]'s predictions of every row.
    pub fitted: Predictions,
    /// The rows [`Self::model`] was fitted on: every measured row.
    pub training_rows: Rows,
}

/// The outer protocol of every fit: for each fold of `split`, `procedure` selects and fits on
/// its training rows and predicts its test rows (targets `rel`); then it fits on every row.
/// `progress` gets (done, total) steps, the final fit the last one.
pub(crate) fn cross_validate<P: Procedure>(
    dataset: &Dataset,
    split: Split,
    rel: &[Vec<Vec<f64>>],
    procedure: &mut P,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<CrossValidated<P::Model>, String> {
    let splits = split.folds(dataset)?;
    let steps = splits.len() + 1;
    let mut held = OutOfFold::new(dataset);
    let mut folds = Vec::with_capacity(splits.len());
    let mut beyond = 0;
    for (f, (train, test)) in splits.into_iter().enumerate() {
        progress(f, steps);
        if test.is_empty() {
            return Err(format!("fold {}: no test rows", f + 1));
        }
        let model = procedure.fit(&train)?;
        let predicted = procedure.predict(&model)?;
        held.record(f, &test, rel, &predicted);
        beyond += procedure.rows_beyond(&model, &predicted, &train, &test);
        folds.push(Fold { test, model });
    }
    if folds.is_empty() {
        return Err("no folds".into());
    }
    progress(folds.len(), steps);
    let training_rows = all_rows(dataset);
    let model = procedure.fit(&training_rows)?;
    let fitted = procedure.predict(&model)?;
    progress(steps, steps);
    let measured = std::mem::take(&mut held.measured);
    let predicted = std::mem::take(&mut held.predicted);
    Ok(CrossValidated {
        folds,
        measured,
        predicted,
        done: held.finish(&fitted),
        held_out_beyond: beyond,
        model,
        fitted,
        training_rows,
    })
}

/// The outer folds' predictions, filled fold by fold ([`OutOfFold::record`]) and completed by
/// the final model ([`OutOfFold::finish`]).
pub(crate) struct OutOfFold {
    /// Per target, the measured value of every held-out row, in the order the folds held them.
    pub measured: Vec<Vec<f64>>,
    /// Per target, the prediction of every held-out row by the fold that held it out.
    pub predicted: Vec<Vec<f64>>,
    /// Per run and row, the fold that held it out.
    pub fold_of: Vec<Vec<Option<usize>>>,
    predictions: Predictions,
    /// Per run and row without a measurement, the measured row whose fold predicts it.
    owners: Vec<Vec<Option<usize>>>,
    /// Rows without a measurement that a fold predicted out of sample.
    filled: Vec<Vec<bool>>,
}

impl OutOfFold {
    pub(crate) fn new(dataset: &Dataset) -> Self {
        let nt = dataset.target_names.len();
        let runs = &dataset.runs;
        Self {
            measured: vec![Vec::new(); nt],
            predicted: vec![Vec::new(); nt],
            fold_of: runs.iter().map(|r| vec![None; r.len()]).collect(),
            predictions: runs
                .iter()
                .map(|r| vec![vec![f64::NAN; r.len()]; nt])
                .collect(),
            owners: owners(dataset),
            filled: runs.iter().map(|r| vec![false; r.len()]).collect(),
        }
    }

    /// Fold `f` held out `test` (measured rows); `rel` are the targets, `pred` the fold model's
    /// predictions of every row. The rows without a measurement that a held-out row owns get
    /// the same fold's prediction.
    pub(crate) fn record(
        &mut self,
        f: usize,
        test: &[(usize, usize)],
        rel: &[Vec<Vec<f64>>],
        pred: &Predictions,
    ) {
        for &(r, i) in test {
            self.fold_of[r][i] = Some(f);
            for k in 0..self.measured.len() {
                self.measured[k].push(rel[r][k][i]);
                self.predicted[k].push(pred[r][k][i]);
                self.predictions[r][k][i] = pred[r][k][i];
            }
        }
        for (r, run) in self.owners.iter().enumerate() {
            for (i, owner) in run.iter().enumerate() {
                if owner.is_some_and(|o| self.fold_of[r][o] == Some(f)) {
                    self.filled[r][i] = true;
                    for (k, col) in self.predictions[r].iter_mut().enumerate() {
                        col[i] = pred[r][k][i];
                    }
                }
            }
        }
    }

    /// The predictions of every row, whether each is out of fold, and which fold held each out.
    /// A row no fold predicted (a chronological split's training rows) has no honest prediction:
    /// it gets the final model's (`fitted`), and its flag says so.
    pub(crate) fn finish(mut self, fitted: &Predictions) -> Finished {
        let mut held = Vec::with_capacity(self.predictions.len());
        for (r, run) in self.predictions.iter_mut().enumerate() {
            let flags: Vec<bool> = (0..self.fold_of[r].len())
                .map(|i| self.fold_of[r][i].is_some() || self.filled[r][i])
                .collect();
            for (k, col) in run.iter_mut().enumerate() {
                for (i, v) in col.iter_mut().enumerate() {
                    if !flags[i] {
                        *v = fitted[r][k][i];
                    }
                }
            }
            held.push(flags);
        }
        Finished {
            predictions: self.predictions,
            held_out: held,
            fold_of: self.fold_of,
        }
    }
}

/// What [`OutOfFold::finish`] returns.
pub(crate) struct Finished {
    /// Per run, target and row: the out-of-fold prediction, or the final model's.
    pub predictions: Predictions,
    /// Per run and row: whether its prediction is out of fold.
    pub held_out: Vec<Vec<bool>>,
    /// Per run and row: the fold that held it out.
    pub fold_of: Vec<Vec<Option<usize>>>,
}

/// For each row without a measurement, the measured row of its run whose fold predicts it: the
/// last one before it, or at a run's start the first one after (the stretch of the run it lies
/// in); `None` for measured rows.
fn owners(dataset: &Dataset) -> Vec<Vec<Option<usize>>> {
    dataset
        .runs
        .iter()
        .map(|run| {
            let first = run.first_measured();
            let mut last = None;
            (0..run.len())
                .map(|i| {
                    if run.measured(i) {
                        last = Some(i);
                        None
                    } else {
                        last.or(first)
                    }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{InputKind, Run};

    /// Two runs of five rows, measured at rows 1 and 3 only (row 0 and the odd ones between
    /// carry no measurement).
    fn dataset() -> Dataset {
        let run = |name: &str| Run {
            name: name.into(),
            time_s: (0..5).map(|i| 60.0 * i as f64).collect(),
            inputs: vec![vec![20.0; 5]],
            targets: vec![vec![f64::NAN, 1.0, f64::NAN, 3.0, f64::NAN]],
        };
        Dataset {
            input_names: vec!["t".into()],
            input_kinds: vec![InputKind::Temperature],
            target_names: vec!["dz_um".into()],
            runs: vec![run("a"), run("b")],
        }
    }

    /// Fold `f` predicts every row as `10·(f + 1)`.
    fn pred(ds: &Dataset, f: usize) -> Predictions {
        ds.runs
            .iter()
            .map(|r| vec![vec![10.0 * (f + 1) as f64; r.len()]])
            .collect()
    }

    #[test]
    fn leave_one_run_out_holds_every_measured_row_and_its_unmeasured_rows() {
        let ds = dataset();
        let rel = ds.targets(true);
        let mut o = OutOfFold::new(&ds);
        o.record(0, &[(0, 1), (0, 3)], &rel, &pred(&ds, 0));
        o.record(1, &[(1, 1), (1, 3)], &rel, &pred(&ds, 1));
        // The unmeasured rows are never in a fold's test rows: the rule asks for measured ones.
        assert_eq!(o.measured[0], vec![1.0, 3.0, 1.0, 3.0]);
        assert_eq!(o.predicted[0], vec![10.0, 10.0, 20.0, 20.0]);
        let fitted = vec![vec![vec![-1.0; 5]]; 2];
        let done = o.finish(&fitted);
        assert_eq!(done.predictions[0][0], vec![10.0; 5]);
        assert_eq!(done.predictions[1][0], vec![20.0; 5]);
        assert!(done.held_out.iter().flatten().all(|&h| h));
        assert_eq!(done.fold_of[1][3], Some(1));
        assert_eq!(done.fold_of[1][2], None);
    }

    #[test]
    fn rows_no_fold_held_out_get_the_final_model_and_say_so() {
        let ds = dataset();
        let rel = ds.targets(true);
        let mut o = OutOfFold::new(&ds);
        // A chronological split: only each run's last measured row is tested.
        o.record(0, &[(0, 3), (1, 3)], &rel, &pred(&ds, 0));
        let fitted = vec![vec![vec![-1.0; 5]]; 2];
        let done = o.finish(&fitted);
        // Rows 0–2 belong to row 1's stretch (not held out), row 4 to row 3's (held out).
        assert_eq!(done.predictions[0][0], vec![-1.0, -1.0, -1.0, 10.0, 10.0]);
        assert_eq!(done.held_out[0], vec![false, false, false, true, true]);
    }
}
