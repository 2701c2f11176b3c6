//! Recorded runs as tables: CSV files and Excel workbooks (`.xlsx`, `.xlsm`, `.xls`, `.ods`
//! through calamine, with the `xlsx` feature; one sheet per run), with columns chosen by name or glob (`t*_c`). Files
//! are read by [`crate::table`], the one reader of tables.
//!
//! Cells are kept as read and converted to numbers only for the columns a caller selects, so a
//! text column nobody asked for does no harm. Every error names the file, the sheet (for
//! workbooks), the 1-based row and column, the column name and what was expected.
//!
//! ```
//! use std::path::Path;
//! let text = "time_s,t1_c,t2_c,ch1_um\n0,20.0,20.5,0.0\n15,20.1,oops,0.4\n";
//! let table = truepos_io::run::parse_csv(Path::new("run.csv"), text).unwrap();
//! let cols = table.select(&["t*_c"]).unwrap();
//! assert_eq!(cols, vec![1, 2]);
//! assert_eq!(table.numbers(1).unwrap(), vec![20.0, 20.1]);
//! assert_eq!(
//!     table.numbers(2).unwrap_err().to_string(),
//!     "run.csv:3:3: `t2_c`: expected a number, got `oops`"
//! );
//! ```

use std::path::{Path, PathBuf};

use crate::table::{self, CsvOptions, Delimiter, Number};
use crate::timestamp;
use crate::units::{self, Role};
use truepos_files::InputError;

/// One run as a table of named columns, read by [`crate::table`].
#[derive(Debug, Clone, PartialEq)]
pub struct RunTable {
    /// The file it came from.
    pub file: PathBuf,
    /// The sheet, for workbooks.
    pub sheet: Option<String>,
    /// The run's name when a run column split the file into runs ([`Shape::run_column`]).
    pub run: Option<String>,
    /// Column names (the header row).
    pub columns: Vec<String>,
    /// The cells as read, with their places.
    pub table: table::Table,
    /// How the time column's date-times are written, when not in a form read by itself
    /// ([`Shape::time_format`]).
    pub time_format: Option<String>,
}

/// How run files are laid out, beyond what the reader sees by itself.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Shape {
    /// The field separator of CSV files (detected by default).
    pub delimiter: Delimiter,
    /// A column whose value names the run each row belongs to: a file holding several runs is
    /// split into one run per value, in order of first appearance.
    pub run_column: Option<String>,
    /// A `strftime`-style format of the time column's date-times (`%m/%d/%Y %I:%M %p`), for
    /// forms [`crate::timestamp::parse`] does not read by itself.
    pub time_format: Option<String>,
}

/// Where a run's time comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Time {
    /// A column (a name or glob) of seconds or of ISO 8601 date-times.
    Column(String),
    /// No time column: row `i` is at `i` × this many seconds.
    Period(f64),
}

impl Default for Time {
    fn default() -> Self {
        Time::Column("time_s".into())
    }
}

impl RunTable {
    fn new(table: table::Table) -> Self {
        Self {
            file: table.file.clone(),
            sheet: table.sheet.clone(),
            run: None,
            columns: table.columns.clone(),
            table,
            time_format: None,
        }
    }

    /// The run's name: the value of its run column, else "file" or "file, sheet `name`".
    pub fn name(&self) -> String {
        self.run.clone().unwrap_or_else(|| self.table.name())
    }

    /// Splits the table into runs by the value of column `column` (text or number), in order of
    /// first appearance. The rows of one run must be together: a run that appears again after
    /// another one is an error at the row where it does, as is an empty cell.
    pub fn split_runs(self, column: &str) -> Result<Vec<RunTable>, InputError> {
        let col = self.select(&[column])?[0];
        let t = &self.table;
        // (key, first line, first row, end row) of each run, in order.
        let mut runs: Vec<(String, usize, usize, usize)> = Vec::new();
        for (r, row) in t.rows().enumerate() {
            let key = match row.cell(col).map(|c| c.value) {
                Some(table::Value::Number(v)) => v.to_string(),
                Some(table::Value::Text(s)) => s.to_string(),
                Some(table::Value::Empty) | None => {
                    return Err(t.at(
                        r,
                        col,
                        "expected the name of the row's run, the cell is empty",
                    ))
                }
            };
            match runs.iter().position(|(k, ..)| *k == key) {
                Some(i) if i + 1 == runs.len() => runs[i].3 = r + 1,
                Some(i) => {
                    return Err(t.at(
                        r,
                        col,
                        format!(
                            "run `{key}` (from line {}) appears again after run `{}`: the rows of one run must be together",
                            runs[i].1,
                            runs[runs.len() - 1].0
                        ),
                    ))
                }
                None => runs.push((key, row.line(), r, r + 1)),
            }
        }
        Ok(runs
            .into_iter()
            .map(|(key, _, start, end)| RunTable {
                run: Some(key),
                table: t.sub_table(start..end),
                ..self.clone_header()
            })
            .collect())
    }

    fn clone_header(&self) -> RunTable {
        RunTable {
            file: self.file.clone(),
            sheet: self.sheet.clone(),
            run: self.run.clone(),
            columns: self.columns.clone(),
            table: self.table.clone_header(),
            time_format: self.time_format.clone(),
        }
    }

    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.table.len()
    }

    /// The values of column `col` as numbers; an empty or text cell is an error naming its row.
    pub fn numbers(&self, col: usize) -> Result<Vec<f64>, InputError> {
        let t = &self.table;
        t.rows()
            .enumerate()
            .map(|(r, row)| match row.number(col) {
                Number::Value(v) if v.is_finite() => Ok(v),
                Number::Value(v) => Err(t.at(r, col, format!("expected a finite number, got {v}"))),
                Number::Text(x) => Err(t.at(r, col, format!("expected a number, got `{x}`"))),
                Number::Empty => Err(t.at(r, col, "expected a number, the cell is empty")),
            })
            .collect()
    }

    /// The values of column `col` converted to `role`'s unit from the unit its name states
    /// ([`crate::units`]); a unit that is unknown or does not fit the role is an error at the
    /// header naming the column.
    pub fn numbers_as(&self, col: usize, role: Role) -> Result<Vec<f64>, InputError> {
        let unit = self.unit(col, role)?;
        let v = self.numbers(col)?;
        Ok(v.into_iter()
            .map(|x| unit.convert(x, role).unwrap_or(f64::NAN))
            .collect())
    }

    fn unit(&self, col: usize, role: Role) -> Result<units::Unit, InputError> {
        units::for_role(&self.columns[col], role).map_err(|e| self.table.header_at(col, e))
    }

    /// A column of measured errors, converted to µm by its unit: an empty cell is a row without
    /// a measurement (NaN), text is an error at its cell, and so is a column with no value at
    /// all in this run.
    pub fn measured(&self, col: usize) -> Result<Vec<f64>, InputError> {
        let unit = self.unit(col, Role::Error)?;
        let t = &self.table;
        let v = t
            .rows()
            .enumerate()
            .map(|(r, row)| match row.number(col) {
                Number::Value(v) if v.is_finite() => Ok(unit.convert(v, Role::Error).unwrap_or(v)),
                Number::Value(v) => Err(t.at(r, col, format!("expected a finite number, got {v}"))),
                Number::Text(x) => Err(t.at(r, col, format!("expected a number, got `{x}`"))),
                Number::Empty => Ok(f64::NAN),
            })
            .collect::<Result<Vec<f64>, _>>()?;
        if v.iter().all(|x| x.is_nan()) {
            let mut e = t.header_at(
                col,
                format!(
                    "run `{}` has no measured value in this column (every cell is empty)",
                    self.name()
                ),
            );
            if self.run.is_none() {
                e.message = "no measured value in this column (every cell is empty)".into();
            }
            return Err(e);
        }
        Ok(v)
    }

    /// The run's time in s from `time`: a column of seconds or of ISO 8601 date-times (then
    /// seconds since the run's first row), or row `i` × a sample period.
    pub fn times(&self, time: &Time) -> Result<Vec<f64>, InputError> {
        match time {
            Time::Period(p) => Ok((0..self.rows()).map(|i| i as f64 * p).collect()),
            Time::Column(name) => match self.select(&[name.as_str()]) {
                Ok(cols) => self.time(cols[0]),
                Err(e) if *time == Time::default() => self.time(self.date_column().ok_or(e)?),
                Err(e) => Err(e),
            },
        }
    }

    /// Without the default `time_s` column, a run's time is found by its cells: the first
    /// column whose first cell is a date-time (a workbook's date cell, ISO 8601 or day-first
    /// text) — shops name it in their own words (`Datum/Uhrzeit`, `Zeitstempel`).
    fn date_column(&self) -> Option<usize> {
        if self.table.is_empty() {
            return None;
        }
        let first = self.table.row(0);
        (0..self.columns.len()).find(|&c| match first.cell(c).map(|cell| cell.value) {
            Some(table::Value::Text(x)) => timestamp::parse(x).is_ok(),
            _ => false,
        })
    }

    /// A time column: seconds, or ISO 8601 date-times as seconds since the first row (the first
    /// cell decides which), that increase strictly (a duplicate time is an error).
    pub fn time(&self, col: usize) -> Result<Vec<f64>, InputError> {
        let t = self.time_values(col)?;
        for r in 1..t.len() {
            if t[r] <= t[r - 1] {
                return Err(self.table.at(
                    r,
                    col,
                    format!(
                        "time must increase strictly: {} follows {} ({})",
                        t[r],
                        t[r - 1],
                        if t[r] == t[r - 1] {
                            "duplicate time"
                        } else {
                            "backwards"
                        }
                    ),
                ));
            }
        }
        Ok(t)
    }

    fn time_values(&self, col: usize) -> Result<Vec<f64>, InputError> {
        if let Some(format) = &self.time_format {
            return self.formatted_times(col, format);
        }
        let t = &self.table;
        let iso = |r: usize| -> Result<Option<i128>, InputError> {
            match t.row(r).cell(col).map(|c| c.value) {
                Some(table::Value::Text(x)) => {
                    timestamp::parse(x)
                        .map(Some)
                        .or_else(|_| match t.row(r).number(col) {
                            Number::Value(_) => Ok(None),
                            _ => Err(t.at(r, col, timestamp::parse(x).unwrap_err())),
                        })
                }
                _ => Ok(None),
            }
        };
        let Some(first) = (!t.is_empty()).then(|| iso(0)).transpose()?.flatten() else {
            return self.numbers(col).map_err(|mut e| {
                if let Some(rest) = e.message.strip_prefix("expected a number, got ") {
                    e.message = format!("expected seconds (a number), an ISO 8601 date-time like 2024-03-01T08:00:00 or a day-first one like 01.03.2024 08:00:00, got {rest}");
                }
                e
            });
        };
        (0..t.len())
            .map(|r| match iso(r)? {
                Some(ns) => Ok((ns - first) as f64 / 1e9),
                None => Err(t.at(
                    r,
                    col,
                    "expected an ISO 8601 date-time as in the first row, got a number or an empty cell",
                )),
            })
            .collect()
    }

    /// A time column of date-times written as `format` says, as seconds since the first row.
    fn formatted_times(&self, col: usize, format: &str) -> Result<Vec<f64>, InputError> {
        let t = &self.table;
        let mut first = None;
        (0..t.len())
            .map(|r| {
                let ns = match t.row(r).cell(col).map(|c| c.value) {
                    Some(table::Value::Text(x)) => timestamp::parse_with(format, x),
                    Some(table::Value::Number(v)) => timestamp::parse_with(format, &v.to_string()),
                    _ => Err(format!("expected a date-time in the form `{format}` (--time-format), got an empty cell")),
                }
                .map_err(|e| t.at(r, col, e))?;
                let first = *first.get_or_insert(ns);
                Ok((ns - first) as f64 / 1e9)
            })
            .collect()
    }

    /// Column indices for names or globs (`*` any run of characters, `?` one character), in
    /// pattern order and, within a glob, in column order; each column at most once. A pattern
    /// matching nothing is an error listing the columns there are.
    pub fn select(&self, patterns: &[&str]) -> Result<Vec<usize>, InputError> {
        let mut out: Vec<usize> = Vec::new();
        for p in patterns {
            let found: Vec<usize> = (0..self.columns.len())
                .filter(|&c| glob_match(p, &self.columns[c]))
                .collect();
            if found.is_empty() {
                let mut e = InputError::file(
                    &self.file,
                    format!(
                        "no column matches `{p}`; the columns are: {}",
                        self.columns.join(", ")
                    ),
                );
                e.key = self.sheet.as_ref().map(|s| format!("sheet `{s}`"));
                return Err(e);
            }
            for c in found {
                if !out.contains(&c) {
                    out.push(c);
                }
            }
        }
        Ok(out)
    }
}

/// Whether `name` matches `pattern` (`*` = any run of characters, `?` = one character).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let n: Vec<char> = name.chars().collect();
    // Iterative matching with backtracking to the last `*`.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

/// Parses a CSV run (header row of column names, comma-separated).
pub fn parse_csv(file: &Path, text: &str) -> Result<RunTable, InputError> {
    csv_run(table::parse_csv(
        file,
        text.as_bytes(),
        CsvOptions::default(),
    )?)
}

/// A run's rules on a CSV table: a header of distinct names, every row as wide, a data row.
fn csv_run(t: table::Table) -> Result<RunTable, InputError> {
    if t.columns.iter().all(String::is_empty) {
        return Err(InputError::file(
            &t.file,
            "the file is empty: expected a header row of column names",
        ));
    }
    t.check_unique_columns()?;
    if let Some(e) = (0..t.len()).find_map(|r| t.width_error(r)) {
        return Err(e);
    }
    if t.is_empty() {
        return Err(InputError::file(&t.file, "no data rows below the header"));
    }
    Ok(RunTable::new(t))
}

/// Reads a workbook: every non-empty sheet (or only `sheet`) is one run; the first non-empty
/// row of a sheet holds the column names.
pub fn read_workbook(file: &Path, sheet: Option<&str>) -> Result<Vec<RunTable>, InputError> {
    table::read_workbook(file, sheet)?
        .into_iter()
        .map(|t| {
            t.check_unique_columns()?;
            Ok(RunTable::new(t))
        })
        .collect()
}

/// Reads a run file by its extension: `.csv` (one run) or a workbook (one run per sheet).
pub fn read(file: &Path, sheet: Option<&str>) -> Result<Vec<RunTable>, InputError> {
    read_shaped(file, sheet, &Shape::default())
}

/// [`read`] with the file's [`Shape`]: its CSV separator, and a run column that splits every
/// table into runs.
pub fn read_shaped(
    file: &Path,
    sheet: Option<&str>,
    shape: &Shape,
) -> Result<Vec<RunTable>, InputError> {
    let tables = if table::is_workbook(file) {
        read_workbook(file, sheet)?
    } else {
        let options = CsvOptions {
            delimiter: shape.delimiter,
            ..Default::default()
        };
        vec![csv_run(table::load_csv(file, options)?)?]
    };
    let tables: Vec<RunTable> = tables
        .into_iter()
        .map(|t| RunTable {
            time_format: shape.time_format.clone(),
            ..t
        })
        .collect();
    match &shape.run_column {
        None => Ok(tables),
        Some(column) => {
            let mut out = Vec::new();
            for t in tables {
                out.extend(t.split_runs(column)?);
            }
            Ok(out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs() {
        assert!(glob_match("t*_c", "t12_c"));
        assert!(glob_match("t*_c", "t_c"));
        assert!(!glob_match("t*_c", "t12_um"));
        assert!(glob_match("ch?_um", "ch3_um"));
        assert!(!glob_match("ch?_um", "ch10_um"));
        assert!(glob_match("*", "anything"));
        assert!(glob_match("spindle_rpm", "spindle_rpm"));
        assert!(glob_match("a*b*c", "aXbYbZc"));
    }

    #[test]
    fn csv_errors_name_row_and_column() {
        let f = Path::new("r.csv");
        let t = parse_csv(f, "time_s,a\n0,1\n1,\n").unwrap();
        assert_eq!(
            t.numbers(1).unwrap_err().to_string(),
            "r.csv:3:2: `a`: expected a number, the cell is empty"
        );
        let t = parse_csv(f, "time_s,a\n0,1\n5,2\n5,3\n").unwrap();
        assert_eq!(
            t.time(0).unwrap_err().to_string(),
            "r.csv:4:1: `time_s`: time must increase strictly: 5 follows 5 (duplicate time)"
        );
        let e = t.select(&["b*"]).unwrap_err().to_string();
        assert!(
            e.contains("no column matches `b*`; the columns are: time_s, a"),
            "{e}"
        );
        assert!(parse_csv(f, "").is_err());
        assert!(parse_csv(f, "time_s,a\n")
            .unwrap_err()
            .to_string()
            .contains("no data rows"));
        assert!(parse_csv(f, "a,a\n1,2\n")
            .unwrap_err()
            .to_string()
            .contains("duplicate column"));
        let e = parse_csv(f, "a,b\n1,2\n3\n").unwrap_err().to_string();
        assert!(e.starts_with("r.csv:3:"), "{e}");
    }

    #[test]
    fn select_keeps_pattern_order_without_duplicates() {
        let t = parse_csv(Path::new("r.csv"), "time_s,t2_c,rpm,t1_c\n0,1,2,3\n").unwrap();
        assert_eq!(t.select(&["rpm", "t*_c", "t1_c"]).unwrap(), vec![2, 1, 3]);
    }

    #[cfg(feature = "xlsx")]
    #[test]
    fn the_fl_thermal_workbook_reads_like_its_csv() {
        // The real published workbook beside its ASCII CSV (../shared/data/fl_thermal).
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/fl_thermal");
        let book = read(&dir.join("data.xlsx"), None).unwrap();
        assert_eq!(book.len(), 1);
        let sheet = &book[0];
        assert_eq!(sheet.sheet.as_deref(), Some("工作表1"));
        assert_eq!(sheet.rows(), 11_115);
        assert_eq!(sheet.columns.len(), 23);
        let csv = read(&dir.join("fl_thermal.csv"), None).unwrap();
        // Same numbers in the same column positions (the CSV renamed the columns to ASCII).
        for c in [0, 5, 22] {
            let (a, b) = (sheet.numbers(c).unwrap(), csv[0].numbers(c).unwrap());
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() <= 1e-6 * y.abs().max(1.0), "{x} {y}");
            }
        }
        let e = read(&dir.join("data.xlsx"), Some("nope"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no sheet `nope`; the sheets are: 工作表1"),
            "{e}"
        );
    }
}
