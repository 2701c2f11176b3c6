//! Compensation table files: truepos' plain CSV form, LinuxCNC `COMP_FILE`s and Siemens
//! SINUMERIK INI part programs (leadscrew/encoder `$AA_ENC_COMP[…]`, sag/cross `$AN_CEC[…]`).
//!
//! Each controller format is first read into a struct that holds exactly what the file says
//! ([`LinuxCncComp`], [`SiemensTable`]), so that a file written by truepos reads back
//! identically (floats are written in Rust's shortest round-trip form). Conversions to and from
//! [`CompTable`] state their units and signs.
//!
//! * **CSV** (truepos): `#` comments, a header `position,value` or `position,forward,reverse`,
//!   then one support point per line.
//! * **LinuxCNC** (`[JOINT_n] COMP_FILE`, `COMP_FILE_TYPE`): lines of three numbers
//!   `nominal forward reverse`, at most 256 rows, nominal strictly increasing. Type 0 holds the
//!   actual positions reached when moving forward / in reverse, type 1 the trims
//!   (actual − nominal). LinuxCNC's joint compensation documentation describes both types.
//! * **Siemens** (SINUMERIK 840D sl, function manual "Compensations" K3): an INI part program
//!   of assignments `$AA_ENC_COMP[e,N,AXn]=value` with `$AA_ENC_COMP_STEP/_MIN/_MAX/_IS_MODULO[e,AXn]`,
//!   and `$AN_CEC[t,N]=value` with `$AN_CEC_INPUT_AXIS/_OUTPUT_AXIS/_STEP/_MIN/_MAX/_DIRECTION/
//!   _MULT_BY_TABLE/_IS_MODULO[t]`; `;` starts a comment; `%_N_…`, `CHANDATA(…)`, `M17`, `M30`
//!   and `M02` lines are accepted. Values are in mm; support points are equidistant.
//!   One Siemens table holds one value column: `$AA_ENC_COMP` has no direction of travel, so
//!   a directional (forward/reverse) table is refused there, and goes out as two CEC tables
//!   with `_DIRECTION` 1 and −1 ([`SiemensTable::directional_pair`], read back with
//!   [`SiemensTable::pair_to_table`]).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};

use crate::error::InputError;

/// Most rows LinuxCNC accepts in a compensation file.
pub const LINUXCNC_MAX_ROWS: usize = 256;

fn parse_number(
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
fn fields(line: &str, sep: Option<char>) -> Vec<(usize, &str)> {
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

fn table_error(
    path: &Path,
    lines: &[usize],
    e: truepos_kinematics::table::TableError,
) -> InputError {
    use truepos_kinematics::table::TableError as E;
    let line = match e {
        E::NonFinite { index } | E::NotIncreasing { index } => lines.get(index).copied(),
        E::JointMismatch { .. } | E::SpanTooLarge { .. } => lines.last().copied(),
        _ => None,
    };
    match line {
        Some(l) => InputError::at(path, l, 1, "position", e.to_string()),
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
    built.map_err(|e| table_error(path, &lines, e))
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

// ------------------------------------------------------------------------------------------
// LinuxCNC

/// What the second and third columns of a LinuxCNC compensation file hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinuxCncType {
    /// `COMP_FILE_TYPE = 0`: actual positions reached moving forward / in reverse.
    Positions,
    /// `COMP_FILE_TYPE = 1`: trims (actual − nominal) moving forward / in reverse.
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
}

impl LinuxCncComp {
    /// The error table in µm (error = actual − nominal), directional, of a linear axis.
    pub fn to_table(&self, interpolation: Interpolation) -> Result<CompTable, String> {
        let trim = |col: &[f64]| -> Vec<f64> {
            col.iter()
                .zip(&self.nominal)
                .map(|(v, n)| match self.file_type {
                    LinuxCncType::Positions => (v - n) * 1000.0,
                    LinuxCncType::Trims => v * 1000.0,
                })
                .collect()
        };
        CompTable::directional(
            self.nominal.clone(),
            trim(&self.forward),
            trim(&self.reverse),
            Wrap::Hold,
            interpolation,
        )
        .map_err(|e| e.to_string())
    }

    /// A LinuxCNC file from an error table in µm (a non-directional table gives equal columns).
    pub fn from_table(table: &CompTable, file_type: LinuxCncType) -> Result<Self, String> {
        if table.positions().len() > LINUXCNC_MAX_ROWS {
            return Err(format!(
                "the table has {} support points; LinuxCNC takes at most {LINUXCNC_MAX_ROWS}",
                table.positions().len()
            ));
        }
        let col = |values: &[f64]| -> Vec<f64> {
            values
                .iter()
                .zip(table.positions())
                .map(|(v, n)| match file_type {
                    LinuxCncType::Positions => n + v / 1000.0,
                    LinuxCncType::Trims => v / 1000.0,
                })
                .collect()
        };
        Ok(Self {
            file_type,
            nominal: table.positions().to_vec(),
            forward: col(table.forward()),
            reverse: col(table.reverse().unwrap_or(table.forward())),
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

// ------------------------------------------------------------------------------------------
// Siemens

/// Which Siemens compensation a table belongs to.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum SiemensKind {
    /// Leadscrew / measuring-system error compensation `$AA_ENC_COMP[encoder, N, axis]`.
    Encoder {
        /// Measuring system (encoder) index, 0 or 1.
        encoder: u32,
        /// Axis name (`AX1`, `X1`).
        axis: String,
    },
    /// Sag / cross compensation `$AN_CEC[table, N]`.
    Cec {
        /// Table number.
        table: u32,
    },
}

/// One Siemens table exactly as the INI file states it.
#[derive(Debug, Clone, PartialEq)]
pub struct SiemensTable {
    /// Leadscrew or sag/cross, with its indices.
    pub kind: SiemensKind,
    /// Compensation values in mm at MIN, MIN + STEP, …, MAX.
    pub values: Vec<f64>,
    /// `_STEP`: distance between support points (mm or degrees).
    pub step: f64,
    /// `_MIN`: first support point.
    pub min: f64,
    /// `_MAX`: last support point.
    pub max: f64,
    /// `_IS_MODULO`: the table is periodic (rotary axis).
    pub is_modulo: bool,
    /// CEC only: `_INPUT_AXIS`, the axis whose position reads the table.
    pub input_axis: Option<String>,
    /// CEC only: `_OUTPUT_AXIS`, the axis the value is added to.
    pub output_axis: Option<String>,
    /// CEC only: `_DIRECTION`: 0 both directions, 1 positive only, −1 negative only.
    pub direction: Option<i32>,
    /// CEC only: `_MULT_BY_TABLE`: number of the table this one is multiplied with (0: none).
    pub mult_by_table: Option<u32>,
}

impl SiemensTable {
    /// The table as a [`CompTable`] of the values in µm (Siemens values are mm).
    pub fn to_table(&self, interpolation: Interpolation) -> Result<CompTable, String> {
        let positions: Vec<f64> = (0..self.values.len())
            .map(|i| self.min + self.step * i as f64)
            .collect();
        let values = self.values.iter().map(|v| v * 1000.0).collect();
        let wrap = if self.is_modulo {
            Wrap::Rotary
        } else {
            Wrap::Hold
        };
        CompTable::new(positions, values, wrap, interpolation).map_err(|e| e.to_string())
    }

    /// A Siemens table from an equidistant [`CompTable`] in µm.
    pub fn from_table(table: &CompTable, kind: SiemensKind) -> Result<Self, String> {
        let p = table.positions();
        let span = p[p.len() - 1] - p[0];
        let step = table
            .step(1e-9 * (1.0 + span.abs()))
            .ok_or("Siemens tables need equidistant support points; resample the table first")?;
        if table.reverse().is_some() {
            // One Siemens table holds one value column: $AA_ENC_COMP has no direction at all,
            // and a CEC table applies to one direction only through its `_DIRECTION`.
            return Err(match kind {
                SiemensKind::Encoder { .. } => "a directional (forward/reverse) table cannot be written as $AA_ENC_COMP, which has no direction of travel; write it as two $AN_CEC tables (SiemensTable::directional_pair) or as a LinuxCNC COMP_FILE",
                SiemensKind::Cec { .. } => "a directional (forward/reverse) table needs two $AN_CEC tables, one with _DIRECTION 1 and one with -1 (SiemensTable::directional_pair)",
            }
            .into());
        }
        let is_cec = matches!(kind, SiemensKind::Cec { .. });
        Ok(Self {
            kind,
            values: table.forward().iter().map(|v| v / 1000.0).collect(),
            step,
            min: p[0],
            max: p[p.len() - 1],
            is_modulo: table.wrap() == Wrap::Rotary,
            input_axis: None,
            output_axis: None,
            direction: is_cec.then_some(0),
            mult_by_table: is_cec.then_some(0),
        })
    }
}

impl SiemensTable {
    /// A directional (forward/reverse) table as the two sag/cross tables Siemens needs for it:
    /// number `first` with `_DIRECTION` 1 (read while the input axis moves towards larger
    /// positions) holding the forward values, and `first + 1` with `_DIRECTION` −1 holding the
    /// reverse ones; both read `input_axis` and correct `output_axis`. A non-directional table
    /// is refused (write it with [`Self::from_table`]).
    pub fn directional_pair(
        table: &CompTable,
        first: u32,
        input_axis: &str,
        output_axis: &str,
    ) -> Result<[Self; 2], String> {
        let Some(reverse) = table.reverse() else {
            return Err("the table has one direction; write it as one table".into());
        };
        let second = first
            .checked_add(1)
            .ok_or("no table number after the first one")?;
        let column = |values: &[f64]| {
            CompTable::new(
                table.positions().to_vec(),
                values.to_vec(),
                table.wrap(),
                table.interpolation(),
            )
            .map_err(|e| e.to_string())
        };
        let mut forward =
            Self::from_table(&column(table.forward())?, SiemensKind::Cec { table: first })?;
        let mut backward = Self::from_table(&column(reverse)?, SiemensKind::Cec { table: second })?;
        for (t, d) in [(&mut forward, 1), (&mut backward, -1)] {
            t.direction = Some(d);
            t.input_axis = Some(input_axis.into());
            t.output_axis = Some(output_axis.into());
        }
        Ok([forward, backward])
    }

    /// The directional [`CompTable`] (µm) from two CEC tables over the same support points,
    /// one with `_DIRECTION` 1 and one with −1 (in either order), as
    /// [`Self::directional_pair`] writes them.
    pub fn pair_to_table(
        a: &Self,
        b: &Self,
        interpolation: Interpolation,
    ) -> Result<CompTable, String> {
        let (forward, reverse) = match (a.direction, b.direction) {
            (Some(1), Some(-1)) => (a, b),
            (Some(-1), Some(1)) => (b, a),
            (x, y) => {
                return Err(format!(
                    "expected one table with _DIRECTION 1 and one with -1, got {} and {}",
                    x.map_or("none".into(), |d| d.to_string()),
                    y.map_or("none".into(), |d| d.to_string())
                ))
            }
        };
        if (
            forward.min,
            forward.step,
            forward.values.len(),
            forward.is_modulo,
        ) != (
            reverse.min,
            reverse.step,
            reverse.values.len(),
            reverse.is_modulo,
        ) {
            return Err("the two direction tables have different support points".into());
        }
        let f = forward.to_table(interpolation)?;
        let r = reverse.to_table(interpolation)?;
        CompTable::directional(
            f.positions().to_vec(),
            f.forward().to_vec(),
            r.forward().to_vec(),
            f.wrap(),
            interpolation,
        )
        .map_err(|e| e.to_string())
    }
}

/// Writes Siemens tables as one INI part program.
pub fn write_siemens(tables: &[SiemensTable]) -> String {
    let mut out = String::from("%_N_COMP_INI\nCHANDATA(1)\n");
    for t in tables {
        match &t.kind {
            SiemensKind::Encoder { encoder, axis } => {
                for (n, v) in t.values.iter().enumerate() {
                    let _ = writeln!(out, "$AA_ENC_COMP[{encoder},{n},{axis}]={v}");
                }
                let _ = writeln!(out, "$AA_ENC_COMP_STEP[{encoder},{axis}]={}", t.step);
                let _ = writeln!(out, "$AA_ENC_COMP_MIN[{encoder},{axis}]={}", t.min);
                let _ = writeln!(out, "$AA_ENC_COMP_MAX[{encoder},{axis}]={}", t.max);
                let _ = writeln!(
                    out,
                    "$AA_ENC_COMP_IS_MODULO[{encoder},{axis}]={}",
                    u8::from(t.is_modulo)
                );
            }
            SiemensKind::Cec { table } => {
                for (n, v) in t.values.iter().enumerate() {
                    let _ = writeln!(out, "$AN_CEC[{table},{n}]={v}");
                }
                if let Some(a) = &t.input_axis {
                    let _ = writeln!(out, "$AN_CEC_INPUT_AXIS[{table}]={a}");
                }
                if let Some(a) = &t.output_axis {
                    let _ = writeln!(out, "$AN_CEC_OUTPUT_AXIS[{table}]={a}");
                }
                let _ = writeln!(out, "$AN_CEC_STEP[{table}]={}", t.step);
                let _ = writeln!(out, "$AN_CEC_MIN[{table}]={}", t.min);
                let _ = writeln!(out, "$AN_CEC_MAX[{table}]={}", t.max);
                if let Some(d) = t.direction {
                    let _ = writeln!(out, "$AN_CEC_DIRECTION[{table}]={d}");
                }
                if let Some(m) = t.mult_by_table {
                    let _ = writeln!(out, "$AN_CEC_MULT_BY_TABLE[{table}]={m}");
                }
                let _ = writeln!(out, "$AN_CEC_IS_MODULO[{table}]={}", u8::from(t.is_modulo));
            }
        }
    }
    out.push_str("M17\n");
    out
}

#[derive(Default)]
struct Pending {
    values: BTreeMap<usize, (f64, usize)>,
    step: Option<f64>,
    min: Option<f64>,
    max: Option<f64>,
    is_modulo: Option<bool>,
    input_axis: Option<String>,
    output_axis: Option<String>,
    direction: Option<i32>,
    mult_by_table: Option<u32>,
    first_line: usize,
}

fn is_axis_name(s: &str) -> bool {
    let mut c = s.chars();
    c.next().is_some_and(|ch| ch.is_ascii_alphabetic())
        && c.all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
}

/// Reads a Siemens INI part program of `$AA_ENC_COMP` and `$AN_CEC` tables. If `axes` is given,
/// every axis name must be one of them.
pub fn parse_siemens(
    path: &Path,
    text: &str,
    axes: Option<&[&str]>,
) -> Result<Vec<SiemensTable>, InputError> {
    let mut pending: BTreeMap<SiemensKind, Pending> = BTreeMap::new();
    let mut ended = false;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split(';').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let upper = line.to_ascii_uppercase();
        if upper.starts_with('%') || upper.starts_with("CHANDATA(") {
            continue;
        }
        if matches!(upper.as_str(), "M17" | "M30" | "M02" | "M2") {
            ended = true;
            continue;
        }
        if ended {
            return Err(InputError::at(
                path,
                line_no,
                1,
                "",
                "assignment after the end of the program (M17/M30/M02)",
            ));
        }
        let col = raw.len() - raw.trim_start().len() + 1;
        let bad = |msg: String| InputError::at(path, line_no, col, line, msg);
        let (lhs, rhs) = line
            .split_once('=')
            .ok_or_else(|| bad("expected an assignment `$NAME[indices]=value`".into()))?;
        let (lhs, rhs) = (lhs.trim(), rhs.trim());
        let (name, idx) = lhs
            .strip_suffix(']')
            .and_then(|l| l.split_once('['))
            .ok_or_else(|| bad("expected `$NAME[indices]` left of `=`".into()))?;
        let name = name.to_ascii_uppercase();
        let idx: Vec<&str> = idx.split(',').map(str::trim).collect();
        let int = |s: &str, what: &str| -> Result<u32, InputError> {
            s.parse::<u32>()
                .map_err(|_| bad(format!("expected a non-negative integer {what}, got `{s}`")))
        };
        let axis = |s: &str| -> Result<String, InputError> {
            if !is_axis_name(s) {
                return Err(bad(format!("expected an axis name such as AX1, got `{s}`")));
            }
            if let Some(known) = axes {
                if !known.contains(&s) {
                    return Err(bad(format!(
                        "unknown axis `{s}`; expected one of {}",
                        known.join(", ")
                    )));
                }
            }
            Ok(s.to_string())
        };
        let number = |s: &str| -> Result<f64, InputError> {
            match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(bad(format!(
                    "expected a finite number right of `=`, got `{s}`"
                ))),
            }
        };
        let want = |n: usize| -> Result<(), InputError> {
            if idx.len() == n {
                Ok(())
            } else {
                Err(bad(format!(
                    "{name} takes {n} index(es), got {}",
                    idx.len()
                )))
            }
        };
        let (kind, field) = if let Some(field) = name.strip_prefix("$AA_ENC_COMP") {
            if field.is_empty() {
                want(3)?;
                let kind = SiemensKind::Encoder {
                    encoder: int(idx[0], "encoder")?,
                    axis: axis(idx[2])?,
                };
                (kind, format!("N{}", int(idx[1], "support point")?))
            } else {
                want(2)?;
                let kind = SiemensKind::Encoder {
                    encoder: int(idx[0], "encoder")?,
                    axis: axis(idx[1])?,
                };
                (kind, field.to_string())
            }
        } else if let Some(field) = name.strip_prefix("$AN_CEC") {
            if field.is_empty() {
                want(2)?;
                let kind = SiemensKind::Cec {
                    table: int(idx[0], "table")?,
                };
                (kind, format!("N{}", int(idx[1], "support point")?))
            } else {
                want(1)?;
                let kind = SiemensKind::Cec {
                    table: int(idx[0], "table")?,
                };
                (kind, field.to_string())
            }
        } else {
            return Err(bad(format!(
                "unknown variable `{name}`; expected $AA_ENC_COMP… or $AN_CEC…"
            )));
        };
        let cec = matches!(kind, SiemensKind::Cec { .. });
        let p = pending.entry(kind).or_insert_with(|| Pending {
            first_line: line_no,
            ..Pending::default()
        });
        let dup = || bad("assigned twice".into());
        match field.as_str() {
            f if f.starts_with('N') => {
                let n: usize = f[1..].parse().unwrap_or(usize::MAX);
                if p.values.insert(n, (number(rhs)?, line_no)).is_some() {
                    return Err(dup());
                }
            }
            "_STEP" => {
                let v = number(rhs)?;
                if v <= 0.0 {
                    return Err(bad(format!("expected a positive step, got {v}")));
                }
                if p.step.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_MIN" => {
                if p.min.replace(number(rhs)?).is_some() {
                    return Err(dup());
                }
            }
            "_MAX" => {
                if p.max.replace(number(rhs)?).is_some() {
                    return Err(dup());
                }
            }
            "_IS_MODULO" => {
                let v = match rhs {
                    "0" | "FALSE" => false,
                    "1" | "TRUE" => true,
                    _ => return Err(bad(format!("expected 0 or 1, got `{rhs}`"))),
                };
                if p.is_modulo.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_INPUT_AXIS" | "_OUTPUT_AXIS" if cec => {
                let a = axis(rhs)?;
                let slot = if field == "_INPUT_AXIS" {
                    &mut p.input_axis
                } else {
                    &mut p.output_axis
                };
                if slot.replace(a).is_some() {
                    return Err(dup());
                }
            }
            "_DIRECTION" if cec => {
                let v = match rhs {
                    "0" => 0,
                    "1" => 1,
                    "-1" => -1,
                    _ => return Err(bad(format!("expected 0, 1 or -1, got `{rhs}`"))),
                };
                if p.direction.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_MULT_BY_TABLE" if cec => {
                let v = int(rhs, "table number")?;
                if p.mult_by_table.replace(v).is_some() {
                    return Err(dup());
                }
            }
            _ => return Err(bad(format!("unknown field `{name}`"))),
        }
    }
    let mut out = Vec::new();
    for (kind, p) in pending {
        let line = p.first_line;
        let prefix = match &kind {
            SiemensKind::Encoder { encoder, axis } => format!("$AA_ENC_COMP[{encoder},…,{axis}]"),
            SiemensKind::Cec { table } => format!("$AN_CEC[{table},…]"),
        };
        let missing = |what: &str| {
            InputError::at(
                path,
                line,
                1,
                prefix.clone(),
                format!("table has no {what} entry; expected one"),
            )
        };
        let step = p.step.ok_or_else(|| missing("_STEP"))?;
        let min = p.min.ok_or_else(|| missing("_MIN"))?;
        let max = p.max.ok_or_else(|| missing("_MAX"))?;
        if max <= min {
            return Err(InputError::at(
                path,
                line,
                1,
                prefix,
                format!("_MAX {max} must be larger than _MIN {min}"),
            ));
        }
        let count_f = (max - min) / step + 1.0;
        let count = count_f.round();
        if (count - count_f).abs() > 1e-6 || count < 2.0 {
            return Err(InputError::at(
                path,
                line,
                1,
                prefix,
                format!("(_MAX − _MIN) / _STEP = ({max} − {min}) / {step} is not a whole number of at least 1"),
            ));
        }
        let count = count as usize;
        let mut values = Vec::with_capacity(count);
        for (expected, (&n, &(v, vline))) in p.values.iter().enumerate() {
            if n != expected {
                return Err(InputError::at(
                    path,
                    vline,
                    1,
                    prefix,
                    format!("support point {n} follows {}; expected support points 0, 1, 2, … without gaps", expected as isize - 1),
                ));
            }
            values.push(v);
        }
        if values.len() != count {
            return Err(InputError::at(
                path,
                line,
                1,
                prefix,
                format!(
                    "{} support point values, but _MIN/_MAX/_STEP describe {count}",
                    values.len()
                ),
            ));
        }
        let is_cec = matches!(kind, SiemensKind::Cec { .. });
        if is_cec && p.input_axis.is_none() {
            return Err(missing("_INPUT_AXIS"));
        }
        if is_cec && p.output_axis.is_none() {
            return Err(missing("_OUTPUT_AXIS"));
        }
        out.push(SiemensTable {
            kind,
            values,
            step,
            min,
            max,
            is_modulo: p.is_modulo.unwrap_or(false),
            input_axis: p.input_axis,
            output_axis: p.output_axis,
            direction: p.direction,
            mult_by_table: p.mult_by_table,
        });
    }
    if out.is_empty() {
        return Err(InputError::file(
            path,
            "no $AA_ENC_COMP or $AN_CEC table; expected at least one",
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn backlash() -> CompTable {
        // 4 µm of backlash around a 3 µm pitch error: forward reads +2, reverse −2 on top.
        let p: Vec<f64> = (0..5).map(|i| 100.0 * i as f64).collect();
        let f = vec![2.0, 3.5, 5.0, 3.5, 2.0];
        let r = f.iter().map(|v| v - 4.0).collect();
        CompTable::directional(p, f, r, Wrap::Hold, Interpolation::Linear).unwrap()
    }

    #[test]
    fn directional_tables_go_to_siemens_as_two_cec_tables() {
        let t = backlash();
        // One table cannot hold both directions, whichever Siemens kind.
        let enc = SiemensKind::Encoder {
            encoder: 0,
            axis: "AX1".into(),
        };
        let e = SiemensTable::from_table(&t, enc).unwrap_err();
        assert!(e.contains("no direction of travel"), "{e}");
        let e = SiemensTable::from_table(&t, SiemensKind::Cec { table: 3 }).unwrap_err();
        assert!(e.contains("_DIRECTION 1"), "{e}");
        let pair = SiemensTable::directional_pair(&t, 3, "AX1", "AX1").unwrap();
        assert_eq!(pair[0].direction, Some(1));
        assert_eq!(pair[1].direction, Some(-1));
        assert_eq!(pair[1].kind, SiemensKind::Cec { table: 4 });
        // Siemens values are mm: 2 µm → 0.002, reverse −2 µm → −0.002.
        assert_eq!(pair[0].values[0], 0.002);
        assert_eq!(pair[1].values[0], -0.002);
        let text = write_siemens(&pair);
        assert!(text.contains("$AN_CEC_DIRECTION[3]=1\n"));
        assert!(text.contains("$AN_CEC_DIRECTION[4]=-1\n"));
        let back = parse_siemens(Path::new("t.ini"), &text, None).unwrap();
        assert_eq!(back, pair);
        // Read back into one directional table, in either order: the same values.
        let t2 = SiemensTable::pair_to_table(&back[1], &back[0], Interpolation::Linear).unwrap();
        assert_eq!(t2.positions(), t.positions());
        for (a, b) in t2.forward().iter().zip(t.forward()) {
            assert!((a - b).abs() < 1e-9);
        }
        for (a, b) in t2.reverse().unwrap().iter().zip(t.reverse().unwrap()) {
            assert!((a - b).abs() < 1e-9);
        }
        // Two tables of the same direction, or a one-direction table, are refused.
        assert!(SiemensTable::pair_to_table(&back[0], &back[0], Interpolation::Linear).is_err());
        let one = CompTable::new(
            t.positions().to_vec(),
            t.forward().to_vec(),
            Wrap::Hold,
            Interpolation::Linear,
        )
        .unwrap();
        assert!(SiemensTable::directional_pair(&one, 3, "AX1", "AX1").is_err());
    }
}
