//! HEIDENHAIN TNC nonlinear axis error compensation: compensation-value tables `*.COM` and
//! the assignment table `*.CMA` that selects them, read into exactly what they say
//! ([`HeidenhainCom`], [`HeidenhainCma`]) and converted to and from [`CompTable`].
//!
//! The layout relied on, from HEIDENHAIN's technical manuals ("Nonlinear axis error
//! compensation": TNC 640 / iTNC 530 / MANUALplus 620 technical manual, chapter on machine
//! axes; the TNC 407 technical manual, section 4 "Machine axes"):
//!
//! * A `.COM` table has a column `NR` (line number), a column `AXISPOS` (the compensation
//!   points, relative to the machine datum) and one column per compensated axis, named as the
//!   axis (`CfgAxes/axisList`), holding the compensation values at those points.
//! * A `.CMA` table has one column per axis; a `.COM` entered in the column of axis A makes
//!   `[axis of the .COM's column] = F(A)`: `AXISPOS` is a position of A. Several lines may
//!   assign tables, exactly one is active, marked by `*` in column `ACTIVE` (selected in the
//!   table editor, by the PLC or by module 9095).
//! * Like every TNC table, the file starts with `BEGIN <name> MM` (or `INCH`), the second line
//!   names the columns, each row follows in the columns' fixed character positions (so an
//!   empty cell is blank) and the file ends with `[END]`.
//!
//! Not verified from a public document, and said so in docs/controls.md: the column widths the
//! control's table editor uses (the reader takes the columns where the header line puts them;
//! the writer pads every column to its widest entry), whether a `.CMA` entry is a bare file
//! name or a path, and the sign of a value (this module writes the error, actual − nominal, as
//! the manual's example plots "Error in Z" at the compensation points).

use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};

use crate::table::{ExportError, Origin};
use truepos_files::InputError;

/// A `.COM` compensation-value table exactly as written: values in mm at `AXISPOS` (mm, or
/// degrees of a rotary axis), one column per compensated axis.
#[derive(Debug, Clone, PartialEq)]
pub struct HeidenhainCom {
    /// The table's name on its `BEGIN` line (`X.COM`).
    pub name: String,
    /// `AXISPOS`: compensation points, strictly increasing.
    pub axispos: Vec<f64>,
    /// The compensated axes (column names) and their values in mm, one per point.
    pub columns: Vec<(String, Vec<f64>)>,
    /// The file and the line of each point, for errors of [`Self::to_table`].
    pub origin: Origin,
}

/// One line of a `.CMA` assignment table.
#[derive(Debug, Clone, PartialEq)]
pub struct CmaLine {
    /// `NR`.
    pub nr: u32,
    /// Per axis column of the table, the `.COM` entered there (`None`: blank).
    pub tables: Vec<Option<String>>,
    /// `ACTIVE` holds `*`.
    pub active: bool,
    /// The line in the file (0 for a table built in memory).
    pub line: usize,
}

/// A `.CMA` assignment table exactly as written.
#[derive(Debug, Clone)]
pub struct HeidenhainCma {
    /// The table's name on its `BEGIN` line (`CONFIG.CMA`).
    pub name: String,
    /// The axis columns, in order.
    pub axes: Vec<String>,
    /// The lines.
    pub lines: Vec<CmaLine>,
}

impl PartialEq for HeidenhainCma {
    fn eq(&self, o: &Self) -> bool {
        let strip = |l: &[CmaLine]| -> Vec<(u32, Vec<Option<String>>, bool)> {
            l.iter()
                .map(|c| (c.nr, c.tables.clone(), c.active))
                .collect()
        };
        self.name == o.name && self.axes == o.axes && strip(&self.lines) == strip(&o.lines)
    }
}

fn is_name(s: &str) -> bool {
    let mut c = s.chars();
    c.next().is_some_and(|ch| ch.is_ascii_alphabetic())
        && c.all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
}

fn is_file_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|ch| ch.is_ascii_alphanumeric() || "_-.:\\/".contains(ch))
}

/// A table name without blanks (it stands on the `BEGIN` line) and an axis name that can be a
/// column name.
fn check_names(name: &str, axis: &str) -> Result<(), ExportError> {
    if name.is_empty() || name.chars().any(char::is_whitespace) {
        return Err(ExportError::Heidenhain(format!(
            "table name `{name}`: expected a name without blanks (it stands on the BEGIN line)"
        )));
    }
    if !is_name(axis) {
        return Err(ExportError::Heidenhain(format!(
            "axis `{axis}`: expected an axis name (a letter, then letters, digits or `_`)"
        )));
    }
    Ok(())
}

/// A TNC table's text: its name, its column names with their 0-based character positions,
/// and its rows' cells (trimmed, with their 1-based columns), each with its line.
struct TncTable<'a> {
    name: String,
    header: Vec<(usize, &'a str)>,
    rows: Vec<(usize, Vec<(usize, &'a str)>)>,
}

/// Reads the frame every TNC table shares (`BEGIN name MM`, the column line, rows at the
/// columns' positions, `[END]`); `expect` names the file type in errors (`.COM`).
fn read_tnc<'a>(path: &Path, text: &'a str, expect: &str) -> Result<TncTable<'a>, InputError> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    let bad =
        |line: usize, col: usize, key: &str, msg: String| InputError::at(path, line, col, key, msg);
    let Some((_, first)) = lines.next() else {
        return Err(InputError::file(
            path,
            format!("empty file; expected a {expect} table starting `BEGIN <name> MM`"),
        ));
    };
    let words: Vec<&str> = first.split_whitespace().collect();
    let name = match words.as_slice() {
        ["BEGIN", name] | ["BEGIN", name, "MM"] => name.to_string(),
        ["BEGIN", _, unit] => {
            return Err(bad(
                1,
                first.find(unit).map_or(1, |i| i + 1),
                "BEGIN",
                format!("unit `{unit}`: truepos writes and reads tables in MM only"),
            ))
        }
        _ => {
            return Err(bad(
                1,
                1,
                "BEGIN",
                format!(
                    "expected `BEGIN <name> MM` opening a {expect} table, got `{}`",
                    first.trim()
                ),
            ))
        }
    };
    let (hline, htext) = lines
        .next()
        .ok_or_else(|| InputError::file(path, "no column line after BEGIN; expected one"))?;
    let mut header: Vec<(usize, &str)> = Vec::new();
    let mut at = 0;
    for w in htext.split_whitespace() {
        let i = htext[at..].find(w).map_or(at, |i| at + i);
        if !htext.is_char_boundary(i) || !htext.is_ascii() {
            return Err(bad(hline, 1, "", "expected ASCII column names".into()));
        }
        header.push((i, w));
        at = i + w.len();
    }
    if header.is_empty() {
        return Err(bad(
            hline,
            1,
            "",
            "empty column line; expected column names".into(),
        ));
    }
    let mut rows = Vec::new();
    let mut ended = false;
    for (n, raw) in lines {
        if ended {
            if raw.trim().is_empty() {
                continue;
            }
            return Err(bad(
                n,
                1,
                "[END]",
                "text after [END]; expected the end of the file".into(),
            ));
        }
        if raw.trim() == "[END]" {
            ended = true;
            continue;
        }
        if raw.trim().is_empty() {
            continue;
        }
        rows.push((n, cells(path, n, raw, &header)?));
    }
    if !ended {
        return Err(InputError::file(
            path,
            "no [END] line: the table is cut short; expected [END] after the last row",
        ));
    }
    Ok(TncTable { name, header, rows })
}

/// The cells of one row at the header's column positions (characters, not bytes).
fn cells<'a>(
    path: &Path,
    n: usize,
    raw: &'a str,
    header: &[(usize, &str)],
) -> Result<Vec<(usize, &'a str)>, InputError> {
    let chars: Vec<(usize, char)> = raw.char_indices().collect();
    let byte = |c: usize| chars.get(c).map_or(raw.len(), |&(b, _)| b);
    let blank = |c: usize| chars.get(c).is_none_or(|&(_, ch)| ch.is_whitespace());
    let mut out = Vec::with_capacity(header.len());
    for (k, &(start, name)) in header.iter().enumerate() {
        if start > 0 && !blank(start - 1) && !blank(start) {
            return Err(InputError::at(
                path,
                n,
                start + 1,
                name,
                format!("a value runs into column {name}; expected each value within its column, as the column line places it"),
            ));
        }
        if k == 0 && (0..start).any(|c| !blank(c)) {
            return Err(InputError::at(
                path,
                n,
                1,
                name,
                format!("text before column {name}"),
            ));
        }
        let end = header.get(k + 1).map_or(chars.len(), |&(s, _)| s);
        let (b0, b1) = (byte(start), byte(end.max(start)));
        let cell = &raw[b0..b1];
        let lead = cell.len() - cell.trim_start().len();
        out.push((raw[..b0 + lead].chars().count() + 1, cell.trim()));
    }
    Ok(out)
}

fn number(path: &Path, line: usize, (col, s): (usize, &str), key: &str) -> Result<f64, InputError> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(InputError::at(
            path,
            line,
            col,
            key,
            format!("expected a finite number, got `{s}`"),
        )),
    }
}

fn nr(path: &Path, line: usize, (col, s): (usize, &str), want: usize) -> Result<u32, InputError> {
    match s.parse::<u32>() {
        Ok(v) if v as usize == want => Ok(v),
        _ => Err(InputError::at(
            path,
            line,
            col,
            "NR",
            format!("expected line number {want} (0, 1, 2, … in order), got `{s}`"),
        )),
    }
}

/// Reads a `.COM` compensation-value table: `NR`, `AXISPOS` and at least one axis column.
pub fn parse_com(path: &Path, text: &str) -> Result<HeidenhainCom, InputError> {
    let t = read_tnc(path, text, ".COM")?;
    let names: Vec<&str> = t.header.iter().map(|h| h.1).collect();
    if names.len() < 3 || names[0] != "NR" || names[1] != "AXISPOS" {
        return Err(InputError::at(
            path,
            2,
            1,
            "",
            format!(
                "expected the columns `NR AXISPOS <axis> …`, got `{}`",
                names.join(" ")
            ),
        ));
    }
    for (i, &(pos, name)) in t.header.iter().enumerate().skip(2) {
        if !is_name(name) || names[..i].contains(&name) {
            return Err(InputError::at(
                path,
                2,
                pos + 1,
                name,
                format!("expected a new axis name as column name, got `{name}`"),
            ));
        }
    }
    let mut com = HeidenhainCom {
        name: t.name,
        axispos: vec![],
        columns: names[2..].iter().map(|n| (n.to_string(), vec![])).collect(),
        origin: Origin::read(path, vec![]),
    };
    for (k, (line, cells)) in t.rows.iter().enumerate() {
        nr(path, *line, cells[0], k)?;
        let p = number(path, *line, cells[1], "AXISPOS")?;
        if let Some(&last) = com.axispos.last() {
            if p <= last {
                return Err(InputError::at(
                    path,
                    *line,
                    cells[1].0,
                    "AXISPOS",
                    format!("{p} is not larger than {last} on the line before; expected strictly increasing compensation points"),
                ));
            }
        }
        com.axispos.push(p);
        for ((name, col), &cell) in com.columns.iter_mut().zip(&cells[2..]) {
            col.push(number(path, *line, cell, name)?);
        }
        com.origin.lines.push(*line);
    }
    if com.axispos.len() < 2 {
        return Err(InputError::file(
            path,
            format!(
                "{} compensation point(s); expected at least 2",
                com.axispos.len()
            ),
        ));
    }
    Ok(com)
}

impl HeidenhainCom {
    /// A `.COM` named `name` with one column `axis` from an error table in µm (values in mm).
    /// A directional table is refused: a `.COM` column holds one value per point.
    pub fn from_table(table: &CompTable, name: &str, axis: &str) -> Result<Self, ExportError> {
        if table.reverse().is_some() {
            return Err(ExportError::DirectionalHeidenhain);
        }
        check_names(name, axis)?;
        Ok(Self {
            name: name.to_string(),
            axispos: table.positions().to_vec(),
            columns: vec![(
                axis.to_string(),
                table.forward().iter().map(|v| v / 1000.0).collect(),
            )],
            origin: Origin::default(),
        })
    }

    /// The error table in µm of column `axis`; an error names the point's line.
    pub fn to_table(
        &self,
        axis: &str,
        wrap: Wrap,
        interpolation: Interpolation,
    ) -> Result<CompTable, InputError> {
        let Some((_, values)) = self.columns.iter().find(|(n, _)| n == axis) else {
            let have: Vec<&str> = self.columns.iter().map(|(n, _)| n.as_str()).collect();
            return Err(self.origin.error(
                "",
                format!(
                    "{} has no column {axis}; it compensates {}",
                    self.name,
                    have.join(", ")
                ),
            ));
        };
        let um = values.iter().map(|v| v * 1000.0).collect();
        CompTable::new(self.axispos.clone(), um, wrap, interpolation)
            .map_err(|e| self.origin.table_error(axis, e))
    }

    /// The file's text: fixed-width columns, each as wide as its widest entry plus two spaces.
    pub fn write(&self) -> String {
        let mut cols: Vec<(String, Vec<String>)> = vec![
            (
                "NR".into(),
                (0..self.axispos.len()).map(|i| i.to_string()).collect(),
            ),
            (
                "AXISPOS".into(),
                self.axispos.iter().map(|p| p.to_string()).collect(),
            ),
        ];
        for (name, v) in &self.columns {
            cols.push((name.clone(), v.iter().map(|x| x.to_string()).collect()));
        }
        write_tnc(&format!("BEGIN {} MM", self.name), &cols)
    }
}

/// A TNC table's text from its columns (name, cells); every row has every column.
fn write_tnc(begin: &str, cols: &[(String, Vec<String>)]) -> String {
    let width: Vec<usize> = cols
        .iter()
        .map(|(n, c)| {
            c.iter()
                .map(String::len)
                .chain([n.len()])
                .max()
                .unwrap_or(0)
                + 2
        })
        .collect();
    let mut out = format!("{begin}\n");
    let line = |cells: Vec<&str>, out: &mut String| {
        let mut l = String::new();
        for (c, w) in cells.iter().zip(&width) {
            let _ = write!(l, "{c:<w$}");
        }
        out.push_str(l.trim_end());
        out.push('\n');
    };
    line(cols.iter().map(|(n, _)| n.as_str()).collect(), &mut out);
    let rows = cols.first().map_or(0, |(_, c)| c.len());
    for r in 0..rows {
        line(cols.iter().map(|(_, c)| c[r].as_str()).collect(), &mut out);
    }
    out.push_str("[END]\n");
    out
}

/// Reads a `.CMA` assignment table: `NR`, one column per axis, `ACTIVE`.
pub fn parse_cma(path: &Path, text: &str) -> Result<HeidenhainCma, InputError> {
    let t = read_tnc(path, text, ".CMA")?;
    let names: Vec<&str> = t.header.iter().map(|h| h.1).collect();
    if names.len() < 3 || names[0] != "NR" || names[names.len() - 1] != "ACTIVE" {
        return Err(InputError::at(
            path,
            2,
            1,
            "",
            format!(
                "expected the columns `NR <axis> … ACTIVE`, got `{}`",
                names.join(" ")
            ),
        ));
    }
    let axes = &t.header[1..t.header.len() - 1];
    for (i, &(pos, name)) in axes.iter().enumerate() {
        if !is_name(name) || axes[..i].iter().any(|a| a.1 == name) {
            return Err(InputError::at(
                path,
                2,
                pos + 1,
                name,
                format!("expected a new axis name as column name, got `{name}`"),
            ));
        }
    }
    let mut cma = HeidenhainCma {
        name: t.name,
        axes: axes.iter().map(|a| a.1.to_string()).collect(),
        lines: vec![],
    };
    for (k, (line, cells)) in t.rows.iter().enumerate() {
        let nr = nr(path, *line, cells[0], k)?;
        let mut tables = Vec::new();
        for (&(col, s), axis) in cells[1..cells.len() - 1].iter().zip(&cma.axes) {
            tables.push(match s {
                "" | "-" => None,
                f if is_file_name(f) => Some(f.to_string()),
                f => {
                    return Err(InputError::at(
                        path,
                        *line,
                        col,
                        axis,
                        format!("expected the name of a .COM table or a blank, got `{f}`"),
                    ))
                }
            });
        }
        let (col, act) = cells[cells.len() - 1];
        let active = match act {
            "*" => true,
            "" => false,
            a => {
                return Err(InputError::at(
                    path,
                    *line,
                    col,
                    "ACTIVE",
                    format!("expected `*` (active) or a blank, got `{a}`"),
                ))
            }
        };
        cma.lines.push(CmaLine {
            nr,
            tables,
            active,
            line: *line,
        });
    }
    Ok(cma)
}

impl HeidenhainCma {
    /// One active line assigning `com` to the reading axis `axis`; names the table format
    /// cannot hold (blanks, an axis that is no column name) are refused.
    pub fn single(name: &str, axis: &str, com: &str) -> Result<Self, ExportError> {
        check_names(name, axis)?;
        if !is_file_name(com) {
            return Err(ExportError::Heidenhain(format!(
                "`{com}` cannot be a .CMA entry; expected letters, digits, `_-.:\\/`"
            )));
        }
        Ok(Self {
            name: name.to_string(),
            axes: vec![axis.to_string()],
            lines: vec![CmaLine {
                nr: 0,
                tables: vec![Some(com.to_string())],
                active: true,
                line: 0,
            }],
        })
    }

    /// The file's text.
    pub fn write(&self) -> String {
        let mut cols: Vec<(String, Vec<String>)> = vec![(
            "NR".into(),
            self.lines.iter().map(|l| l.nr.to_string()).collect(),
        )];
        for (i, a) in self.axes.iter().enumerate() {
            let cells = self
                .lines
                .iter()
                .map(|l| l.tables.get(i).cloned().flatten().unwrap_or_default())
                .collect();
            cols.push((a.clone(), cells));
        }
        cols.push((
            "ACTIVE".into(),
            self.lines
                .iter()
                .map(|l| if l.active { "*" } else { "" }.to_string())
                .collect(),
        ));
        write_tnc(&format!("BEGIN {}", self.name), &cols)
    }

    /// The `.COM` the active line assigns to the reading axis `axis`, with that line. Exactly
    /// one line must be active (the control activates one); errors name the `.CMA`'s line.
    pub fn active_for(&self, path: &Path, axis: &str) -> Result<(&str, usize), InputError> {
        let active: Vec<&CmaLine> = self.lines.iter().filter(|l| l.active).collect();
        let line = match active.as_slice() {
            [l] => *l,
            [] => {
                return Err(InputError::file(
                    path,
                    "no line is active; expected `*` in column ACTIVE of one line",
                ))
            }
            [_, second, ..] => {
                return Err(InputError::at(
                    path,
                    second.line,
                    1,
                    "ACTIVE",
                    format!(
                        "{} lines are active; the control activates one",
                        active.len()
                    ),
                ))
            }
        };
        let Some(i) = self.axes.iter().position(|a| a == axis) else {
            return Err(InputError::file(
                path,
                format!(
                    "no column {axis}; the table assigns {} (give the control's name of the axis if it differs)",
                    self.axes.join(", ")
                ),
            ));
        };
        match &line.tables[i] {
            Some(f) => Ok((f.as_str(), line.line)),
            None => Err(InputError::at(
                path,
                line.line,
                1,
                axis,
                format!(
                    "the active line {} assigns no .COM table to {axis}",
                    line.nr
                ),
            )),
        }
    }
}

/// The error table in µm that the `.CMA` at `cma_path` applies to axis `output` as a function
/// of axis `axis` (the control's axis names): the `.COM` its active line enters in column
/// `axis`, read beside the `.CMA` (a path in the entry, `TNC:\table\X.COM`, is reduced to its
/// file name), and that table's column `output`. Errors name the file and line.
pub fn read_heidenhain(
    cma_path: &Path,
    axis: &str,
    output: &str,
    wrap: Wrap,
    interpolation: Interpolation,
) -> Result<CompTable, InputError> {
    let cma_text = truepos_files::read::read_text(cma_path, truepos_files::TABLE)?;
    let cma = parse_cma(cma_path, &cma_text)?;
    let (entry, line) = cma.active_for(cma_path, axis)?;
    let file = entry.rsplit(['\\', '/', ':']).next().unwrap_or(entry);
    let com_path = cma_path.with_file_name(file);
    let com_text =
        truepos_files::read::read_text(&com_path, truepos_files::TABLE).map_err(|e| {
            InputError::at(
                cma_path,
                line,
                1,
                axis,
                format!("the active line's table {entry}: {e}"),
            )
        })?;
    parse_com(&com_path, &com_text)?.to_table(output, wrap, interpolation)
}
