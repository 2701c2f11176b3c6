//! LinuxCNC compensation files (`[JOINT_n] COMP_FILE`, `COMP_FILE_TYPE`), read into exactly
//! what they say ([`LinuxCncComp`]) and converted to and from [`CompTable`].

use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Interpolation, TableError, Wrap};

use crate::table::{fields, parse_number, ExportError, Origin};
use truepos_files::InputError;

/// Most rows LinuxCNC accepts in a compensation file.
pub const LINUXCNC_MAX_ROWS: usize = 256;

/// What the second and third columns of a LinuxCNC compensation file hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinuxCncType {
    /// `COMP_FILE_TYPE = 0`: actual positions reached moving forward / in reverse.
    Positions,
    /// `COMP_FILE_TYPE = 1`: trims moving forward / in reverse, trim = nominal − actual (what
    /// LinuxCNC adds to the commanded position: the compensation, −error), as LinuxCNC's
    /// loader (`usrmotLoadComp`) documents and turns a type 0 line into.
    Trims,
}

/// A LinuxCNC compensation file exactly as written: rows of `nominal forward reverse` in
/// machine units (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct LinuxCncComp {
    /// `COMP_FILE_TYPE`.
    pub file_type: LinuxCncType,
    /// Nominal positions, strictly increasing.
    pub nominal: Vec<f64>,
    /// Second column.
    pub forward: Vec<f64>,
    /// Third column.
    pub reverse: Vec<f64>,
    /// The file and the line of each row, for errors of [`Self::to_table`].
    pub origin: Origin,
}

impl LinuxCncComp {
    /// The error table in µm (error = actual − nominal), directional, of a linear axis; an
    /// error names the row's line (see [`Origin`]).
    pub fn to_table(&self, interpolation: Interpolation) -> Result<CompTable, InputError> {
        let um = |v: f64, n: f64| match self.file_type {
            LinuxCncType::Positions => (v - n) * 1000.0,
            LinuxCncType::Trims => -v * 1000.0,
        };
        let trim = |col: &[f64]| -> Vec<f64> {
            col.iter()
                .zip(&self.nominal)
                .map(|(&v, &n)| um(v, n))
                .collect()
        };
        // The column of a value that is no number in µm (beyond ±1.8e305 mm).
        let key = |e: &TableError| {
            let TableError::NonFinite { index } = *e else {
                return "nominal";
            };
            let bad = |col: &[f64]| {
                let v = col.get(index).zip(self.nominal.get(index));
                v.is_some_and(|(&v, &n)| !um(v, n).is_finite())
            };
            if self.nominal.get(index).is_some_and(|n| !n.is_finite()) {
                "nominal"
            } else if bad(&self.forward) {
                "forward"
            } else {
                "reverse"
            }
        };
        CompTable::directional(
            self.nominal.clone(),
            trim(&self.forward),
            trim(&self.reverse),
            Wrap::Hold,
            interpolation,
        )
        .map_err(|e| self.origin.table_error(key(&e), e))
    }

    /// A LinuxCNC file from an error table in µm (a non-directional table gives equal columns).
    pub fn from_table(table: &CompTable, file_type: LinuxCncType) -> Result<Self, ExportError> {
        if table.positions().len() > LINUXCNC_MAX_ROWS {
            return Err(ExportError::TooManyRows {
                rows: table.positions().len(),
            });
        }
        let col = |values: &[f64]| -> Vec<f64> {
            values
                .iter()
                .zip(table.positions())
                .map(|(v, n)| match file_type {
                    LinuxCncType::Positions => n + v / 1000.0,
                    LinuxCncType::Trims => -v / 1000.0,
                })
                .collect()
        };
        Ok(Self {
            file_type,
            nominal: table.positions().to_vec(),
            forward: col(table.forward()),
            reverse: col(table.reverse().unwrap_or(table.forward())),
            origin: Origin::default(),
        })
    }

    /// The file's text.
    pub fn write(&self) -> String {
        let mut out = String::new();
        for ((n, f), r) in self.nominal.iter().zip(&self.forward).zip(&self.reverse) {
            let _ = writeln!(out, "{n} {f} {r}");
        }
        out
    }
}

/// Reads a LinuxCNC compensation file of the given `COMP_FILE_TYPE`. Blank lines and `#`
/// comments are skipped.
pub fn parse_linuxcnc(
    path: &Path,
    text: &str,
    file_type: LinuxCncType,
) -> Result<LinuxCncComp, InputError> {
    let mut comp = LinuxCncComp {
        file_type,
        nominal: vec![],
        forward: vec![],
        reverse: vec![],
        origin: Origin::read(path, vec![]),
    };
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split('#').next().unwrap_or("");
        let f = fields(line, None);
        if f.is_empty() {
            continue;
        }
        if f.len() != 3 {
            return Err(InputError::at(
                path,
                line_no,
                1,
                "",
                format!(
                    "expected three numbers `nominal forward reverse`, got {} field(s)",
                    f.len()
                ),
            ));
        }
        let n = parse_number(path, line_no, f[0].0, "nominal", f[0].1)?;
        if let Some(&last) = comp.nominal.last() {
            if n <= last {
                return Err(InputError::at(
                    path,
                    line_no,
                    f[0].0,
                    "nominal",
                    format!("nominal {n} is not larger than {last} on the line before; expected strictly increasing positions"),
                ));
            }
        }
        if comp.nominal.len() == LINUXCNC_MAX_ROWS {
            return Err(InputError::at(
                path,
                line_no,
                1,
                "",
                format!("more than {LINUXCNC_MAX_ROWS} rows; LinuxCNC takes at most {LINUXCNC_MAX_ROWS}"),
            ));
        }
        comp.nominal.push(n);
        comp.forward
            .push(parse_number(path, line_no, f[1].0, "forward", f[1].1)?);
        comp.reverse
            .push(parse_number(path, line_no, f[2].0, "reverse", f[2].1)?);
        comp.origin.lines.push(line_no);
    }
    if comp.nominal.len() < 2 {
        return Err(InputError::file(
            path,
            format!(
                "{} row(s); expected at least 2 lines `nominal forward reverse`",
                comp.nominal.len()
            ),
        ));
    }
    Ok(comp)
}
