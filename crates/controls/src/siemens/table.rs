//! Siemens SINUMERIK INI part programs of compensation tables (`$AA_ENC_COMP`, `$AN_CEC`),
//! read into exactly what they say ([`SiemensTable`]) and converted to and from
//! [`CompTable`].

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};

use crate::table::{ExportError, Origin};
use truepos_files::InputError;

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
    /// The file and the line of each support point's value, for errors of [`Self::to_table`]
    /// and [`Self::pair_to_table`].
    pub origin: Origin,
}

impl SiemensKind {
    /// The table's name in errors: `$AA_ENC_COMP[0,…,AX1]`, `$AN_CEC[3,…]`.
    pub fn key(&self) -> String {
        match self {
            Self::Encoder { encoder, axis } => format!("$AA_ENC_COMP[{encoder},…,{axis}]"),
            Self::Cec { table } => format!("$AN_CEC[{table},…]"),
        }
    }
}

impl SiemensTable {
    /// The table as a [`CompTable`] of the values in µm (Siemens values are mm); an error
    /// names the line of the support point it is about (see [`Origin`]).
    pub fn to_table(&self, interpolation: Interpolation) -> Result<CompTable, InputError> {
        let positions: Vec<f64> = (0..self.values.len())
            .map(|i| self.min + self.step * i as f64)
            .collect();
        let values = self.values.iter().map(|v| v * 1000.0).collect();
        let wrap = if self.is_modulo {
            Wrap::Rotary
        } else {
            Wrap::Hold
        };
        CompTable::new(positions, values, wrap, interpolation)
            .map_err(|e| self.origin.table_error(&self.kind.key(), e))
    }

    /// A Siemens table from an equidistant [`CompTable`] in µm.
    pub fn from_table(table: &CompTable, kind: SiemensKind) -> Result<Self, ExportError> {
        let p = table.positions();
        let span = p[p.len() - 1] - p[0];
        let step = table
            .step(1e-9 * (1.0 + span.abs()))
            .ok_or(ExportError::NotEquidistant)?;
        if table.reverse().is_some() {
            // One Siemens table holds one value column: $AA_ENC_COMP has no direction at all,
            // and a CEC table applies to one direction only through its `_DIRECTION`.
            return Err(match kind {
                SiemensKind::Encoder { .. } => ExportError::DirectionalEncoder,
                SiemensKind::Cec { .. } => ExportError::DirectionalCec,
            });
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
            origin: Origin::default(),
        })
    }

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
    ) -> Result<[Self; 2], ExportError> {
        let Some(reverse) = table.reverse() else {
            return Err(ExportError::OneDirection);
        };
        let second = first
            .checked_add(1)
            .ok_or(ExportError::NoTableNumber { first })?;
        let column = |values: &[f64]| {
            CompTable::new(
                table.positions().to_vec(),
                values.to_vec(),
                table.wrap(),
                table.interpolation(),
            )
            .map_err(ExportError::Table)
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
    /// [`Self::directional_pair`] writes them; an error names the table it is about.
    pub fn pair_to_table(
        a: &Self,
        b: &Self,
        interpolation: Interpolation,
    ) -> Result<CompTable, InputError> {
        let (forward, reverse) = match (a.direction, b.direction) {
            (Some(1), Some(-1)) => (a, b),
            (Some(-1), Some(1)) => (b, a),
            (x, y) => {
                let odd = if matches!(x, Some(1 | -1)) { b } else { a };
                return Err(odd.origin.error(
                    &odd.kind.key(),
                    format!(
                        "expected one table with _DIRECTION 1 and one with -1, got {} and {}",
                        x.map_or("none".into(), |d| d.to_string()),
                        y.map_or("none".into(), |d| d.to_string())
                    ),
                ));
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
            return Err(reverse.origin.error(
                &reverse.kind.key(),
                format!(
                    "the two direction tables have different support points; expected those of {}",
                    forward.kind.key()
                ),
            ));
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
        .map_err(|e| forward.origin.table_error(&forward.kind.key(), e))
    }
}

impl SiemensTable {
    /// The axis whose position reads the table: `_INPUT_AXIS` of a CEC table, the axis of an
    /// encoder table.
    pub fn reading_axis(&self) -> Option<&str> {
        match &self.kind {
            SiemensKind::Encoder { axis, .. } => Some(axis),
            SiemensKind::Cec { .. } => self.input_axis.as_deref(),
        }
    }

    /// A CEC table whose `_OUTPUT_AXIS` is not `output` (default its own input axis) is refused
    /// at its first line, naming both axes; an encoder table corrects its own axis.
    fn check_output(&self, output: Option<&str>) -> Result<(), InputError> {
        let SiemensKind::Cec { .. } = self.kind else {
            return Ok(());
        };
        let out = output.or(self.input_axis.as_deref()).unwrap_or("?");
        if self.output_axis.as_deref() == Some(out) {
            return Ok(());
        }
        Err(self.origin.error(
            &self.kind.key(),
            format!(
                "{} corrects output axis {} (_OUTPUT_AXIS), not {out}, the axis it is applied to here; expected a table whose _OUTPUT_AXIS is {out} (give the control's name of the corrected axis if it differs)",
                self.kind.key(),
                self.output_axis.as_deref().unwrap_or("?")
            ),
        ))
    }

    /// `$AN_CEC[3,…] (input AX2, output AX3, direction 1)`: the table and its metadata.
    fn describe(&self) -> String {
        match &self.kind {
            SiemensKind::Encoder { .. } => self.kind.key(),
            SiemensKind::Cec { .. } => format!(
                "{} (input {}, output {}, direction {})",
                self.kind.key(),
                self.input_axis.as_deref().unwrap_or("?"),
                self.output_axis.as_deref().unwrap_or("?"),
                self.direction.unwrap_or(0)
            ),
        }
    }

    /// One table as a [`CompTable`] in µm, its `_DIRECTION` kept: a CEC table with
    /// `_DIRECTION` 1 (−1) corrects only while the input axis moves towards larger (smaller)
    /// positions, so it becomes a directional table that is zero the other way.
    fn single_to_table(&self, interpolation: Interpolation) -> Result<CompTable, InputError> {
        let t = self.to_table(interpolation)?;
        let zero = vec![0.0; t.forward().len()];
        let (f, r) = match self.direction {
            Some(1) => (t.forward().to_vec(), zero),
            Some(-1) => (zero, t.forward().to_vec()),
            _ => return Ok(t),
        };
        CompTable::directional(t.positions().to_vec(), f, r, t.wrap(), interpolation)
            .map_err(|e| self.origin.table_error(&self.kind.key(), e))
    }
}

/// The compensation table for `axis` (the control's name of the axis whose position reads it)
/// among the `tables` of one Siemens file, optionally only CEC table `number`: the one table
/// that reads `axis`, or the two CEC tables with `_DIRECTION` 1 and −1 that read it and
/// correct the same output axis (one directional table). A table declared for another input
/// axis is never applied to `axis`; a CEC table whose `_OUTPUT_AXIS` is not `output` (the
/// control's name of the axis the caller applies the values to; `None`: the axis the table
/// reads, i.e. the table is that axis' own error) is refused too, naming both: the control
/// adds its values to that axis and no other. A table multiplied by another
/// (`_MULT_BY_TABLE`) is refused, since its value depends on that table too. Errors name the
/// file and the table.
pub fn select_siemens(
    path: &Path,
    tables: &[SiemensTable],
    axis: Option<&str>,
    output: Option<&str>,
    number: Option<u32>,
    interpolation: Interpolation,
) -> Result<CompTable, InputError> {
    let list = || {
        tables
            .iter()
            .map(SiemensTable::describe)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let numbered: Vec<&SiemensTable> = match number {
        None => tables.iter().collect(),
        Some(n) => {
            let t = tables
                .iter()
                .find(|t| t.kind == SiemensKind::Cec { table: n })
                .ok_or_else(|| {
                    InputError::file(
                        path,
                        format!("no $AN_CEC table {n}; the file holds {}", list()),
                    )
                })?;
            vec![t]
        }
    };
    let chosen: Vec<&SiemensTable> = match axis {
        None => numbered,
        Some(a) => {
            if let [t] = numbered.as_slice() {
                if t.reading_axis() != Some(a) {
                    return Err(t.origin.error(
                        &t.kind.key(),
                        format!(
                            "{} is declared for input axis {}, not {a}; expected a table that reads {a} (give the control's name of the axis if it differs)",
                            t.kind.key(),
                            t.reading_axis().unwrap_or("?")
                        ),
                    ));
                }
            }
            numbered
                .into_iter()
                .filter(|t| t.reading_axis() == Some(a))
                .collect()
        }
    };
    if let Some(t) = chosen.iter().find(|t| t.mult_by_table.unwrap_or(0) != 0) {
        return Err(t.origin.error(
            &t.kind.key(),
            format!(
                "{} is multiplied by table {} (_MULT_BY_TABLE); expected 0, a table truepos can evaluate on its own",
                t.kind.key(),
                t.mult_by_table.unwrap_or(0)
            ),
        ));
    }
    match chosen.as_slice() {
        [t] => {
            t.check_output(output)?;
            t.single_to_table(interpolation)
        }
        [a, b]
            if matches!((a.direction, b.direction), (Some(1), Some(-1)) | (Some(-1), Some(1)))
                && a.input_axis == b.input_axis
                && a.output_axis == b.output_axis =>
        {
            a.check_output(output)?;
            SiemensTable::pair_to_table(a, b, interpolation)
        }
        [] => Err(InputError::file(
            path,
            format!(
                "no table reads axis {}; the file holds {} (give the control's name of the axis if it differs)",
                axis.unwrap_or("?"),
                list()
            ),
        )),
        many => Err(InputError::file(
            path,
            format!(
                "{} tables apply: {}; expected one, or two $AN_CEC tables with _DIRECTION 1 and -1 (choose the table by its number)",
                many.len(),
                many.iter().map(|t| t.describe()).collect::<Vec<_>>().join(", ")
            ),
        )),
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
                // The manual's form, the axis in parentheses.
                if let Some(a) = &t.input_axis {
                    let _ = writeln!(out, "$AN_CEC_INPUT_AXIS[{table}]=({a})");
                }
                if let Some(a) = &t.output_axis {
                    let _ = writeln!(out, "$AN_CEC_OUTPUT_AXIS[{table}]=({a})");
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
        let at = Assignment {
            path,
            line_no,
            col: raw.len() - raw.trim_start().len() + 1,
            text: line,
            axes,
        };
        let (kind, name, field, rhs) = at.target()?;
        let cec = matches!(kind, SiemensKind::Cec { .. });
        let p = pending.entry(kind).or_insert_with(|| Pending {
            first_line: line_no,
            ..Pending::default()
        });
        at.store(p, cec, &name, &field, rhs)?;
    }
    let out = pending
        .into_iter()
        .map(|(kind, p)| finish(path, kind, p))
        .collect::<Result<Vec<_>, _>>()?;
    if out.is_empty() {
        return Err(InputError::file(
            path,
            "no $AA_ENC_COMP or $AN_CEC table; expected at least one",
        ));
    }
    Ok(out)
}

/// One assignment line of the program, with what its errors name.
struct Assignment<'a> {
    path: &'a Path,
    line_no: usize,
    col: usize,
    /// The line without its comment: the key of its errors.
    text: &'a str,
    /// The axes the machine has, if known.
    axes: Option<&'a [&'a str]>,
}

impl Assignment<'_> {
    fn bad(&self, msg: String) -> InputError {
        InputError::at(self.path, self.line_no, self.col, self.text, msg)
    }

    fn int(&self, s: &str, what: &str) -> Result<u32, InputError> {
        s.parse::<u32>()
            .map_err(|_| self.bad(format!("expected a non-negative integer {what}, got `{s}`")))
    }

    fn axis(&self, s: &str) -> Result<String, InputError> {
        if !is_axis_name(s) {
            return Err(self.bad(format!("expected an axis name such as AX1, got `{s}`")));
        }
        if let Some(known) = self.axes {
            if !known.contains(&s) {
                return Err(self.bad(format!(
                    "unknown axis `{s}`; expected one of {}",
                    known.join(", ")
                )));
            }
        }
        Ok(s.to_string())
    }

    fn number(&self, s: &str) -> Result<f64, InputError> {
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.bad(format!("expected a finite number right of `=`, got `{s}`"))),
        }
    }

    /// The table the left side assigns to, the variable's name, the field (`N3` for support
    /// point 3, `_STEP`, …) and the right side.
    fn target(&self) -> Result<(SiemensKind, String, String, &str), InputError> {
        let (lhs, rhs) = self
            .text
            .split_once('=')
            .ok_or_else(|| self.bad("expected an assignment `$NAME[indices]=value`".into()))?;
        let (lhs, rhs) = (lhs.trim(), rhs.trim());
        let (name, idx) = lhs
            .strip_suffix(']')
            .and_then(|l| l.split_once('['))
            .ok_or_else(|| self.bad("expected `$NAME[indices]` left of `=`".into()))?;
        let name = name.to_ascii_uppercase();
        let idx: Vec<&str> = idx.split(',').map(str::trim).collect();
        let want = |n: usize| -> Result<(), InputError> {
            if idx.len() == n {
                Ok(())
            } else {
                Err(self.bad(format!("{name} takes {n} index(es), got {}", idx.len())))
            }
        };
        let (kind, field) = if let Some(field) = name.strip_prefix("$AA_ENC_COMP") {
            if field.is_empty() {
                want(3)?;
                let kind = SiemensKind::Encoder {
                    encoder: self.int(idx[0], "encoder")?,
                    axis: self.axis(idx[2])?,
                };
                (kind, format!("N{}", self.int(idx[1], "support point")?))
            } else {
                want(2)?;
                let kind = SiemensKind::Encoder {
                    encoder: self.int(idx[0], "encoder")?,
                    axis: self.axis(idx[1])?,
                };
                (kind, field.to_string())
            }
        } else if let Some(field) = name.strip_prefix("$AN_CEC") {
            if field.is_empty() {
                want(2)?;
                let kind = SiemensKind::Cec {
                    table: self.int(idx[0], "table")?,
                };
                (kind, format!("N{}", self.int(idx[1], "support point")?))
            } else {
                want(1)?;
                let kind = SiemensKind::Cec {
                    table: self.int(idx[0], "table")?,
                };
                (kind, field.to_string())
            }
        } else {
            return Err(self.bad(format!(
                "unknown variable `{name}`; expected $AA_ENC_COMP… or $AN_CEC…"
            )));
        };
        Ok((kind, name, field, rhs))
    }

    /// Stores the right side `rhs` in `field` of its table (`cec`: a sag/cross table).
    fn store(
        &self,
        p: &mut Pending,
        cec: bool,
        name: &str,
        field: &str,
        rhs: &str,
    ) -> Result<(), InputError> {
        let dup = || self.bad("assigned twice".into());
        match field {
            f if f.starts_with('N') => {
                let n: usize = f[1..].parse().unwrap_or(usize::MAX);
                if p.values
                    .insert(n, (self.number(rhs)?, self.line_no))
                    .is_some()
                {
                    return Err(dup());
                }
            }
            "_STEP" => {
                let v = self.number(rhs)?;
                if v <= 0.0 {
                    return Err(self.bad(format!("expected a positive step, got {v}")));
                }
                if p.step.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_MIN" => {
                if p.min.replace(self.number(rhs)?).is_some() {
                    return Err(dup());
                }
            }
            "_MAX" => {
                if p.max.replace(self.number(rhs)?).is_some() {
                    return Err(dup());
                }
            }
            "_IS_MODULO" => {
                let v = match rhs {
                    "0" | "FALSE" => false,
                    "1" | "TRUE" => true,
                    _ => return Err(self.bad(format!("expected 0 or 1, got `{rhs}`"))),
                };
                if p.is_modulo.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_INPUT_AXIS" | "_OUTPUT_AXIS" if cec => {
                // The function manual (K3, "Sag compensation") writes the axis in parentheses,
                // `$AN_CEC_INPUT_AXIS[0]=(AX1)`; a bare name is read the same.
                let name = match rhs.strip_prefix('(') {
                    Some(inner) => inner.strip_suffix(')').map(str::trim).ok_or_else(|| {
                        self.bad(format!(
                            "expected `(AXIS)` with a closing parenthesis, got `{rhs}`"
                        ))
                    })?,
                    None => rhs,
                };
                let a = self.axis(name)?;
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
                    _ => return Err(self.bad(format!("expected 0, 1 or -1, got `{rhs}`"))),
                };
                if p.direction.replace(v).is_some() {
                    return Err(dup());
                }
            }
            "_MULT_BY_TABLE" if cec => {
                let v = self.int(rhs, "table number")?;
                if p.mult_by_table.replace(v).is_some() {
                    return Err(dup());
                }
            }
            _ => return Err(self.bad(format!("unknown field `{name}`"))),
        }
        Ok(())
    }
}

/// A table from all its assignments: checks that they describe one (step, range, support
/// points without gaps, the axes of a CEC table).
fn finish(path: &Path, kind: SiemensKind, p: Pending) -> Result<SiemensTable, InputError> {
    let line = p.first_line;
    let prefix = kind.key();
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
                format!(
                    "support point {n} follows {}; expected support points 0, 1, 2, … without gaps",
                    expected as isize - 1
                ),
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
    let lines = p.values.values().map(|&(_, line)| line).collect();
    Ok(SiemensTable {
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
        origin: Origin::read(path, lines),
    })
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
        assert!(e.to_string().contains("no direction of travel"), "{e}");
        let e = SiemensTable::from_table(&t, SiemensKind::Cec { table: 3 }).unwrap_err();
        assert!(e.to_string().contains("_DIRECTION 1"), "{e}");
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
