//! The one reader of tables: every CSV file and Excel workbook the project reads (runs for
//! fitting, cycles for evaluation and replay, measured errors for reports, point lists of
//! `truepos kin`) goes through here once, into named columns of cells that keep their place in
//! the file. Workbooks are read with the `xlsx` feature (on by default; the LinuxCNC component
//! builds without it).
//!
//! One place knows the rules: fields split by the csv crate's parser (`,`, or `;` or a tab as
//! detected from the header line or given, [`Delimiter`]; `"` quoting, `\n`,
//! `\r\n` or `\r` line ends, empty lines skipped, a UTF-8 byte order mark ignored), cells
//! trimmed, an empty cell is [`Value::Empty`], numbers parsed by [`Value::number`] (with `;` or a
//! tab between fields, `20,5` too), and errors
//! name file:line:column, the column and the expectation ([`Table::at`]). What a caller accepts
//! (an empty cell as NaN or as an error, NaN at all) stays the caller's rule.
//!
//! ```
//! use std::path::Path;
//! use truepos_io::table::{self, Number};
//! let t = table::parse_csv(Path::new("r.csv"), b"time_s, a\n0,1\n1,\"x\"\n", Default::default())
//!     .unwrap();
//! assert_eq!(t.columns, ["time_s", "a"]);
//! assert_eq!(t.rows[1].cells[1].value.number(), Number::Text("x"));
//! assert_eq!(
//!     t.at(1, 1, "expected a number, got `x`").to_string(),
//!     "r.csv:3:2: `a`: expected a number, got `x`"
//! );
//! ```

use std::io::Read;
use std::path::{Path, PathBuf};

#[cfg(feature = "xlsx")]
use calamine::{open_workbook_auto, Data, Reader};

use crate::error::InputError;

/// A cell's content.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Nothing (an empty or blank CSV field, an empty workbook cell).
    Empty,
    /// A finite number (a CSV field that reads as one, or a numeric workbook cell).
    Number(f64),
    /// Anything else, trimmed for CSV, as stored for workbooks (`NaN`, `inf` and `1e400` stay
    /// text so that a message can quote them as written).
    Text(Box<str>),
}

/// A cell read as a number: [`Value::number`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Number<'a> {
    /// A number, not necessarily finite (`NaN`, `inf`).
    Value(f64),
    /// The cell is empty.
    Empty,
    /// Text that is no number.
    Text(&'a str),
}

impl Value {
    /// The cell as a number, the one number syntax of every table: Rust's `f64` syntax on the
    /// trimmed text (`1`, `-2.5e3`, `NaN`, `inf`).
    pub fn number(&self) -> Number<'_> {
        match self {
            Value::Empty => Number::Empty,
            Value::Number(v) => Number::Value(*v),
            Value::Text(t) => t
                .trim()
                .parse::<f64>()
                .map_or(Number::Text(t), Number::Value),
        }
    }
}

/// One cell and its place: 1-based line and column in characters (CSV) or row and column
/// (workbook sheets).
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// What it holds.
    pub value: Value,
    /// Line (CSV) or row (sheet) where it starts.
    pub line: u32,
    /// Character column (CSV) or column (sheet) where it starts.
    pub column: u32,
}

/// One data row.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Line (CSV) or row (sheet) where it starts.
    pub line: usize,
    /// Its cells, in file order; a CSV row may hold more or fewer than the header
    /// ([`Table::width_error`]).
    pub cells: Vec<Cell>,
}

/// A table as read: a header row of column names and the data rows below it.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file it came from.
    pub file: PathBuf,
    /// The sheet, for workbooks.
    pub sheet: Option<String>,
    /// Column names (the header row, trimmed); empty when the file is.
    pub columns: Vec<String>,
    /// 1-based line (CSV) or row (sheet) of the header.
    pub header_line: usize,
    /// 1-based column of the first column (sheets may start to the right).
    pub first_column: usize,
    /// The data rows.
    pub rows: Vec<Row>,
}

impl Table {
    /// "file" or "file, sheet `name`", for messages and run names.
    pub fn name(&self) -> String {
        match &self.sheet {
            Some(s) => format!("{}, sheet `{s}`", self.file.display()),
            None => self.file.display().to_string(),
        }
    }

    /// The first column called `name`.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// The key of column `col` in messages: its name, with the sheet for workbooks.
    pub fn key(&self, col: usize) -> String {
        let name = self.columns.get(col).map_or("", String::as_str);
        match &self.sheet {
            Some(s) => format!("sheet `{s}`, column `{name}`"),
            None => name.to_string(),
        }
    }

    /// An error about the cell of data row `row`, column `col`: its line, its column as a
    /// field number (the n-th column of the header, for a person counting columns), the
    /// column's name and `message`.
    pub fn at(&self, row: usize, col: usize, message: impl Into<String>) -> InputError {
        let line = self.rows.get(row).map_or(self.header_line, |r| {
            r.cells.get(col).map_or(r.line, |c| c.line as usize)
        });
        InputError::at(
            &self.file,
            line,
            self.first_column + col,
            self.key(col),
            message,
        )
    }

    /// [`Table::at`] with the cell's character column instead of its field number (the place
    /// an editor's cursor shows).
    pub fn at_character(&self, row: usize, col: usize, message: impl Into<String>) -> InputError {
        let cell = self.rows.get(row).and_then(|r| r.cells.get(col));
        let (line, column) = match cell {
            Some(c) => (c.line as usize, c.column as usize),
            None => (self.rows.get(row).map_or(self.header_line, |r| r.line), 1),
        };
        let key = self.columns.get(col).cloned().unwrap_or_default();
        InputError::at(&self.file, line, column, key, message)
    }

    /// An error about column `col` of the header row.
    pub fn header_at(&self, col: usize, message: impl Into<String>) -> InputError {
        InputError::at(
            &self.file,
            self.header_line,
            self.first_column + col,
            self.key(col),
            message,
        )
    }

    /// The error of data row `row` when it does not have as many fields as the header.
    pub fn width_error(&self, row: usize) -> Option<InputError> {
        let r = self.rows.get(row)?;
        (r.cells.len() != self.columns.len()).then(|| {
            InputError::at(
                &self.file,
                r.line,
                1,
                "",
                format!(
                    "expected {} fields as in the header, found {}",
                    self.columns.len(),
                    r.cells.len()
                ),
            )
        })
    }

    /// The table without its rows.
    pub fn clone_header(&self) -> Table {
        Table {
            file: self.file.clone(),
            sheet: self.sheet.clone(),
            columns: self.columns.clone(),
            header_line: self.header_line,
            first_column: self.first_column,
            rows: Vec::new(),
        }
    }

    /// An error at the first column name that repeats an earlier one.
    pub fn check_unique_columns(&self) -> Result<(), InputError> {
        for (c, name) in self.columns.iter().enumerate() {
            if self.columns[..c].contains(name) {
                return Err(self.header_at(c, "duplicate column name"));
            }
        }
        Ok(())
    }
}

/// How a CSV file is read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CsvOptions {
    /// `#` starts a comment to the end of its line, and lines holding only a comment or blanks
    /// are skipped (the point lists of `truepos kin`).
    pub comments: bool,
    /// The field separator; [`Delimiter::Auto`] detects it from the header line.
    pub delimiter: Delimiter,
}

/// The field separator of a CSV file. With `;` or a tab, a number may also be written with a
/// decimal comma (`20,5`), as spreadsheets in many locales save it; with `,` it cannot be.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Delimiter {
    /// Detected from the header line ([`detect_delimiter`]).
    #[default]
    Auto,
    /// `,`.
    Comma,
    /// `;` (decimal commas allowed).
    Semicolon,
    /// A tab (decimal commas allowed).
    Tab,
}

impl Delimiter {
    fn byte(self) -> u8 {
        match self {
            Self::Auto | Self::Comma => b',',
            Self::Semicolon => b';',
            Self::Tab => b'\t',
        }
    }

    /// Whether a number may be written with a decimal comma.
    pub fn decimal_comma(self) -> bool {
        matches!(self, Self::Semicolon | Self::Tab)
    }
}

impl std::str::FromStr for Delimiter {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "," | "comma" => Ok(Self::Comma),
            ";" | "semicolon" => Ok(Self::Semicolon),
            "\t" | "\\t" | "tab" => Ok(Self::Tab),
            _ => Err(format!(
                "expected auto, `,` (comma), `;` (semicolon) or tab, got `{s}`"
            )),
        }
    }
}

impl std::fmt::Display for Delimiter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Auto => "auto",
            Self::Comma => ",",
            Self::Semicolon => ";",
            Self::Tab => "tab",
        })
    }
}

/// The separator of a CSV text, from its header line (the first line that is not blank): the
/// one of `,`, `;` and tab that occurs most often outside double quotes, `,` on a tie or when
/// none occurs. Quoted cells are skipped, so `time_s,"a;b","c;d"` stays comma-separated, and a
/// header whose names hold a comma (`t1 (°C, front);dz_um`) is still read by its majority.
pub fn detect_delimiter(text: &str) -> Delimiter {
    let header = text
        .split('\n')
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    let (mut comma, mut semicolon, mut tab) = (0usize, 0usize, 0usize);
    let mut quoted = false;
    for ch in header.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => comma += 1,
            ';' if !quoted => semicolon += 1,
            '\t' if !quoted => tab += 1,
            _ => {}
        }
    }
    if semicolon > comma && semicolon >= tab {
        Delimiter::Semicolon
    } else if tab > comma && tab > semicolon {
        Delimiter::Tab
    } else {
        Delimiter::Comma
    }
}

/// Reads a CSV file.
pub fn load_csv(file: &Path, options: CsvOptions) -> Result<Table, InputError> {
    let bytes =
        std::fs::read(file).map_err(|e| InputError::file(file, format!("cannot read: {e}")))?;
    parse_csv(file, &bytes, options)
}

/// Reads CSV from any reader; `file` only names it in errors.
pub fn read_csv(
    file: &Path,
    mut reader: impl Read,
    options: CsvOptions,
) -> Result<Table, InputError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|e| InputError::file(file, format!("cannot read: {e}")))?;
    parse_csv(file, &bytes, options)
}

/// Parses CSV text: the first record holds the column names, every further record is a row.
/// The only errors are about the text itself (not UTF-8); what the rows must hold is the
/// caller's to check ([`Table::width_error`], [`Value::number`], [`Table::at`]).
pub fn parse_csv(file: &Path, bytes: &[u8], options: CsvOptions) -> Result<Table, InputError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        InputError::at(file, line, 1, "", "expected UTF-8 text")
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let stripped;
    let text = if options.comments {
        stripped = strip_comments(text);
        stripped.as_str()
    } else {
        text
    };
    let delimiter = match options.delimiter {
        Delimiter::Auto => detect_delimiter(text),
        d => d,
    };
    let mut records = tokenize(text, delimiter.byte()).into_iter();
    let (columns, header_line) = match records.next() {
        Some(header) => (
            header.iter().map(|c| c.text.trim().to_string()).collect(),
            header.first().map_or(1, |c| c.line as usize),
        ),
        None => (Vec::new(), 1),
    };
    let rows = records
        .map(|fields| Row {
            line: fields.first().map_or(0, |c| c.line as usize),
            cells: fields
                .into_iter()
                .map(|f| Cell {
                    value: value_of(f.text.trim(), delimiter.decimal_comma()),
                    line: f.line,
                    column: f.column,
                })
                .collect(),
        })
        .collect();
    Ok(Table {
        file: file.to_path_buf(),
        sheet: None,
        columns,
        header_line,
        first_column: 1,
        rows,
    })
}

fn value_of(text: &str, decimal_comma: bool) -> Value {
    if text.is_empty() {
        return Value::Empty;
    }
    let parsed = match text.parse::<f64>() {
        Err(_) if decimal_comma && text.matches(',').count() == 1 && !text.contains('.') => {
            text.replacen(',', ".", 1).parse::<f64>()
        }
        other => other,
    };
    match parsed {
        Ok(v) if v.is_finite() => Value::Number(v),
        _ => Value::Text(text.into()),
    }
}

/// Cuts every line at its first `#`; a line left blank becomes empty (and is then skipped).
/// Line ends are kept, so lines and the columns before a comment stay where they were.
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.split_inclusive('\n') {
        let body = line.trim_end_matches(['\n', '\r']);
        let end = &line[body.len()..];
        let body = body.split('#').next().unwrap_or("");
        if !body.trim().is_empty() {
            out.push_str(body);
        }
        out.push_str(end);
    }
    out
}

struct Field {
    text: String,
    line: u32,
    column: u32,
}

/// Splits CSV text into records of fields with their 1-based line and character column, with
/// the csv crate's parser (csv-core).
fn tokenize(text: &str, delimiter: u8) -> Vec<Vec<Field>> {
    let input = text.as_bytes();
    let mut reader = csv_core::ReaderBuilder::new().delimiter(delimiter).build();
    let mut records = Vec::new();
    let mut record: Vec<Field> = Vec::new();
    let mut out = vec![0u8; 1024];
    let mut field = Vec::new();
    let mut pos = 0;
    let mut start: Option<usize> = None;
    // Where the line/column count stands, advanced monotonically.
    let (mut at, mut line, mut column) = (0usize, 1u32, 1u32);
    loop {
        if start.is_none() {
            let mut s = pos;
            if record.is_empty() {
                // The parser skips empty lines before a record; the record starts after them.
                while s < input.len() && matches!(input[s], b'\r' | b'\n') {
                    s += 1;
                }
            }
            start = Some(s);
        }
        let rest = &input[pos..];
        let (result, nin, nout) = reader.read_field(rest, &mut out);
        pos += nin;
        field.extend_from_slice(&out[..nout]);
        match result {
            csv_core::ReadFieldResult::InputEmpty => {
                if rest.is_empty() {
                    break; // cannot happen: an empty input ends the field or the text
                }
            }
            csv_core::ReadFieldResult::OutputFull => {
                let n = out.len();
                out.resize(2 * n, 0);
            }
            csv_core::ReadFieldResult::Field { record_end } => {
                let s = start.take().unwrap_or(pos).min(text.len());
                for ch in text[at.min(s)..s].chars() {
                    if ch == '\n' {
                        line = line.saturating_add(1);
                        column = 1;
                    } else {
                        column = column.saturating_add(1);
                    }
                }
                at = at.max(s);
                record.push(Field {
                    text: String::from_utf8_lossy(&field).into_owned(),
                    line,
                    column,
                });
                field.clear();
                if record_end {
                    records.push(std::mem::take(&mut record));
                }
            }
            csv_core::ReadFieldResult::End => break,
        }
    }
    records
}

/// Reads a workbook (`.xlsx`, `.xlsm`, `.xlsb`, `.xls`, `.ods` through calamine): every
/// non-empty sheet (or only `sheet`) is one table; the first non-empty row of a sheet holds the
/// column names. A sheet without data rows is skipped, or an error when it was asked for by
/// name; a workbook with none is an error.
#[cfg(feature = "xlsx")]
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
        let (header_line, first_column) = (r0 as usize + 1, c0 as usize + 1);
        let mut columns = Vec::with_capacity(header.len());
        for (c, cell) in header.iter().enumerate() {
            match cell {
                Data::String(s) if !s.trim().is_empty() => columns.push(s.trim().to_string()),
                other => {
                    return Err(InputError::at(
                        file,
                        header_line,
                        first_column + c,
                        format!("sheet `{name}`"),
                        format!("expected a column name in the header row, got {other:?}"),
                    ))
                }
            }
        }
        let data: Vec<Row> = rows
            .enumerate()
            .map(|(i, row)| {
                let line = header_line + 1 + i;
                Row {
                    line,
                    cells: (0..columns.len())
                        .map(|c| Cell {
                            value: match row.get(c) {
                                Some(Data::Float(v)) if v.is_finite() => Value::Number(*v),
                                Some(Data::Float(v)) => Value::Text(v.to_string().into()),
                                Some(Data::Int(v)) => Value::Number(*v as f64),
                                Some(Data::Empty) | None => Value::Empty,
                                Some(Data::String(s)) => Value::Text(s.as_str().into()),
                                Some(other) => Value::Text(other.to_string().into()),
                            },
                            line: u32::try_from(line).unwrap_or(u32::MAX),
                            column: u32::try_from(first_column + c).unwrap_or(u32::MAX),
                        })
                        .collect(),
                }
            })
            .collect();
        if data.is_empty() {
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
            header_line,
            first_column,
            rows: data,
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

/// Without the `xlsx` feature there is no workbook reader: a workbook is refused by name rather
/// than read as CSV text.
#[cfg(not(feature = "xlsx"))]
pub fn read_workbook(file: &Path, _sheet: Option<&str>) -> Result<Vec<Table>, InputError> {
    Err(InputError::file(file, NO_XLSX))
}

/// Why a build without the `xlsx` feature refuses a workbook, and what to do instead.
#[cfg(not(feature = "xlsx"))]
const NO_XLSX: &str = "this build reads no XLSX; it was built without truepos-io's `xlsx` \
     feature (the LinuxCNC component reads CSV only): save the sheet as CSV, or read the \
     workbook with `truepos`";

/// Whether `file` names a workbook by its extension.
pub fn is_workbook(file: &Path) -> bool {
    let ext = file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(
        ext.as_deref(),
        Some("xlsx" | "xlsm" | "xlsb" | "xls" | "ods")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Table {
        parse_csv(Path::new("t.csv"), text.as_bytes(), CsvOptions::default()).unwrap()
    }

    #[test]
    fn cells_know_their_line_and_character_column() {
        let t = parse("\u{feff}a, b ,c\n\n1,\"x,y\",  3\r\n°4,,\"multi\nline\"\n");
        assert_eq!(t.columns, ["a", "b", "c"]);
        assert_eq!(t.header_line, 1);
        assert_eq!(t.rows.len(), 2);
        let r = &t.rows[0];
        assert_eq!(r.line, 3);
        assert_eq!(
            r.cells.iter().map(|c| c.column).collect::<Vec<_>>(),
            [1, 3, 9]
        );
        assert_eq!(r.cells[1].value, Value::Text("x,y".into()));
        assert_eq!(r.cells[2].value, Value::Number(3.0));
        let r = &t.rows[1];
        assert_eq!(r.line, 4);
        assert_eq!(r.cells[0].value, Value::Text("°4".into()));
        assert_eq!(r.cells[1].value, Value::Empty);
        assert_eq!((r.cells[2].line, r.cells[2].column), (4, 5));
        assert_eq!(r.cells[2].value, Value::Text("multi\nline".into()));
    }

    #[test]
    fn comments_and_blank_lines() {
        let text = "# points\nX,Y # names\n\n  \n1,2 # first\n#\n3,4\n";
        let t = parse_csv(
            Path::new("p.csv"),
            text.as_bytes(),
            CsvOptions {
                comments: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(t.columns, ["X", "Y"]);
        assert_eq!(t.header_line, 2);
        assert_eq!(t.rows.iter().map(|r| r.line).collect::<Vec<_>>(), [5, 7]);
        assert_eq!(t.rows[0].cells[1].value, Value::Number(2.0));
    }

    #[test]
    fn semicolons_and_decimal_commas_are_detected_from_the_header() {
        let t = parse("time_s;t1_c;dz_um\n0;20,5;1\n1;21.25;-0,5\n");
        assert_eq!(t.columns, ["time_s", "t1_c", "dz_um"]);
        assert_eq!(t.rows[0].cells[1].value, Value::Number(20.5));
        assert_eq!(t.rows[1].cells[1].value, Value::Number(21.25));
        assert_eq!(t.rows[1].cells[2].value, Value::Number(-0.5));
        assert_eq!(t.rows[1].cells[2].column, 9);
        // A thousands separator is no decimal comma: the cell stays text for a message.
        let t = parse("a;b\n1.234,5;1,2,3\n");
        assert_eq!(t.rows[0].cells[0].value, Value::Text("1.234,5".into()));
        assert_eq!(t.rows[0].cells[1].value, Value::Text("1,2,3".into()));
        // Quoted semicolons do not make a comma file a semicolon file; with `,` a decimal
        // comma cannot exist.
        let t = parse("time_s,\"a;b\",\"c;d;e\"\n0,\"1,5\",2\n");
        assert_eq!(t.columns, ["time_s", "a;b", "c;d;e"]);
        assert_eq!(t.rows[0].cells[1].value, Value::Text("1,5".into()));
        // A comma inside a name does not outvote the semicolons.
        assert_eq!(
            detect_delimiter("\n\ntime_s;t1 (°C, front);dz_um\n"),
            Delimiter::Semicolon
        );
        assert_eq!(detect_delimiter("a\tb\tc\n"), Delimiter::Tab);
        assert_eq!(detect_delimiter("a\n"), Delimiter::Comma);
        assert_eq!(detect_delimiter("a;b,c\n"), Delimiter::Comma);
        // Forced: a `;` header read as one comma column.
        let t = parse_csv(
            Path::new("t.csv"),
            b"a;b\n1;2\n",
            CsvOptions {
                delimiter: Delimiter::Comma,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(t.columns, ["a;b"]);
        assert_eq!("tab".parse::<Delimiter>(), Ok(Delimiter::Tab));
        assert!("x".parse::<Delimiter>().is_err());
    }

    proptest::proptest! {
        /// Any numbers written with `;` and decimal commas read as the same numbers written
        /// with `,` and points, in the same places.
        #[test]
        fn decimal_commas_read_as_points(
            rows in proptest::collection::vec(proptest::collection::vec(-1e6f64..1e6, 3), 1..20)
        ) {
            let mut comma = String::from("a,b,c\n");
            let mut semi = String::from("a;b;c\n");
            for r in &rows {
                let cells: Vec<String> = r.iter().map(f64::to_string).collect();
                comma += &format!("{}\n", cells.join(","));
                semi += &format!("{}\n", cells.join(";").replace('.', ","));
            }
            let (c, s) = (parse(&comma), parse(&semi));
            proptest::prop_assert_eq!(&c.columns, &s.columns);
            for (x, y) in c.rows.iter().zip(&s.rows) {
                let v = |r: &Row| r.cells.iter().map(|c| c.value.clone()).collect::<Vec<_>>();
                proptest::prop_assert_eq!(v(x), v(y));
            }
        }
    }

    #[test]
    fn not_utf8_names_the_line() {
        let e = parse_csv(Path::new("t.csv"), b"a\n1\n\xff\n", CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert_eq!(e, "t.csv:3:1: expected UTF-8 text");
    }

    #[cfg(not(feature = "xlsx"))]
    #[test]
    fn without_the_xlsx_feature_a_workbook_is_refused_by_name() {
        let e = read_workbook(Path::new("run.xlsx"), None)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("run.xlsx: this build reads no XLSX; "), "{e}");
    }

    #[test]
    fn numbers_and_widths() {
        let t = parse("a,b\nNaN,1e400\n1\n");
        assert_eq!(t.rows[0].cells[0].value, Value::Text("NaN".into()));
        assert!(matches!(t.rows[0].cells[0].value.number(), Number::Value(v) if v.is_nan()));
        assert_eq!(
            t.rows[0].cells[1].value.number(),
            Number::Value(f64::INFINITY)
        );
        assert!(t.width_error(0).is_none());
        assert_eq!(
            t.width_error(1).unwrap().to_string(),
            "t.csv:3:1: expected 2 fields as in the header, found 1"
        );
        assert!(parse("").columns.is_empty());
    }
}
