//! The outer validation's bookkeeping, one door for the dynamic fit ([`crate::validate`]) and
//! the machine fit ([`crate::machine_fit`]): which fold held each row out, every held-out row's
//! measured and predicted value per target (the pooled figures), and the prediction each row of
//! every run gets — its own fold's when a fold held it out or owns it, else the final model's.

use crate::dataset::Dataset;
use crate::validate::Predictions;

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

    /// Whether every measured row was held out once (leave-one-run-out, blocked k-fold): the
    /// folds then only measure the procedure, and the model to write is the same procedure on
    /// every row — else it would be the last fold's, which never saw the last run or block. A
    /// chronological split keeps its training part's model: the one its test figures describe.
    pub(crate) fn every_measured_row_held_out(&self, dataset: &Dataset) -> bool {
        dataset
            .runs
            .iter()
            .zip(&self.fold_of)
            .all(|(run, folds)| (0..run.len()).all(|i| !run.measured(i) || folds[i].is_some()))
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
        assert!(o.every_measured_row_held_out(&ds));
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
        assert!(!o.every_measured_row_held_out(&ds));
        let fitted = vec![vec![vec![-1.0; 5]]; 2];
        let done = o.finish(&fitted);
        // Rows 0–2 belong to row 1's stretch (not held out), row 4 to row 3's (held out).
        assert_eq!(done.predictions[0][0], vec![-1.0, -1.0, -1.0, 10.0, 10.0]);
        assert_eq!(done.held_out[0], vec![false, false, false, true, true]);
    }
}
