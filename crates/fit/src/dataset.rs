//! Recorded runs in memory: time, inputs (what the control knows: temperatures, operating state)
//! and targets (measured errors, which a model must never read).

use std::fmt;

pub use truepos_io::dynamic_model_file::InputKind;

/// One recorded run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Where it came from (file, sheet), for messages.
    pub name: String,
    /// Time in s, strictly increasing.
    pub time_s: Vec<f64>,
    /// One column per input of the [`Dataset`].
    pub inputs: Vec<Vec<f64>>,
    /// One column per target of the [`Dataset`], µm.
    pub targets: Vec<Vec<f64>>,
}

impl Run {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// Whether it has no samples.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Target `k` relative to the run's first sample: the displacement since the start, which
    /// is what a model started with the run predicts and what "uncompensated" means.
    pub fn relative_target(&self, k: usize) -> Vec<f64> {
        let col = &self.targets[k];
        let first = col.first().copied().unwrap_or(0.0);
        col.iter().map(|v| v - first).collect()
    }
}

/// A dataset that does not hang together.
#[derive(Debug, Clone, PartialEq)]
pub enum DatasetError {
    /// A run's column has a different length than its time column.
    Length {
        /// Run name.
        run: String,
        /// Column name.
        column: String,
    },
    /// Time does not strictly increase.
    Time {
        /// Run name.
        run: String,
        /// Row (0-based sample index).
        row: usize,
    },
    /// A value is NaN or infinite.
    NonFinite {
        /// Run name.
        run: String,
        /// Column name.
        column: String,
        /// Row (0-based sample index).
        row: usize,
    },
    /// No runs, inputs or targets.
    Empty,
}

impl fmt::Display for DatasetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Length { run, column } => {
                write!(
                    f,
                    "{run}: column `{column}` does not have one value per time"
                )
            }
            Self::Time { run, row } => write!(
                f,
                "{run}: sample {row}: time must increase strictly (duplicate or backwards time)"
            ),
            Self::NonFinite { run, column, row } => {
                write!(
                    f,
                    "{run}: sample {row}, column `{column}`: not a finite number"
                )
            }
            Self::Empty => write!(f, "the dataset needs at least one run, input and target"),
        }
    }
}

impl std::error::Error for DatasetError {}

/// Several runs with the same inputs and targets: fitted together, validated apart.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Input names (column names of the runs).
    pub input_names: Vec<String>,
    /// Kind of each input.
    pub input_kinds: Vec<InputKind>,
    /// Target names.
    pub target_names: Vec<String>,
    /// The runs.
    pub runs: Vec<Run>,
}

impl Dataset {
    /// Checks lengths, time order and finiteness.
    pub fn check(&self) -> Result<(), DatasetError> {
        if self.runs.is_empty() || self.input_names.is_empty() || self.target_names.is_empty() {
            return Err(DatasetError::Empty);
        }
        for run in &self.runs {
            let cols = self
                .input_names
                .iter()
                .zip(&run.inputs)
                .chain(self.target_names.iter().zip(&run.targets));
            if run.inputs.len() != self.input_names.len()
                || run.targets.len() != self.target_names.len()
            {
                return Err(DatasetError::Length {
                    run: run.name.clone(),
                    column: "(column count)".into(),
                });
            }
            for (name, col) in cols {
                if col.len() != run.len() {
                    return Err(DatasetError::Length {
                        run: run.name.clone(),
                        column: name.clone(),
                    });
                }
                if let Some(row) = col.iter().position(|v| !v.is_finite()) {
                    return Err(DatasetError::NonFinite {
                        run: run.name.clone(),
                        column: name.clone(),
                        row,
                    });
                }
            }
            for (row, w) in run.time_s.windows(2).enumerate() {
                if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
                    return Err(DatasetError::Time {
                        run: run.name.clone(),
                        row: row + 1,
                    });
                }
            }
            if run.time_s.iter().any(|t| !t.is_finite()) {
                return Err(DatasetError::NonFinite {
                    run: run.name.clone(),
                    column: "time".into(),
                    row: run.time_s.iter().position(|t| !t.is_finite()).unwrap_or(0),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ds() -> Dataset {
        Dataset {
            input_names: vec!["t1".into()],
            input_kinds: vec![InputKind::Temperature],
            target_names: vec!["dz_um".into()],
            runs: vec![Run {
                name: "a.csv".into(),
                time_s: vec![0.0, 1.0, 2.0],
                inputs: vec![vec![20.0, 21.0, 22.0]],
                targets: vec![vec![5.0, 7.0, 4.0]],
            }],
        }
    }

    #[test]
    fn relative_target_subtracts_the_first_sample() {
        assert_eq!(ds().runs[0].relative_target(0), vec![0.0, 2.0, -1.0]);
        assert_eq!(ds().check(), Ok(()));
    }

    #[test]
    fn bad_datasets_are_named() {
        let mut d = ds();
        d.runs[0].time_s[2] = 1.0;
        assert_eq!(
            d.check().unwrap_err().to_string(),
            "a.csv: sample 2: time must increase strictly (duplicate or backwards time)"
        );
        let mut d = ds();
        d.runs[0].inputs[0][1] = f64::NAN;
        assert!(d.check().unwrap_err().to_string().contains("column `t1`"));
        let mut d = ds();
        d.runs[0].targets[0].pop();
        assert!(matches!(d.check(), Err(DatasetError::Length { .. })));
    }
}
