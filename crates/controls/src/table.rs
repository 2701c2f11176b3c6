//! What every control's compensation table shares, and truepos' own CSV form of a table.
//!
//! Each control's table file is read, in its control's module, into a struct that holds exactly
//! what the file says ([`crate::linuxcnc::LinuxCncComp`], [`crate::siemens::SiemensTable`],
//! [`crate::heidenhain::HeidenhainCom`], [`crate::isg::IsgSsfk`], [`crate::fanuc::FanucPitch`]),
//! so that a file written by truepos reads back identically (floats are written in Rust's
//! shortest round-trip form). Conversions to and from [`CompTable`] state their units and signs;
//! [`Origin`] keeps each support point's line, so a point that does not make a table is named.
//!
//! * **CSV** (truepos): `#` comments, a header `position,value` or `position,forward,reverse`,
//!   then one support point per line ([`parse_csv`], [`write_csv`]).
//! * **LinuxCNC** (`[JOINT_n] COMP_FILE`, `COMP_FILE_TYPE`): lines of three numbers
//!   `nominal forward reverse`, at most 256 rows, nominal strictly increasing. Type 0 holds the
//!   actual positions reached when moving forward / in reverse, type 1 the trims
//!   (nominal − actual: what LinuxCNC adds to the command, the compensation), the sign LinuxCNC's
//!   own loader gives a type 0 line (`usrmotLoadComp` in `usrmotintf.cc`).
//! * **Siemens** (SINUMERIK 840D sl, function manual "Compensations" K3): an INI part program
//!   of assignments `$AA_ENC_COMP[e,N,AXn]=value` with `$AA_ENC_COMP_STEP/_MIN/_MAX/_IS_MODULO[e,AXn]`,
//!   and `$AN_CEC[t,N]=value` with `$AN_CEC_INPUT_AXIS/_OUTPUT_AXIS/_STEP/_MIN/_MAX/_DIRECTION/
//!   _MULT_BY_TABLE/_IS_MODULO[t]`; `;` starts a comment; `%_N_…`, `CHANDATA(…)`, `M17`, `M30`
//!   and `M02` lines are accepted. Values are in mm; support points are equidistant.
//!   One Siemens table holds one value column: `$AA_ENC_COMP` has no direction of travel, so
//!   a directional (forward/reverse) table is refused there, and goes out as two CEC tables
//!   with `_DIRECTION` 1 and −1.
//! * **HEIDENHAIN** (TNC nonlinear axis error compensation): a `.COM` table (`NR`, `AXISPOS`,
//!   one column per compensated axis, mm) selected for a reading axis by the active line of a
//!   `.CMA` assignment table.
//! * **ISG** (Beckhoff TwinCAT CNC) leadscrew error compensation lists `kw.ssfk.*` (0.1 µm,
//!   unilateral or bilateral, equidistant or with set-points).
//! * **FANUC** pitch error compensation: parameters 3620–3624 and incremental point values
//!   in detection units × magnification, in the parameter tape format.

use std::fmt::{self, Write as _};
use std::path::{Path, PathBuf};

use truepos_kinematics::table::{CompTable, Interpolation, TableError, Wrap};

use truepos_files::InputError;

use crate::linuxcnc::LINUXCNC_MAX_ROWS;

/// Where a controller's table was read from: its file and the line of each support point, so
/// that turning it into a [`CompTable`] names the line of a support point that does not make
/// one. Not part of the table's value: tables that say the same compare equal wherever they
/// were read from, so a file truepos writes reads back equal to the table it wrote.
#[derive(Debug, Clone, Default)]
pub struct Origin {
    /// The file; `None` for a table built in memory ([`crate::linuxcnc::LinuxCncComp::from_table`],
    /// [`crate::siemens::SiemensTable::from_table`]).
    pub file: Option<PathBuf>,
    /// The 1-based line of each support point, in order (empty for a table built in memory).
    pub lines: Vec<usize>,
}

impl PartialEq for Origin {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Origin {
    pub(crate) fn read(file: &Path, lines: Vec<usize>) -> Self {
        Self {
            file: Some(file.to_path_buf()),
            lines,
        }
    }

    /// The file an error names: a table built in memory has none, and says so.
    fn file(&self) -> &Path {
        self.file
            .as_deref()
            .unwrap_or(Path::new("(table built in memory)"))
    }

    /// An error about the table as a whole (at its first support point) and `key`.
    pub(crate) fn error(&self, key: &str, message: impl Into<String>) -> InputError {
        InputError {
            file: self.file().to_path_buf(),
            position: self.lines.first().map(|&l| (l, 1)),
            key: Some(key.to_string()).filter(|k| !k.is_empty()),
            message: message.into(),
        }
    }

    /// The error of support points that do not make a table, at the line of the one it names.
    pub(crate) fn table_error(&self, key: &str, e: TableError) -> InputError {
        let mut error = table_error(self.file(), &self.lines, key, e);
        error.key = Some(key.to_string()).filter(|k| !k.is_empty());
        error
    }
}

/// Why a table cannot be written in a controller's format: the table is a valid [`CompTable`],
/// the format cannot hold it (no file is involved yet, so there is no place to name).
#[derive(Debug, Clone, PartialEq)]
pub enum ExportError {
    /// LinuxCNC takes at most [`LINUXCNC_MAX_ROWS`] support points.
    TooManyRows {
        /// Support points of the table.
        rows: usize,
    },
    /// Siemens tables need equidistant support points.
    NotEquidistant,
    /// `$AA_ENC_COMP` has no direction of travel: a directional table does not fit.
    DirectionalEncoder,
    /// One `$AN_CEC` table holds one direction: a directional table needs two.
    DirectionalCec,
    /// [`crate::siemens::SiemensTable::directional_pair`] of a table with one direction.
    OneDirection,
    /// [`crate::siemens::SiemensTable::directional_pair`] needs a table number after `first`.
    NoTableNumber {
        /// The first table's number.
        first: u32,
    },
    /// A HEIDENHAIN `.COM` column holds one value per point: a directional table does not fit.
    DirectionalHeidenhain,
    /// A FANUC pitch-error table: the reason (interval, range, quantisation).
    Fanuc(String),
    /// An ISG compensation list: the reason (a position off the 0.1 µm grid, a 32-bit range).
    Isg(String),
    /// A HEIDENHAIN table: a name the table cannot hold.
    Heidenhain(String),
    /// A column of the table did not make a table on its own.
    Table(TableError),
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManyRows { rows } => write!(
                f,
                "the table has {rows} support points; LinuxCNC takes at most {LINUXCNC_MAX_ROWS}"
            ),
            Self::NotEquidistant => f.write_str(
                "Siemens tables need equidistant support points; resample the table first",
            ),
            Self::DirectionalEncoder => f.write_str(
                "a directional (forward/reverse) table cannot be written as $AA_ENC_COMP, which has no direction of travel; write it as two $AN_CEC tables (SiemensTable::directional_pair) or as a LinuxCNC COMP_FILE",
            ),
            Self::DirectionalCec => f.write_str(
                "a directional (forward/reverse) table needs two $AN_CEC tables, one with _DIRECTION 1 and one with -1 (SiemensTable::directional_pair)",
            ),
            Self::OneDirection => {
                f.write_str("the table has one direction; write it as one table")
            }
            Self::NoTableNumber { first } => {
                write!(f, "no table number after the first one ({first})")
            }
            Self::DirectionalHeidenhain => f.write_str(
                "a directional (forward/reverse) table cannot be written as a HEIDENHAIN .COM column, which holds one value per point; write one direction, or a LinuxCNC COMP_FILE or two Siemens $AN_CEC tables",
            ),
            Self::Fanuc(why) | Self::Isg(why) | Self::Heidenhain(why) => f.write_str(why),
            Self::Table(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for ExportError {}

pub(crate) fn parse_number(
    path: &Path,
    line: usize,
    column: usize,
    key: &str,
    field: &str,
) -> Result<f64, InputError> {
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(InputError::at(
            path,
            line,
            column,
            key,
            format!("expected a finite number, got `{field}`"),
        )),
    }
}

/// Splits a line into fields with their 1-based columns, on `sep` (or whitespace if `None`).
pub(crate) fn fields(line: &str, sep: Option<char>) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    match sep {
        Some(c) => {
            let mut start = 0;
            for part in line.split(c) {
                let lead = part.len() - part.trim_start().len();
                out.push((line[..start + lead].chars().count() + 1, part.trim()));
                start += part.len() + c.len_utf8();
            }
        }
        None => {
            let mut rest = line;
            let mut offset = 0;
            while let Some(i) = rest.find(|ch: char| !ch.is_whitespace()) {
                let s = &rest[i..];
                let end = s.find(char::is_whitespace).unwrap_or(s.len());
                out.push((line[..offset + i].chars().count() + 1, &s[..end]));
                offset += i + end;
                rest = &s[end..];
            }
        }
    }
    out
}

/// A table the support points at `lines` do not make, at the line of the one `e` names (the
/// last one for an error of the whole span), about `key`; about the file if it names none.
pub(crate) fn table_error(path: &Path, lines: &[usize], key: &str, e: TableError) -> InputError {
    use TableError as E;
    let line = match e {
        E::NonFinite { index } | E::NotIncreasing { index } => lines.get(index).copied(),
        E::JointMismatch { .. } | E::SpanTooLarge { .. } => lines.last().copied(),
        _ => None,
    };
    match line {
        Some(l) => InputError::at(path, l, 1, key, e.to_string()),
        None => InputError::file(path, e.to_string()),
    }
}

// ------------------------------------------------------------------------------------------
// CSV

/// Reads truepos' CSV table form. `wrap` says whether the axis is linear or rotary.
pub fn parse_csv(
    path: &Path,
    text: &str,
    wrap: Wrap,
    interpolation: Interpolation,
) -> Result<CompTable, InputError> {
    let mut header: Option<usize> = None;
    let (mut pos, mut fwd, mut rev, mut lines) = (vec![], vec![], vec![], vec![]);
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split('#').next().unwrap_or("");
        if line.trim().is_empty() {
            continue;
        }
        let f = fields(line, Some(','));
        let Some(columns) = header else {
            let names: Vec<&str> = f.iter().map(|(_, s)| *s).collect();
            header = Some(match names.as_slice() {
                ["position", "value"] => 2,
                ["position", "forward", "reverse"] => 3,
                _ => {
                    return Err(InputError::at(
                        path,
                        line_no,
                        1,
                        "header",
                        format!(
                            "expected the header `position,value` or `position,forward,reverse`, got `{}`",
                            line.trim()
                        ),
                    ))
                }
            });
            continue;
        };
        if f.len() != columns {
            return Err(InputError::at(
                path,
                line_no,
                1,
                "",
                format!(
                    "expected {columns} comma-separated numbers, got {}",
                    f.len()
                ),
            ));
        }
        pos.push(parse_number(path, line_no, f[0].0, "position", f[0].1)?);
        let key = if columns == 2 { "value" } else { "forward" };
        fwd.push(parse_number(path, line_no, f[1].0, key, f[1].1)?);
        if columns == 3 {
            rev.push(parse_number(path, line_no, f[2].0, "reverse", f[2].1)?);
        }
        lines.push(line_no);
    }
    if header.is_none() {
        return Err(InputError::file(
            path,
            "empty table; expected a header `position,value` and support points",
        ));
    }
    let built = if header == Some(3) {
        CompTable::directional(pos, fwd, rev, wrap, interpolation)
    } else {
        CompTable::new(pos, fwd, wrap, interpolation)
    };
    built.map_err(|e| table_error(path, &lines, "position", e))
}

/// Writes a table in truepos' CSV form (shortest round-trip float formatting).
pub fn write_csv(table: &CompTable) -> String {
    let mut out = String::new();
    match table.reverse() {
        None => {
            out.push_str("position,value\n");
            for (p, v) in table.positions().iter().zip(table.forward()) {
                let _ = writeln!(out, "{p},{v}");
            }
        }
        Some(rev) => {
            out.push_str("position,forward,reverse\n");
            for ((p, f), r) in table.positions().iter().zip(table.forward()).zip(rev) {
                let _ = writeln!(out, "{p},{f},{r}");
            }
        }
    }
    out
}
