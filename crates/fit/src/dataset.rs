//! Recorded runs in memory: time, inputs (what the control knows: temperatures, operating state)
//! and targets (measured errors, which a model must never read); built from run tables read by
//! `truepos_io::run` and the columns a person names ([`Columns`], [`Dataset::from_tables`]).

use std::convert::Infallible;
use std::fmt;
use std::str::FromStr;

use truepos_files::InputError;
pub use truepos_io::model_file::filtered::InputKind;
pub use truepos_io::run::Time;
use truepos_io::run::{glob_match, RunTable};
use truepos_io::units::Role;

/// The largest |target| a run may hold, µm: 1 m. No machine errs by that much, so a value beyond
/// it is a wrong unit or a corrupt cell, and one such value is enough to wreck a fit (a 1e300
/// target gives a model with an intercept of 2.35e296 µm). Non-finite cells `truepos_io::run`
/// refuses itself.
pub const MAX_TARGET_UM: f64 = 1e6;

/// One recorded run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Where it came from (file, sheet), for messages.
    pub name: String,
    /// Time in s, strictly increasing.
    pub time_s: Vec<f64>,
    /// One column per input of the [`Dataset`].
    pub inputs: Vec<Vec<f64>>,
    /// One column per target of the [`Dataset`], µm; NaN where the row has no measurement
    /// (a probe every 15 minutes): such a row drives the filters but neither trains nor scores.
    pub targets: Vec<Vec<f64>>,
}

impl Run {
    /// The columns named `inputs` and `targets` of a table, and its time column.
    fn from_table(
        t: &RunTable,
        time: &Time,
        inputs: &[(String, InputKind)],
        targets: &[String],
    ) -> Result<Run, InputError> {
        let col = |name: &str| t.select(&[name]).map(|v| v[0]);
        // Temperatures in °C whatever unit their names state; operating state as written.
        let numbers = |names: &[(String, InputKind)]| -> Result<Vec<Vec<f64>>, InputError> {
            names
                .iter()
                .map(|(n, kind)| match kind {
                    InputKind::Temperature => t.numbers_as(col(n)?, Role::Temperature),
                    InputKind::Operating => t.numbers(col(n)?),
                })
                .collect()
        };
        let measured = |names: &[String]| -> Result<Vec<Vec<f64>>, InputError> {
            names
                .iter()
                .map(|n| {
                    let c = col(n)?;
                    let v = t.measured(c)?;
                    match v.iter().position(|x| x.abs() > MAX_TARGET_UM) {
                        Some(r) => Err(t.table.at(
                            r,
                            c,
                            format!(
                                "{:e} µm is not a measured error: more than {MAX_TARGET_UM:e} µm (1 m) away (a unit or a corrupt cell?)",
                                v[r]
                            ),
                        )),
                        None => Ok(v),
                    }
                })
                .collect()
        };
        Ok(Run {
            name: t.name(),
            time_s: t.times(time)?,
            inputs: numbers(inputs)?,
            targets: measured(targets)?,
        })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// Whether it has no samples.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Target `k` as measured (`absolute`) or [relative to the run's first
    /// sample](Self::relative_target).
    pub fn target(&self, k: usize, absolute: bool) -> Vec<f64> {
        if absolute {
            self.targets[k].clone()
        } else {
            self.relative_target(k)
        }
    }

    /// Target `k` relative to the run's first measured sample: the displacement since the
    /// start, which is what a model started with the run predicts and what "uncompensated"
    /// means (NaN where the row has no measurement). A run should therefore be measured at its
    /// start; [`Run::first_measured`] tells where it was.
    pub fn relative_target(&self, k: usize) -> Vec<f64> {
        let col = &self.targets[k];
        let first = col.iter().copied().find(|v| !v.is_nan()).unwrap_or(0.0);
        col.iter().map(|v| v - first).collect()
    }

    /// Whether row `i` has a measurement of every target (only such rows train and score).
    pub fn measured(&self, i: usize) -> bool {
        self.targets.iter().all(|c| !c[i].is_nan())
    }

    /// Rows with a measurement of every target.
    pub fn measured_rows(&self) -> usize {
        (0..self.len()).filter(|&i| self.measured(i)).count()
    }

    /// The first row with a measurement of every target.
    pub fn first_measured(&self) -> Option<usize> {
        (0..self.len()).find(|&i| self.measured(i))
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
    /// A run table does not have a named column, or a cell is not a number.
    Input(InputError),
    /// A column chosen both as an input and as a target.
    InputIsTarget {
        /// Column name.
        column: String,
    },
    /// Two runs with one name (the same run-column value in two files).
    DuplicateRun {
        /// The name.
        run: String,
    },
    /// A run without a single row that has a measurement of every target.
    NoMeasuredRow {
        /// Run name.
        run: String,
    },
    /// A name that should be a temperature input of the dataset is not one.
    NotATemperature {
        /// The name given.
        name: String,
        /// The temperature inputs there are.
        temperatures: Vec<String>,
    },
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
            Self::DuplicateRun { run } => write!(
                f,
                "two runs are named `{run}`: the values of a run column name runs and must differ between files"
            ),
            Self::NoMeasuredRow { run } => write!(
                f,
                "{run}: no row has a value in every target column: a row trains and scores only where every target is measured"
            ),
            Self::Input(e) => write!(f, "{e}"),
            Self::InputIsTarget { column } => write!(
                f,
                "column `{column}` is both an input and a target: a model must never read the measured error"
            ),
            Self::NotATemperature { name, temperatures } => write!(
                f,
                "`{name}`: not a temperature input; the temperature inputs are {}",
                temperatures.join(", ")
            ),
        }
    }
}

impl std::error::Error for DatasetError {}

impl From<InputError> for DatasetError {
    fn from(e: InputError) -> Self {
        Self::Input(e)
    }
}

/// Column names or globs (`*` any run of characters, `?` one character), comma-separated:
/// `t*_c,spindle_rpm`. Empty items are dropped.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Patterns(pub Vec<String>);

impl Patterns {
    fn as_strs(&self) -> Vec<&str> {
        self.0.iter().map(String::as_str).collect()
    }

    /// Whether any pattern matches `name`.
    pub fn matches(&self, name: &str) -> bool {
        self.0.iter().any(|p| glob_match(p, name))
    }
}

impl FromStr for Patterns {
    type Err = Infallible;

    fn from_str(s: &str) -> Result<Self, Infallible> {
        Ok(Self(
            s.split(',')
                .map(str::trim)
                .filter(|p| !p.is_empty())
                .map(String::from)
                .collect(),
        ))
    }
}

/// The most inputs one fit takes. Every input gives several candidate features (its lags and
/// rates), and the fit's QR triangles grow with the square of their number: 1 000 inputs on
/// 3 898 rows still ran after 300 s at 3.3 GB, while a machine has tens of sensors.
pub const MAX_INPUTS: usize = 256;

/// The most input values (inputs × rows over all runs) one fit takes: 10⁷ rows × 3 inputs
/// need 1.2 GB, so 10⁸ values stay within about 4 GB, and a month of 1 s logs of 30 inputs
/// (7.8·10⁷) fits.
pub const MAX_INPUT_VALUES: usize = 100_000_000;

/// Refuses a fit beyond [`MAX_INPUTS`] or [`MAX_INPUT_VALUES`] before any work, naming the
/// inputs and the rows.
pub fn check_budget(inputs: usize, rows: usize) -> Result<(), String> {
    if inputs > MAX_INPUTS {
        return Err(format!(
            "{inputs} inputs × {rows} rows: more than the {MAX_INPUTS} inputs one fit takes (its \
             work and memory grow with the square of the inputs); choose fewer with --inputs"
        ));
    }
    let values = inputs.saturating_mul(rows);
    if values > MAX_INPUT_VALUES {
        return Err(format!(
            "{inputs} inputs × {rows} rows = {values} input values: more than the \
             {MAX_INPUT_VALUES} one fit takes (about 4 GB of memory); choose fewer inputs or \
             fewer rows (a longer sample period)"
        ));
    }
    Ok(())
}

/// Whether a glob of inputs leaves `name` out: the time column and the columns whose unit is a
/// length or an angle (axis positions, measured errors) are no inputs unless named exactly, so
/// `t*` takes the temperatures `t1_c, t2_c`, not `time_s`.
fn glob_leaves_out(name: &str, time: &Time) -> bool {
    use truepos_io::units::Unit;
    let is_time = matches!(time, Time::Column(t) if glob_match(t, name));
    let position = matches!(
        truepos_io::units::unit_of(name),
        Ok(Some(
            Unit::Nanometre
                | Unit::Micrometre
                | Unit::Millimetre
                | Unit::Metre
                | Unit::Inch
                | Unit::Degree
        ))
    );
    is_time || position
}

/// The input columns of `first`: each pattern in order, each column once; a glob never takes
/// what [`glob_leaves_out`], and a glob that matches only such columns is an error naming them.
fn input_columns(
    first: &RunTable,
    patterns: &Patterns,
    time: &Time,
) -> Result<Vec<String>, InputError> {
    let mut out: Vec<String> = Vec::new();
    for p in &patterns.0 {
        let found = first.select(&[p.as_str()])?;
        let names = found.iter().map(|&c| first.columns[c].clone());
        let kept: Vec<String> = if p.contains(['*', '?']) {
            let kept: Vec<String> = names.filter(|n| !glob_leaves_out(n, time)).collect();
            if kept.is_empty() {
                let left: Vec<&str> = found.iter().map(|&c| first.columns[c].as_str()).collect();
                return Err(InputError::file(
                    &first.file,
                    format!(
                        "--inputs `{p}` matches only {}, the time or position columns, which a \
                         glob never takes as inputs: name such a column exactly to use it",
                        left.join(", ")
                    ),
                ));
            }
            kept
        } else {
            names.collect()
        };
        for n in kept {
            if !out.contains(&n) {
                out.push(n);
            }
        }
    }
    Ok(out)
}

/// Which columns of the run tables a dataset reads.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    /// The time: a column of seconds or ISO 8601 date-times, or a sample period.
    pub time: Time,
    /// Input columns: what the control knows.
    pub inputs: Patterns,
    /// Target columns: measured errors in µm.
    pub targets: Patterns,
    /// Which inputs are operating state (filtered as is, and squared) rather than temperatures.
    pub operating: Patterns,
}

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
    /// Per run, per target, the values as measured (`absolute`) or relative to the run's first
    /// sample ([`Run::target`]): what every fit and score compares with.
    pub fn targets(&self, absolute: bool) -> Vec<Vec<Vec<f64>>> {
        let nt = self.target_names.len();
        self.runs
            .iter()
            .map(|r| (0..nt).map(|k| r.target(k, absolute)).collect())
            .collect()
    }

    /// The dataset of several runs with the same columns: inputs and targets are chosen on the
    /// first table (in pattern order, each column once) and read by name from every table, so
    /// a run without one of them is refused naming it. Checked ([`Dataset::check`]).
    pub fn from_tables(tables: &[RunTable], columns: &Columns) -> Result<Dataset, DatasetError> {
        let first = tables.first().ok_or(DatasetError::Empty)?;
        let names = |patterns: &Patterns| -> Result<Vec<String>, InputError> {
            let cols = first.select(&patterns.as_strs())?;
            Ok(cols.iter().map(|&c| first.columns[c].clone()).collect())
        };
        let input_names = input_columns(first, &columns.inputs, &columns.time)?;
        let target_names = names(&columns.targets)?;
        if let Some(both) = input_names.iter().find(|n| target_names.contains(n)) {
            return Err(DatasetError::InputIsTarget {
                column: both.clone(),
            });
        }
        let input_kinds: Vec<InputKind> = input_names
            .iter()
            .map(|n| {
                // A speed, load or power is operating state by its unit too (`S [1/min]`).
                let by_unit = truepos_io::units::unit_of(n)
                    .is_ok_and(|u| u.is_some_and(|u| u.is_operating()));
                if columns.operating.matches(n) || by_unit {
                    InputKind::Operating
                } else {
                    InputKind::Temperature
                }
            })
            .collect();
        let named: Vec<(String, InputKind)> = input_names
            .iter()
            .cloned()
            .zip(input_kinds.iter().copied())
            .collect();
        let runs: Vec<Run> = tables
            .iter()
            .map(|t| Run::from_table(t, &columns.time, &named, &target_names))
            .collect::<Result<_, _>>()?;
        // Runs named by a run column must differ: the value is all that names them in the
        // output (a file given twice keeps its meaning: two runs with the file's name).
        if let Some(i) = (0..runs.len())
            .find(|&i| tables[i].run.is_some() && runs[..i].iter().any(|b| b.name == runs[i].name))
        {
            return Err(DatasetError::DuplicateRun {
                run: runs[i].name.clone(),
            });
        }
        let ds = Dataset {
            input_names,
            input_kinds,
            target_names,
            runs,
        };
        ds.check()?;
        Ok(ds)
    }

    /// The index of the temperature input `name` (e.g. the reference sensor of the
    /// reference-sensor regression).
    pub fn temperature_input(&self, name: &str) -> Result<usize, DatasetError> {
        let temperatures = || {
            (0..self.input_names.len()).filter(|&i| self.input_kinds[i] == InputKind::Temperature)
        };
        temperatures()
            .find(|&i| self.input_names[i] == name)
            .ok_or_else(|| DatasetError::NotATemperature {
                name: name.to_string(),
                temperatures: temperatures()
                    .map(|i| self.input_names[i].clone())
                    .collect(),
            })
    }

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
            for (c, (name, col)) in cols.enumerate() {
                if col.len() != run.len() {
                    return Err(DatasetError::Length {
                        run: run.name.clone(),
                        column: name.clone(),
                    });
                }
                // A target may be NaN (not measured in that row), never infinite.
                let bad = |v: &f64| {
                    if c < self.input_names.len() {
                        !v.is_finite()
                    } else {
                        v.is_infinite()
                    }
                };
                if let Some(row) = col.iter().position(bad) {
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
            if run.first_measured().is_none() && !run.is_empty() {
                return Err(DatasetError::NoMeasuredRow {
                    run: run.name.clone(),
                });
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

/// One run of one temperature sensor `t1_c` and one target `dz_um`: the shape of the fitting
/// crate's single-lag test cases.
#[cfg(test)]
pub(crate) fn one_sensor(time_s: Vec<f64>, temperature: Vec<f64>, target: Vec<f64>) -> Dataset {
    Dataset {
        input_names: vec!["t1_c".into()],
        input_kinds: vec![InputKind::Temperature],
        target_names: vec!["dz_um".into()],
        runs: vec![Run {
            name: "r".into(),
            time_s,
            inputs: vec![temperature],
            targets: vec![target],
        }],
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

    fn table(text: &str) -> RunTable {
        truepos_io::run::parse_csv(std::path::Path::new("day.csv"), text).unwrap()
    }

    fn columns(inputs: &str, targets: &str) -> Columns {
        Columns {
            time: Time::default(),
            inputs: inputs.parse().unwrap(),
            targets: targets.parse().unwrap(),
            operating: "*rpm*".parse().unwrap(),
        }
    }

    #[test]
    fn a_dataset_is_built_from_tables_and_column_globs() {
        let t = table("time_s,t1_c,t2_c,spindle_rpm,dz_um\n0,20,21,0,1\n10,21,22,3000,2\n");
        let ds =
            Dataset::from_tables(&[t.clone(), t], &columns("t*_c, spindle_rpm", "*_um")).unwrap();
        assert_eq!(ds.input_names, ["t1_c", "t2_c", "spindle_rpm"]);
        assert_eq!(
            ds.input_kinds,
            [
                InputKind::Temperature,
                InputKind::Temperature,
                InputKind::Operating
            ]
        );
        assert_eq!(ds.target_names, ["dz_um"]);
        assert_eq!(ds.runs.len(), 2);
        assert_eq!(ds.runs[1].inputs[2], [0.0, 3000.0]);
        assert_eq!(ds.temperature_input("t2_c"), Ok(1));
        assert_eq!(
            ds.temperature_input("spindle_rpm").unwrap_err().to_string(),
            "`spindle_rpm`: not a temperature input; the temperature inputs are t1_c, t2_c"
        );
    }

    #[test]
    fn a_target_read_as_an_input_or_a_missing_column_is_refused() {
        let t = table("time_s,t1_c,dz_um\n0,20,1\n10,21,2\n");
        let e = Dataset::from_tables(std::slice::from_ref(&t), &columns("t1_c,dz_um", "dz_um"))
            .unwrap_err();
        assert_eq!(
            e,
            DatasetError::InputIsTarget {
                column: "dz_um".into()
            }
        );
        let e =
            Dataset::from_tables(std::slice::from_ref(&t), &columns("t9_c", "dz_um")).unwrap_err();
        assert!(e.to_string().contains("no column matches `t9_c`"), "{e}");
        let other = table("time_s,t1_c\n0,20\n");
        let e = Dataset::from_tables(&[t, other], &columns("t1_c", "dz_um")).unwrap_err();
        assert!(e.to_string().contains("no column matches `dz_um`"), "{e}");
        assert_eq!(
            Dataset::from_tables(&[], &columns("t1_c", "dz_um")),
            Err(DatasetError::Empty)
        );
    }

    /// Empty target cells are rows without a measurement: NaN, kept for the filters; targets
    /// count from the first measured row; a target in mm and a temperature in °F are converted.
    #[test]
    fn sparse_targets_and_units() {
        let t = table("time_s,t1 (°F),dz_mm\n0,68,\n10,69.8,0.002\n20,71.6,\n30,73.4,0.005\n");
        let ds = Dataset::from_tables(&[t], &columns("t1 (°F)", "dz_mm")).unwrap();
        let run = &ds.runs[0];
        assert!((run.inputs[0][1] - 21.0).abs() < 1e-12);
        assert!(run.targets[0][0].is_nan());
        assert!((run.targets[0][3] - 5.0).abs() < 1e-12);
        assert_eq!((run.measured_rows(), run.first_measured()), (2, Some(1)));
        let rel = run.relative_target(0);
        assert!(rel[0].is_nan() && rel[1] == 0.0 && (rel[3] - 3.0).abs() < 1e-12);
        let t = table("time_s,t1_c,dz_um\n0,20,\n10,21,\n");
        assert_eq!(
            Dataset::from_tables(&[t], &columns("t1_c", "dz_um"))
                .unwrap_err()
                .to_string(),
            "day.csv:1:3: `dz_um`: no measured value in this column (every cell is empty)"
        );
    }

    /// An absurd target is refused at its cell (file:line:column: name); 1 m itself still passes.
    #[test]
    fn an_absurd_target_is_refused_at_its_cell() {
        let t = table("time_s,t1_c,dz_um\n0,20,1\n10,21,1e300\n20,22,-2e6\n");
        let e = Dataset::from_tables(&[t], &columns("t1_c", "dz_um")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "day.csv:3:3: `dz_um`: 1e300 µm is not a measured error: more than 1e6 µm (1 m) away (a unit or a corrupt cell?)"
        );
        let t = table("time_s,t1_c,dz_um\n0,20,1\n10,21,-1e6\n");
        assert!(Dataset::from_tables(&[t], &columns("t1_c", "dz_um")).is_ok());
    }
}
