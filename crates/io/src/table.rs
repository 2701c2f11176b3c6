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
//! assert_eq!(t.row(1).number(1), Number::Text("x"));
//! assert_eq!(
//!     t.at(1, 1, "expected a number, got `x`").to_string(),
//!     "r.csv:3:2: `a`: expected a number, got `x`"
//! );
//! ```

use std::io::Read;
use std::path::{Path, PathBuf};

use truepos_files::InputError;

mod workbook;
pub use workbook::{is_workbook, read_workbook};

/// A cell's content, borrowed from its table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value<'a> {
    /// Nothing (an empty or blank CSV field, an empty workbook cell).
    Empty,
    /// A finite number (a CSV field that reads as one, or a numeric workbook cell).
    Number(f64),
    /// Anything else, trimmed for CSV, as stored for workbooks (`NaN`, `inf` and `1e400` stay
    /// text so that a message can quote them as written).
    Text(&'a str),
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

impl<'a> Value<'a> {
    /// The cell as a number, the one number syntax of every table: Rust's `f64` syntax on the
    /// trimmed text (`1`, `-2.5e3`, `NaN`, `inf`).
    pub fn number(&self) -> Number<'a> {
        match *self {
            Value::Empty => Number::Empty,
            Value::Number(v) => Number::Value(v),
            Value::Text(t) => t
                .trim()
                .parse::<f64>()
                .map_or(Number::Text(t), Number::Value),
        }
    }
}

/// One cell and its place: 1-based line and column in characters (CSV) or row and column
/// (workbook sheets).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell<'a> {
    /// What it holds.
    pub value: Value<'a>,
    /// Line (CSV) or row (sheet) where it starts.
    pub line: u32,
    /// Character column (CSV) or column (sheet) where it starts.
    pub column: u32,
}

/// One data row of a [`Table`].
#[derive(Debug, Clone, Copy)]
pub struct Row<'t> {
    table: &'t Table,
    index: usize,
}

impl<'t> Row<'t> {
    /// Line (CSV) or row (sheet) where it starts.
    pub fn line(&self) -> usize {
        self.table.spans[self.index].line as usize
    }

    /// Number of its cells; a CSV row may hold more or fewer than the header
    /// ([`Table::width_error`]).
    pub fn len(&self) -> usize {
        self.range().len()
    }

    /// Whether it holds no cell.
    pub fn is_empty(&self) -> bool {
        self.range().is_empty()
    }

    fn range(&self) -> std::ops::Range<usize> {
        let start = self.table.spans[self.index].start;
        let end = self
            .table
            .spans
            .get(self.index + 1)
            .map_or(self.table.slots.len(), |s| s.start);
        start..end
    }

    /// Cell `col`, if the row has one.
    pub fn cell(&self, col: usize) -> Option<Cell<'t>> {
        let i = self.range().start + col;
        (col < self.len()).then(|| self.table.cell_at(self.index, i))
    }

    /// Cell `col` read as a number ([`Value::number`]); a missing cell is empty.
    pub fn number(&self, col: usize) -> Number<'t> {
        self.cell(col).map_or(Number::Empty, |c| c.value.number())
    }

    /// Its cells, in file order.
    pub fn cells(self) -> impl Iterator<Item = Cell<'t>> + 't {
        let (table, row) = (self.table, self.index);
        self.range().map(move |i| table.cell_at(row, i))
    }
}

/// Where a row starts: its line and its first cell's index.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Span {
    line: u32,
    start: usize,
}

/// A table as read: a header row of column names and the data rows below it. The cells are
/// stored flat, 12 bytes each (a month of 1 s logs is tens of millions of cells): a number as
/// itself, an empty or text cell as a NaN that names it (`Slot`), and the character column.
#[derive(Debug, Clone)]
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
    spans: Vec<Span>,
    slots: Vec<f64>,
    places: Vec<u32>,
    texts: Vec<Box<str>>,
    /// (cell index, line) of the cells that start on a later line than their row (a quoted
    /// field holding a line break before them), in cell order.
    late: Vec<(usize, u32)>,
}

/// Equal when every cell holds the same value at the same place: the stored slots compare by
/// their bits, since an empty or text cell is a NaN, which never equals itself as a number.
impl PartialEq for Table {
    fn eq(&self, other: &Self) -> bool {
        self.file == other.file
            && self.sheet == other.sheet
            && self.columns == other.columns
            && self.header_line == other.header_line
            && self.first_column == other.first_column
            && self.spans == other.spans
            && self.places == other.places
            && self.texts == other.texts
            && self.late == other.late
            && self.slots.len() == other.slots.len()
            && self
                .slots
                .iter()
                .zip(&other.slots)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

/// How a cell is stored: a number as itself (numbers are finite), anything else as a quiet NaN
/// whose payload says empty (0) or which text (index + 1).
struct Slot;

impl Slot {
    const NAN: u64 = 0x7ff8_0000_0000_0000;

    fn encode(value: Value<'_>, texts: &mut Vec<Box<str>>) -> f64 {
        match value {
            Value::Number(v) if v.is_finite() => v,
            Value::Number(v) => Self::encode(Value::Text(&v.to_string()), texts),
            Value::Empty => f64::from_bits(Self::NAN),
            Value::Text(t) => {
                texts.push(t.into());
                f64::from_bits(Self::NAN | texts.len() as u64)
            }
        }
    }

    fn decode(slot: f64, texts: &[Box<str>]) -> Value<'_> {
        if !slot.is_nan() {
            return Value::Number(slot);
        }
        match (slot.to_bits() & !Self::NAN) as usize {
            0 => Value::Empty,
            i => Value::Text(&texts[i - 1]),
        }
    }
}

impl Table {
    /// A table with its header and no rows yet.
    pub fn new(
        file: &Path,
        sheet: Option<String>,
        columns: Vec<String>,
        header_line: usize,
    ) -> Self {
        Table {
            file: file.to_path_buf(),
            sheet,
            columns,
            header_line,
            first_column: 1,
            spans: Vec::new(),
            slots: Vec::new(),
            places: Vec::new(),
            texts: Vec::new(),
            late: Vec::new(),
        }
    }

    /// Room for `rows` more rows of `width` cells.
    pub fn reserve(&mut self, rows: usize, width: usize) {
        self.spans.reserve(rows);
        self.slots.reserve(rows.saturating_mul(width));
        self.places.reserve(rows.saturating_mul(width));
    }

    /// Starts a data row at `line`.
    pub fn start_row(&mut self, line: usize) {
        self.spans.push(Span {
            line: u32::try_from(line).unwrap_or(u32::MAX),
            start: self.slots.len(),
        });
    }

    /// Adds a cell to the last row started.
    pub fn push_cell(&mut self, value: Value<'_>, line: u32, column: u32) {
        let slot = Slot::encode(value, &mut self.texts);
        let i = self.slots.len();
        self.slots.push(slot);
        self.places.push(column);
        if self.spans.last().is_some_and(|s| s.line != line) {
            self.late.push((i, line));
        }
    }

    /// Cell `i` (flat index) of row `row`.
    fn cell_at(&self, row: usize, i: usize) -> Cell<'_> {
        let line = match self.late.binary_search_by_key(&i, |l| l.0) {
            Ok(k) => self.late[k].1,
            Err(_) => self.spans[row].line,
        };
        Cell {
            value: Slot::decode(self.slots[i], &self.texts),
            line,
            column: self.places[i],
        }
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// Whether there is no data row.
    pub fn is_empty(&self) -> bool {
        self.spans.is_empty()
    }

    /// Data row `index` (panics past the end, like indexing).
    pub fn row(&self, index: usize) -> Row<'_> {
        assert!(
            index < self.spans.len(),
            "row {index} of {}",
            self.spans.len()
        );
        Row { table: self, index }
    }

    /// Every data row, in file order.
    pub fn rows(&self) -> impl ExactSizeIterator<Item = Row<'_>> + '_ {
        (0..self.spans.len()).map(move |index| Row { table: self, index })
    }

    /// The data rows `range` as a table of their own (same file, same header).
    pub fn sub_table(&self, range: std::ops::Range<usize>) -> Table {
        let mut t = self.clone_header();
        for r in range {
            let row = self.row(r);
            t.start_row(row.line());
            for c in row.cells() {
                t.push_cell(c.value, c.line, c.column);
            }
        }
        t
    }
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
        let line = match (row < self.len()).then(|| self.row(row)) {
            Some(r) => r.cell(col).map_or(r.line(), |c| c.line as usize),
            None => self.header_line,
        };
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
        let r = (row < self.len()).then(|| self.row(row));
        let (line, column) = match r.and_then(|r| r.cell(col)) {
            Some(c) => (c.line as usize, c.column as usize),
            None => (r.map_or(self.header_line, |r| r.line()), 1),
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
        let r = (row < self.len()).then(|| self.row(row))?;
        (r.len() != self.columns.len()).then(|| {
            InputError::at(
                &self.file,
                r.line(),
                1,
                "",
                format!(
                    "expected {} fields as in the header, found {}",
                    self.columns.len(),
                    r.len()
                ),
            )
        })
    }

    /// The table without its rows.
    pub fn clone_header(&self) -> Table {
        Table {
            first_column: self.first_column,
            ..Table::new(
                &self.file,
                self.sheet.clone(),
                self.columns.clone(),
                self.header_line,
            )
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

/// The longest line a CSV file may have, in bytes: a row of a thousand columns of twenty
/// characters is 20 kB, so 1 MiB is no limit to a real table, while a file of one endless line
/// (a binary, a wrong export) is refused at its first MiB instead of being split into millions
/// of column names.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Refuses a line longer than [`MAX_LINE_BYTES`], naming the line, before anything of the
/// file is parsed.
fn check_line_lengths(file: &Path, bytes: &[u8]) -> Result<(), InputError> {
    let (mut start, mut line) = (0usize, 1usize);
    loop {
        let end = memchr::memchr(b'\n', &bytes[start..]).map_or(bytes.len(), |i| start + i);
        if end - start > MAX_LINE_BYTES {
            return Err(InputError::at(
                file,
                line,
                MAX_LINE_BYTES + 1,
                "",
                format!(
                    "the line is longer than {MAX_LINE_BYTES} bytes, the longest line a table \
                     may have: expected one row of a table per line"
                ),
            ));
        }
        if end >= bytes.len() {
            return Ok(());
        }
        start = end + 1;
        line += 1;
    }
}

/// Reads a CSV file.
pub fn load_csv(file: &Path, options: CsvOptions) -> Result<Table, InputError> {
    let bytes = truepos_files::read::read(file, truepos_files::RUN)?;
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

/// CSV bytes as text: UTF-16 when a byte-order mark says so, UTF-8 (with or without a
/// byte-order mark) when they are valid UTF-8, else
/// Windows-1252 — what Excel on a German or English Windows writes with "CSV (semicolon
/// separated)", `°` as one byte 0xB0. Windows-1252 decodes every byte and Latin-1 is its subset
/// for the letters shops use; a UTF-8 file almost never reads as valid UTF-8 by accident in the
/// other direction, so the order decides safely.
fn decode(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    // "Unicode text" from Excel is UTF-16 with a byte-order mark: read by the mark.
    if let Some((encoding, _)) = encoding_rs::Encoding::for_bom(bytes) {
        if encoding != encoding_rs::UTF_8 {
            return encoding.decode_with_bom_removal(bytes).0;
        }
    }
    match std::str::from_utf8(bytes) {
        Ok(text) => std::borrow::Cow::Borrowed(text),
        Err(_) => {
            encoding_rs::WINDOWS_1252
                .decode_without_bom_handling(bytes)
                .0
        }
    }
}

/// Parses CSV text: the first record holds the column names, every further record is a row.
/// The only errors are about the text itself (a line too long); what the rows must hold is the
/// caller's to check ([`Table::width_error`], [`Value::number`], [`Table::at`]).
pub fn parse_csv(file: &Path, bytes: &[u8], options: CsvOptions) -> Result<Table, InputError> {
    check_line_lengths(file, bytes)?;
    let text = decode(bytes);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
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
    let mut table = Table::new(file, None, Vec::new(), 1);
    let mut header = true;
    let mut row_open = false;
    // Room for a full row on every line at once: a growing vector would hold up to twice the
    // cells while it doubles.
    let lines = text.bytes().filter(|&b| b == b'\n').count() + 1;
    tokenize(text, delimiter.byte(), |field, line, column, record_end| {
        if header {
            if table.columns.is_empty() {
                table.header_line = line as usize;
            }
            table.columns.push(field.trim().to_string());
            header = !record_end;
            if record_end {
                table.reserve(lines, table.columns.len());
            }
            return;
        }
        if !row_open {
            table.start_row(line as usize);
            row_open = true;
        }
        table.push_cell(
            value_of(field.trim(), delimiter.decimal_comma()),
            line,
            column,
        );
        row_open = !record_end;
    });
    Ok(table)
}

fn value_of(text: &str, decimal_comma: bool) -> Value<'_> {
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
        _ => Value::Text(text),
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

/// Splits CSV text into fields with the csv crate's parser (csv-core), handing each to
/// `field` with its 1-based line and character column and whether it ends its record.
fn tokenize(text: &str, delimiter: u8, mut field: impl FnMut(&str, u32, u32, bool)) {
    let input = text.as_bytes();
    let mut reader = csv_core::ReaderBuilder::new().delimiter(delimiter).build();
    let mut out = vec![0u8; 1024];
    let mut bytes = Vec::new();
    let mut pos = 0;
    let mut start: Option<usize> = None;
    let mut first_of_record = true;
    // Where the line/column count stands, advanced monotonically.
    let (mut at, mut line, mut column) = (0usize, 1u32, 1u32);
    loop {
        if start.is_none() {
            let mut s = pos;
            if first_of_record {
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
        bytes.extend_from_slice(&out[..nout]);
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
                field(&String::from_utf8_lossy(&bytes), line, column, record_end);
                bytes.clear();
                first_of_record = record_end;
            }
            csv_core::ReadFieldResult::End => break,
        }
    }
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
        assert_eq!(t.len(), 2);
        let r = t.row(0);
        assert_eq!(r.line(), 3);
        assert_eq!(r.cells().map(|c| c.column).collect::<Vec<_>>(), [1, 3, 9]);
        assert_eq!(r.cell(1).unwrap().value, Value::Text("x,y"));
        assert_eq!(r.cell(2).unwrap().value, Value::Number(3.0));
        let r = t.row(1);
        assert_eq!(r.line(), 4);
        assert_eq!(r.cell(0).unwrap().value, Value::Text("°4"));
        assert_eq!(r.cell(1).unwrap().value, Value::Empty);
        let c = r.cell(2).unwrap();
        assert_eq!((c.line, c.column), (4, 5));
        assert_eq!(c.value, Value::Text("multi\nline"));
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
        assert_eq!(t.rows().map(|r| r.line()).collect::<Vec<_>>(), [5, 7]);
        assert_eq!(t.row(0).cell(1).unwrap().value, Value::Number(2.0));
    }

    #[test]
    fn semicolons_and_decimal_commas_are_detected_from_the_header() {
        let t = parse("time_s;t1_c;dz_um\n0;20,5;1\n1;21.25;-0,5\n");
        assert_eq!(t.columns, ["time_s", "t1_c", "dz_um"]);
        assert_eq!(t.row(0).cell(1).unwrap().value, Value::Number(20.5));
        assert_eq!(t.row(1).cell(1).unwrap().value, Value::Number(21.25));
        assert_eq!(t.row(1).cell(2).unwrap().value, Value::Number(-0.5));
        assert_eq!(t.row(1).cell(2).unwrap().column, 9);
        // A thousands separator is no decimal comma: the cell stays text for a message.
        let t = parse("a;b\n1.234,5;1,2,3\n");
        assert_eq!(t.row(0).cell(0).unwrap().value, Value::Text("1.234,5"));
        assert_eq!(t.row(0).cell(1).unwrap().value, Value::Text("1,2,3"));
        // Quoted semicolons do not make a comma file a semicolon file; with `,` a decimal
        // comma cannot exist.
        let t = parse("time_s,\"a;b\",\"c;d;e\"\n0,\"1,5\",2\n");
        assert_eq!(t.columns, ["time_s", "a;b", "c;d;e"]);
        assert_eq!(t.row(0).cell(1).unwrap().value, Value::Text("1,5"));
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
            for (x, y) in c.rows().zip(s.rows()) {
                let (vx, vy): (Vec<Value>, Vec<Value>) =
                    (x.cells().map(|c| c.value).collect(), y.cells().map(|c| c.value).collect());
                proptest::prop_assert_eq!(vx, vy);
            }
        }
    }

    #[test]
    fn windows_1252_is_read_when_the_bytes_are_not_utf8() {
        let bytes = b"Zeit;Spindel vorne [\xb0C];Preis [\x80]\n0;21,5;1\n";
        let t = parse_csv(Path::new("t.csv"), bytes, CsvOptions::default()).unwrap();
        assert_eq!(t.columns, ["Zeit", "Spindel vorne [°C]", "Preis [€]"]);
        assert_eq!(t.row(0).number(1), Number::Value(21.5));
        // The same text in UTF-8, with a byte-order mark, reads the same.
        let utf8 = format!(
            "\u{feff}{}",
            "Zeit;Spindel vorne [°C];Preis [€]\n0;21,5;1\n"
        );
        let u = parse_csv(Path::new("u.csv"), utf8.as_bytes(), CsvOptions::default()).unwrap();
        assert_eq!(u.columns, t.columns);
        // And in UTF-16 with its byte-order mark, as Excel's "Unicode text" writes it.
        let mut utf16 = vec![0xff, 0xfe];
        utf16.extend(
            utf8.trim_start_matches('\u{feff}')
                .encode_utf16()
                .flat_map(u16::to_le_bytes),
        );
        let w = parse_csv(Path::new("w.csv"), &utf16, CsvOptions::default()).unwrap();
        assert_eq!(w.columns, t.columns);
        assert_eq!(w.row(0).number(1), Number::Value(21.5));
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
        assert_eq!(t.row(0).cell(0).unwrap().value, Value::Text("NaN"));
        assert!(matches!(t.row(0).number(0), Number::Value(v) if v.is_nan()));
        assert_eq!(t.row(0).number(1), Number::Value(f64::INFINITY));
        assert!(t.width_error(0).is_none());
        assert_eq!(
            t.width_error(1).unwrap().to_string(),
            "t.csv:3:1: expected 2 fields as in the header, found 1"
        );
        assert!(parse("").columns.is_empty());
        // Empty and text cells are NaNs inside; a table still equals its copy.
        let t = parse("a,b\n,x\n1,2\n");
        assert_eq!(t, t.clone());
        assert_ne!(t, parse("a,b\n,y\n1,2\n"));
    }
}
