//! Recorded runs as tables: CSV files and Excel workbooks (`.xlsx`, `.xlsm`, `.xls`, `.ods`
//! through calamine; one sheet per run), with columns chosen by name or glob (`t*_c`).
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

use calamine::{open_workbook_auto, Data, Reader};

use crate::error::InputError;

/// One cell as read.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// A number.
    Number(f64),
    /// Text (a CSV field, or a text cell of a workbook).
    Text(String),
    /// Nothing.
    Empty,
}

/// One run as a table of named columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file it came from.
    pub file: PathBuf,
    /// The sheet, for workbooks.
    pub sheet: Option<String>,
    /// Column names (the header row).
    pub columns: Vec<String>,
    /// Cells per column, data rows only.
    pub cells: Vec<Vec<Cell>>,
    /// 1-based line (CSV) or row (sheet) of the header; data row i is at `header_row + 1 + i`.
    pub header_row: usize,
    /// 1-based column of the first column (sheets may start to the right).
    pub first_column: usize,
}

impl Table {
    /// "file" or "file, sheet `name`", for messages and run names.
    pub fn name(&self) -> String {
        match &self.sheet {
            Some(s) => format!("{}, sheet `{s}`", self.file.display()),
            None => self.file.display().to_string(),
        }
    }

    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.cells.first().map_or(0, Vec::len)
    }

    fn error(&self, row: Option<usize>, col: usize, message: String) -> InputError {
        let key = match &self.sheet {
            Some(s) => format!("sheet `{s}`, column `{}`", self.columns[col]),
            None => self.columns[col].clone(),
        };
        match row {
            Some(r) => InputError::at(
                &self.file,
                self.header_row + 1 + r,
                self.first_column + col,
                key,
                message,
            ),
            None => InputError::at(
                &self.file,
                self.header_row,
                self.first_column + col,
                key,
                message,
            ),
        }
    }

    /// The values of column `col` as numbers; an empty or text cell is an error naming its row.
    pub fn numbers(&self, col: usize) -> Result<Vec<f64>, InputError> {
        self.cells[col]
            .iter()
            .enumerate()
            .map(|(r, c)| match c {
                Cell::Number(v) if v.is_finite() => Ok(*v),
                Cell::Number(v) => {
                    Err(self.error(Some(r), col, format!("expected a finite number, got {v}")))
                }
                Cell::Text(t) => {
                    Err(self.error(Some(r), col, format!("expected a number, got `{t}`")))
                }
                Cell::Empty => {
                    Err(self.error(Some(r), col, "expected a number, the cell is empty".into()))
                }
            })
            .collect()
    }

    /// A time column: numbers that increase strictly (a duplicate time is an error).
    pub fn time(&self, col: usize) -> Result<Vec<f64>, InputError> {
        let t = self.numbers(col)?;
        for r in 1..t.len() {
            if t[r] <= t[r - 1] {
                return Err(self.error(
                    Some(r),
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
pub fn parse_csv(file: &Path, text: &str) -> Result<Table, InputError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| InputError::file(file, format!("cannot read the header row: {e}")))?
        .clone();
    let columns: Vec<String> = headers.iter().map(str::to_string).collect();
    if columns.is_empty() || columns.iter().all(String::is_empty) {
        return Err(InputError::file(
            file,
            "the file is empty: expected a header row of column names",
        ));
    }
    check_unique(file, None, &columns, 1)?;
    let mut cells = vec![Vec::new(); columns.len()];
    for (r, record) in reader.records().enumerate() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(r + 2, |p| p.line() as usize);
            InputError::at(
                file,
                line,
                1,
                "",
                format!("expected {} fields: {e}", columns.len()),
            )
        })?;
        for (c, field) in record.iter().enumerate() {
            cells[c].push(if field.is_empty() {
                Cell::Empty
            } else {
                match field.parse::<f64>() {
                    Ok(v) => Cell::Number(v),
                    Err(_) => Cell::Text(field.to_string()),
                }
            });
        }
    }
    if cells[0].is_empty() {
        return Err(InputError::file(file, "no data rows below the header"));
    }
    Ok(Table {
        file: file.to_path_buf(),
        sheet: None,
        columns,
        cells,
        header_row: 1,
        first_column: 1,
    })
}

fn check_unique(
    file: &Path,
    sheet: Option<&str>,
    columns: &[String],
    row: usize,
) -> Result<(), InputError> {
    for (c, name) in columns.iter().enumerate() {
        if columns[..c].contains(name) {
            let key = match sheet {
                Some(s) => format!("sheet `{s}`, column `{name}`"),
                None => name.clone(),
            };
            return Err(InputError::at(
                file,
                row,
                c + 1,
                key,
                "duplicate column name",
            ));
        }
    }
    Ok(())
}

/// Reads a workbook: every non-empty sheet (or only `sheet`) is one run; the first non-empty
/// row of a sheet holds the column names.
pub fn read_workbook(file: &Path, sheet: Option<&str>) -> Result<Vec<Table>, InputError> {
    let mut wb = open_workbook_auto(file)
        .map_err(|e| InputError::file(file, format!("cannot open the workbook: {e}")))?;
    let names = wb.sheet_names();
    let wanted: Vec<String> = match sheet {
        Some(s) if names.iter().any(|n| n == s) => vec![s.to_string()],
        Some(s) => {
            return Err(InputError::file(
                file,
                format!("no sheet `{s}`; the sheets are: {}", names.join(", ")),
            ))
        }
        None => names.clone(),
    };
    let mut out = Vec::new();
    for name in wanted {
        let range = wb
            .worksheet_range(&name)
            .map_err(|e| InputError::file(file, format!("sheet `{name}`: cannot read it: {e}")))?;
        let Some((r0, c0)) = range.start() else {
            if sheet.is_some() {
                return Err(InputError::file(file, format!("sheet `{name}` is empty")));
            }
            continue;
        };
        let mut rows = range.rows();
        let header = rows.next().unwrap_or(&[]);
        let (header_row, first_column) = (r0 as usize + 1, c0 as usize + 1);
        let mut columns = Vec::with_capacity(header.len());
        for (c, cell) in header.iter().enumerate() {
            match cell {
                Data::String(s) if !s.trim().is_empty() => columns.push(s.trim().to_string()),
                other => {
                    return Err(InputError::at(
                        file,
                        header_row,
                        first_column + c,
                        format!("sheet `{name}`"),
                        format!("expected a column name in the header row, got {other:?}"),
                    ))
                }
            }
        }
        check_unique(file, Some(&name), &columns, header_row)?;
        let mut cells = vec![Vec::new(); columns.len()];
        for row in rows {
            for (c, col) in cells.iter_mut().enumerate() {
                col.push(match row.get(c) {
                    Some(Data::Float(v)) => Cell::Number(*v),
                    Some(Data::Int(v)) => Cell::Number(*v as f64),
                    Some(Data::Empty) | None => Cell::Empty,
                    Some(Data::String(s)) => match s.trim().parse::<f64>() {
                        Ok(v) => Cell::Number(v),
                        Err(_) => Cell::Text(s.clone()),
                    },
                    Some(other) => Cell::Text(other.to_string()),
                });
            }
        }
        if cells.first().is_none_or(Vec::is_empty) {
            if sheet.is_some() {
                return Err(InputError::file(
                    file,
                    format!("sheet `{name}` has a header row but no data rows"),
                ));
            }
            continue;
        }
        out.push(Table {
            file: file.to_path_buf(),
            sheet: Some(name),
            columns,
            cells,
            header_row,
            first_column,
        });
    }
    if out.is_empty() {
        return Err(InputError::file(
            file,
            "every sheet of the workbook is empty",
        ));
    }
    Ok(out)
}

/// Reads a run file by its extension: `.csv` (one run) or a workbook (one run per sheet).
pub fn read(file: &Path, sheet: Option<&str>) -> Result<Vec<Table>, InputError> {
    let ext = file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("xlsx" | "xlsm" | "xlsb" | "xls" | "ods") => read_workbook(file, sheet),
        _ => {
            let text = std::fs::read_to_string(file)
                .map_err(|e| InputError::file(file, format!("cannot read: {e}")))?;
            Ok(vec![parse_csv(file, &text)?])
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
