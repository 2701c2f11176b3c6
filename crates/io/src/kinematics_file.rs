//! The kinematics table file (`*.ktab`): the kinematics table as text, plus the axes and the
//! compensation tables it references.
//!
//! ```text
//! # a 5-axis head: A swivels in a fork on C; the head rides on Z, Y, X
//! name = head-ac
//! tool_length = 100                      # mm, used when no tool length is given
//! axis X linear -1000 1000               # set-point order; travel in mm / degrees
//! axis A rotary -110 110                 # (travel may be left out when a machine file is given)
//! table F_A_X axis=A unit=um file=tables/F_A_X.csv        # format=csv|linuxcnc-0|linuxcnc-1|siemens
//! table E_X_Z axis=X unit=um file=tables/cec.ini format=siemens siemens-axis=AX1 siemens-output-axis=AX3 siemens-table=2
//! table F_A_B axis=A unit=urad file=tables/F_A_B.csv interpolation=monotone
//! # Nr  Key       Axis  Delta      KompFile
//!   0   Trans     Z     -L-150     -        # tool length L enters here
//!   1   Trans     X     0          F_A_X    # error row: Delta + table value
//!   2   Trans     B     0          F_A_B
//!   3   MachAxis  A     -          -        # Delta of a MachAxis row: the axis name (- = the letter)
//! ```
//!
//! Rows run from the TCP towards the workpiece (see [`truepos_kinematics`] for the
//! convention). A `MachAxis` whose axis letter carries a minus (`-C`) moves the workpiece.
//! Table files are read relative to the kinematics file. Every error names the file, line,
//! column and what was expected.

use std::path::{Path, PathBuf};

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};
use truepos_kinematics::{Chain, Dof, ErrorTable, ErrorUnit, KinAxis, Row};
use truepos_model::{AxisKind, Machine};

use crate::error::read_text;
use truepos_controls::linuxcnc::{parse_linuxcnc, LinuxCncType};
use truepos_controls::siemens::{parse_siemens, select_siemens};
use truepos_controls::table::parse_csv;
use truepos_files::InputError;

/// A loaded kinematics table.
#[derive(Debug, Clone)]
pub struct KinematicsFile {
    /// `name =` (empty if not given).
    pub name: String,
    /// `tool_length =` in mm (0 if not given).
    pub tool_length_mm: f64,
    /// The checked chain.
    pub chain: Chain,
    /// For each chain axis, its index in the machine description (when one was given).
    pub machine_axis: Option<Vec<usize>>,
}

/// Reads a kinematics file and the tables it references; with `machine`, every axis must exist
/// there with the same kind, and travel comes from the machine.
pub fn load(path: &Path, machine: Option<&Machine>) -> Result<KinematicsFile, InputError> {
    let text = read_text(path, truepos_files::CONFIG)?;
    parse(path, &text, machine)
}

struct Field<'a> {
    col: usize,
    text: &'a str,
}

fn split_fields(line: &str) -> Vec<Field<'_>> {
    let mut out = Vec::new();
    let mut offset = 0;
    let mut rest = line;
    while let Some(i) = rest.find(|c: char| !c.is_whitespace()) {
        let s = &rest[i..];
        let end = s.find(char::is_whitespace).unwrap_or(s.len());
        out.push(Field {
            col: line[..offset + i].chars().count() + 1,
            text: &s[..end],
        });
        offset += i + end;
        rest = &s[end..];
    }
    out
}

fn number(path: &Path, line: usize, f: &Field<'_>, key: &str) -> Result<f64, InputError> {
    match f.text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(InputError::at(
            path,
            line,
            f.col,
            key,
            format!("expected a finite number, got `{}`", f.text),
        )),
    }
}

/// Parses `L`, `-L`, `L+c`, `L-c`, `-L+c`, `-L-c` (tool length plus a fixed part).
fn tool_expression(s: &str) -> Option<(f64, f64)> {
    let (sign, rest) = match s.strip_prefix('-') {
        Some(r) => (-1.0, r),
        None => (1.0, s.strip_prefix('+').unwrap_or(s)),
    };
    let rest = rest.strip_prefix('L')?;
    if rest.is_empty() {
        return Some((sign, 0.0));
    }
    let offset: f64 = rest.parse().ok()?;
    offset.is_finite().then_some((sign, offset))
}

/// Parses kinematics text; `path` names the file in errors and locates table files.
pub fn parse(
    path: &Path,
    text: &str,
    machine: Option<&Machine>,
) -> Result<KinematicsFile, InputError> {
    let mut draft = Draft {
        path,
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        machine,
        name: String::new(),
        tool_length_mm: 0.0,
        axes: Vec::new(),
        machine_axis: Vec::new(),
        tables: Vec::new(),
        rows: Vec::new(),
        row_lines: Vec::new(),
    };
    for (i, raw) in text.lines().enumerate() {
        let code = raw.split('#').next().unwrap_or("");
        let line = Line {
            path,
            ln: i + 1,
            raw,
            f: split_fields(code),
        };
        if line.f.is_empty() {
            continue;
        }
        if let Some((key, value)) = code.split_once('=').filter(|_| line.f[0].text != "table") {
            draft.setting(&line, key.trim(), value.trim())?;
            continue;
        }
        match line.f[0].text {
            "axis" => draft.axis(&line)?,
            "table" => draft.table(&line)?,
            _ => draft.row(&line)?,
        }
    }
    draft.finish()
}

/// One non-empty line of a kinematics file, split into fields.
struct Line<'a> {
    path: &'a Path,
    /// 1-based line number.
    ln: usize,
    /// The whole line, comment included, for columns.
    raw: &'a str,
    f: Vec<Field<'a>>,
}

impl Line<'_> {
    /// An error at `field` of this line.
    fn at(&self, field: &Field<'_>, key: &str, msg: String) -> InputError {
        InputError::at(self.path, self.ln, field.col, key, msg)
    }
}

/// What the lines read so far declare, in file order; rows and tables may only reference axes
/// and tables declared above them.
struct Draft<'a> {
    path: &'a Path,
    /// Table files are read relative to this directory.
    dir: PathBuf,
    machine: Option<&'a Machine>,
    name: String,
    tool_length_mm: f64,
    axes: Vec<KinAxis>,
    machine_axis: Vec<usize>,
    tables: Vec<ErrorTable>,
    rows: Vec<Row>,
    /// The line of each row, to place the chain's errors.
    row_lines: Vec<usize>,
}

impl Draft<'_> {
    /// A `key = value` setting: `name` or `tool_length`.
    fn setting(&mut self, line: &Line<'_>, key: &str, value: &str) -> Result<(), InputError> {
        match key {
            "name" => self.name = value.to_string(),
            "tool_length" => {
                let vf = Field {
                    col: line
                        .raw
                        .find('=')
                        .map_or(1, |c| line.raw[..c + 1].chars().count() + 1),
                    text: value,
                };
                self.tool_length_mm = number(self.path, line.ln, &vf, "tool_length")?;
            }
            _ => {
                return Err(line.at(
                    &line.f[0],
                    key,
                    format!("unknown setting `{key}`; expected name or tool_length"),
                ))
            }
        }
        Ok(())
    }

    /// An `axis` line: declared once, and its kind and travel come from the machine when one is
    /// given, else from the line.
    fn axis(&mut self, line: &Line<'_>) -> Result<(), InputError> {
        let f = &line.f;
        let Some(nf) = f.get(1) else {
            return Err(line.at(
                &f[0],
                "axis",
                "expected `axis NAME [linear|rotary MIN MAX]`".into(),
            ));
        };
        let axis_name = nf.text;
        if self.axes.iter().any(|a| a.name == axis_name) {
            return Err(line.at(nf, "axis", format!("axis `{axis_name}` declared twice")));
        }
        let declared = declared_axis(line)?;
        let from_machine = match self.machine {
            Some(m) => {
                let (idx, a) = machine_axis(line, m, declared)?;
                self.machine_axis.push(idx);
                Some(a)
            }
            None => None,
        };
        let Some((kind, lo, hi)) = from_machine.or(declared) else {
            return Err(line.at(
                nf,
                "axis",
                format!("axis `{axis_name}` needs `linear|rotary MIN MAX` when no machine file is given"),
            ));
        };
        self.axes.push(KinAxis {
            name: axis_name.to_string(),
            kind,
            travel_min: lo,
            travel_max: hi,
        });
        Ok(())
    }

    /// A `table` line: its options are complete, its name is new, and the table it reads wraps
    /// like its axis and holds the unit it claims.
    fn table(&mut self, line: &Line<'_>) -> Result<(), InputError> {
        let f = &line.f;
        let Some(nf) = f.get(1) else {
            return Err(line.at(
                &f[0],
                "table",
                "expected `table NAME axis=… unit=… file=…`".into(),
            ));
        };
        let TableOptions {
            axis,
            unit,
            file,
            format,
            interp,
            siemens_axis,
            siemens_output_axis,
            siemens_table,
        } = table_options(line, &self.axes)?;
        let (Some(axis), Some(unit), Some((file_field, file))) = (axis, unit, file) else {
            return Err(line.at(nf, "table", "expected axis=…, unit=… and file=…".into()));
        };
        if self.tables.iter().any(|t| t.name == nf.text) {
            return Err(line.at(nf, "table", format!("table `{}` declared twice", nf.text)));
        }
        let wrap = match self.axes[axis].kind {
            AxisKind::Linear => Wrap::Hold,
            AxisKind::Rotary => Wrap::Rotary,
        };
        let table_path: PathBuf = self.dir.join(file);
        let table_text = read_text(&table_path, truepos_files::TABLE)
            .map_err(|e| line.at(file_field, "file", format!("table `{}`: {}", nf.text, e)))?;
        if format != "siemens"
            && (siemens_axis.is_some() || siemens_output_axis.is_some() || siemens_table.is_some())
        {
            return Err(line.at(
                nf,
                "format",
                "siemens-axis=, siemens-output-axis= and siemens-table= need format=siemens".into(),
            ));
        }
        let reading = siemens_axis.unwrap_or(&self.axes[axis].name);
        let pick = SiemensPick {
            axis: reading,
            output: siemens_output_axis.unwrap_or(reading),
            number: siemens_table,
        };
        let built = read_table(&table_path, &table_text, format, wrap, interp, pick)?;
        if built.wrap() != wrap {
            return Err(line.at(
                nf,
                "table",
                "a modulo (rotary) table on a linear axis or the other way round".into(),
            ));
        }
        if format != "csv" && unit != ErrorUnit::Micrometre {
            return Err(line.at(
                nf,
                "unit",
                "LinuxCNC and Siemens tables hold lengths in mm, read as µm: expected unit=um"
                    .into(),
            ));
        }
        self.tables.push(ErrorTable {
            name: nf.text.to_string(),
            axis,
            unit,
            table: built,
        });
        Ok(())
    }

    /// A row `Nr Key Axis Delta KompFile`: numbered from 0 without gaps, five columns, a known
    /// direction, and a `Trans` or `MachAxis` key.
    fn row(&mut self, line: &Line<'_>) -> Result<(), InputError> {
        let f = &line.f;
        let nr = f[0].text;
        if nr.parse::<usize>().ok() != Some(self.rows.len()) {
            return Err(line.at(
                &f[0],
                "Nr",
                format!(
                    "expected row number {} (rows count from 0 without gaps) or a setting, `axis` or `table` line, got `{nr}`",
                    self.rows.len()
                ),
            ));
        }
        if f.len() != 5 {
            return Err(line.at(
                &f[0],
                "",
                format!(
                    "expected 5 columns `Nr Key Axis Delta KompFile`, got {}",
                    f.len()
                ),
            ));
        }
        let (key, axis_f) = (&f[1], &f[2]);
        let (neg, letter) = match axis_f.text.strip_prefix('-') {
            Some(l) => (true, l),
            None => (false, axis_f.text),
        };
        let Some(dof) = Dof::parse(letter) else {
            return Err(line.at(
                axis_f,
                "Axis",
                format!("expected X, Y, Z, A, B or C, got `{}`", axis_f.text),
            ));
        };
        let row = match key.text {
            "Trans" => self.trans_row(line, neg, dof)?,
            "MachAxis" => self.mach_axis_row(line, neg, letter, dof)?,
            other => {
                return Err(line.at(
                    key,
                    "Key",
                    format!("expected Trans or MachAxis, got `{other}`"),
                ))
            }
        };
        self.rows.push(row);
        self.row_lines.push(line.ln);
        Ok(())
    }

    /// A `Trans` row: an error row when it names a table (whose unit fits the direction), a
    /// tool-length row when Delta holds `L`, else a fixed translation or rotation.
    fn trans_row(&self, line: &Line<'_>, neg: bool, dof: Dof) -> Result<Row, InputError> {
        let (axis_f, delta, komp) = (&line.f[2], &line.f[3], &line.f[4]);
        if neg {
            return Err(line.at(
                axis_f,
                "Axis",
                "a Trans row takes no sign on its axis; put the sign on Delta".into(),
            ));
        }
        if komp.text != "-" {
            let Some(t) = self.tables.iter().position(|t| t.name == komp.text) else {
                return Err(line.at(
                    komp,
                    "KompFile",
                    format!(
                        "unknown table `{}`; declare it with a `table` line first",
                        komp.text
                    ),
                ));
            };
            let offset = if delta.text == "-" {
                0.0
            } else {
                number(self.path, line.ln, delta, "Delta")?
            };
            if self.tables[t].unit.is_angle() != dof.is_rotation() {
                return Err(line.at(
                    komp,
                    "KompFile",
                    format!(
                        "table `{}` is in {}, which does not fit direction {}",
                        komp.text,
                        self.tables[t].unit.name(),
                        dof.name()
                    ),
                ));
            }
            Ok(Row::Error {
                dof,
                offset,
                table: t,
            })
        } else if let Some((sign, offset)) = tool_expression(delta.text) {
            if dof.is_rotation() {
                return Err(line.at(
                    delta,
                    "Delta",
                    "the tool length L can only enter a translation (X, Y, Z)".into(),
                ));
            }
            Ok(Row::Tool { dof, sign, offset })
        } else {
            Ok(Row::Fixed {
                dof,
                value: number(self.path, line.ln, delta, "Delta")?,
            })
        }
    }

    /// A `MachAxis` row: a declared axis (Delta, or the direction letter when Delta is `-`)
    /// whose kind fits the direction, and no table.
    fn mach_axis_row(
        &self,
        line: &Line<'_>,
        neg: bool,
        letter: &str,
        dof: Dof,
    ) -> Result<Row, InputError> {
        let (axis_f, delta, komp) = (&line.f[2], &line.f[3], &line.f[4]);
        let axis_name = if delta.text == "-" {
            letter
        } else {
            delta.text
        };
        let Some(axis) = self.axes.iter().position(|a| a.name == axis_name) else {
            return Err(line.at(
                if delta.text == "-" { axis_f } else { delta },
                "Axis",
                format!("unknown machine axis `{axis_name}`; declare it with an `axis` line first"),
            ));
        };
        if (self.axes[axis].kind == AxisKind::Rotary) != dof.is_rotation() {
            return Err(line.at(
                axis_f,
                "Axis",
                format!(
                    "axis `{axis_name}` is {} but direction {} is {}",
                    if dof.is_rotation() {
                        "linear"
                    } else {
                        "rotary"
                    },
                    dof.name(),
                    if dof.is_rotation() {
                        "a rotation"
                    } else {
                        "a translation"
                    }
                ),
            ));
        }
        if komp.text != "-" {
            return Err(line.at(
                komp,
                "KompFile",
                "a MachAxis row takes no table; put error rows next to it".into(),
            ));
        }
        Ok(Row::Axis {
            dof,
            axis,
            sign: if neg { -1.0 } else { 1.0 },
        })
    }

    /// The checked chain: at least one row, and the chain's own checks placed at the row's line
    /// where they concern one row.
    fn finish(self) -> Result<KinematicsFile, InputError> {
        let path = self.path;
        if self.rows.is_empty() {
            return Err(InputError::file(
                path,
                "no rows; expected `0 Trans …` lines",
            ));
        }
        let row_lines = self.row_lines;
        let chain = Chain::new(self.axes, self.tables, self.rows).map_err(|e| {
            use truepos_kinematics::ChainError as E;
            let line = match &e {
                E::BadReference { row }
                | E::KindMismatch { row }
                | E::UnitMismatch { row }
                | E::ToolNotTranslation { row } => row_lines.get(*row).copied(),
                _ => None,
            };
            match line {
                Some(l) => InputError::at(path, l, 1, "", e.to_string()),
                None => InputError::file(path, e.to_string()),
            }
        })?;
        Ok(KinematicsFile {
            name: self.name,
            tool_length_mm: self.tool_length_mm,
            chain,
            machine_axis: self.machine.map(|_| self.machine_axis),
        })
    }
}

/// The kind and travel an `axis NAME linear|rotary MIN MAX` line declares (MIN < MAX); `None`
/// for a bare `axis NAME`.
fn declared_axis(line: &Line<'_>) -> Result<Option<(AxisKind, f64, f64)>, InputError> {
    let f = &line.f;
    if f.len() >= 5 {
        let kind = match f[2].text {
            "linear" => AxisKind::Linear,
            "rotary" => AxisKind::Rotary,
            other => {
                return Err(line.at(
                    &f[2],
                    "axis",
                    format!("expected linear or rotary, got `{other}`"),
                ))
            }
        };
        let lo = number(line.path, line.ln, &f[3], "axis travel")?;
        let hi = number(line.path, line.ln, &f[4], "axis travel")?;
        if hi <= lo {
            return Err(line.at(
                &f[3],
                "axis travel",
                format!("expected MIN < MAX, got {lo} {hi}"),
            ));
        }
        Ok(Some((kind, lo, hi)))
    } else if f.len() == 2 {
        Ok(None)
    } else {
        Err(line.at(
            &f[0],
            "axis",
            "expected `axis NAME` or `axis NAME linear|rotary MIN MAX`".into(),
        ))
    }
}

/// The machine's axis of the name on an `axis` line: its index, kind and travel. It must exist
/// there, and a kind the line declares must agree with the machine's.
fn machine_axis(
    line: &Line<'_>,
    m: &Machine,
    declared: Option<(AxisKind, f64, f64)>,
) -> Result<(usize, (AxisKind, f64, f64)), InputError> {
    let nf = &line.f[1];
    let axis_name = nf.text;
    let Some(idx) = m.axis_index(axis_name) else {
        let names: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
        return Err(line.at(
            nf,
            "axis",
            format!(
                "machine `{}` has no axis `{axis_name}`; expected one of {}",
                m.name,
                names.join(", ")
            ),
        ));
    };
    let a = &m.axes[idx];
    if let Some((kind, _, _)) = declared {
        if kind != a.kind {
            return Err(line.at(
                &line.f[2],
                "axis",
                format!(
                    "axis `{axis_name}` is {:?} in the machine description",
                    a.kind
                )
                .to_lowercase(),
            ));
        }
    }
    Ok((idx, (a.kind, a.travel_min, a.travel_max)))
}

/// The `key=value` options of a `table` line, each checked; which are missing is for the
/// caller to judge.
struct TableOptions<'l, 'a> {
    axis: Option<usize>,
    unit: Option<ErrorUnit>,
    /// The `file=` field and its value.
    file: Option<(&'l Field<'a>, &'a str)>,
    format: &'a str,
    interp: Interpolation,
    /// `siemens-axis=`: the control's name of the row's axis (`AX2`), which a Siemens table
    /// must read; default the axis' name here.
    siemens_axis: Option<&'a str>,
    /// `siemens-output-axis=`: the control's name of the axis the row's values correct, which
    /// a CEC table's `_OUTPUT_AXIS` must name; default the reading axis (the axis' own error).
    siemens_output_axis: Option<&'a str>,
    /// `siemens-table=`: the number of the `$AN_CEC` table to use.
    siemens_table: Option<u32>,
}

/// Reads the options of a `table` line: `axis` names a declared axis, `unit`, `format` and
/// `interpolation` are known words, and no other key appears.
fn table_options<'l, 'a>(
    line: &'l Line<'a>,
    axes: &[KinAxis],
) -> Result<TableOptions<'l, 'a>, InputError> {
    let mut o = TableOptions {
        axis: None,
        unit: None,
        file: None,
        format: "csv",
        interp: Interpolation::Linear,
        siemens_axis: None,
        siemens_output_axis: None,
        siemens_table: None,
    };
    for kv in &line.f[2..] {
        let Some((k, v)) = kv.text.split_once('=') else {
            return Err(line.at(
                kv,
                "table",
                format!("expected key=value, got `{}`", kv.text),
            ));
        };
        match k {
            "axis" => {
                let Some(idx) = axes.iter().position(|a| a.name == v) else {
                    return Err(line.at(
                        kv,
                        "axis",
                        format!("unknown axis `{v}`; declare it with an `axis` line first"),
                    ));
                };
                o.axis = Some(idx);
            }
            "unit" => {
                o.unit = Some(ErrorUnit::parse(v).ok_or_else(|| {
                    line.at(
                        kv,
                        "unit",
                        format!("expected um, mm, urad, arcsec or deg, got `{v}`"),
                    )
                })?)
            }
            "file" => o.file = Some((kv, v)),
            "format" => {
                if !matches!(v, "csv" | "linuxcnc-0" | "linuxcnc-1" | "siemens") {
                    return Err(line.at(
                        kv,
                        "format",
                        format!("expected csv, linuxcnc-0, linuxcnc-1 or siemens, got `{v}`"),
                    ));
                }
                o.format = v;
            }
            "siemens-axis" => o.siemens_axis = Some(v),
            "siemens-output-axis" => o.siemens_output_axis = Some(v),
            "siemens-table" => {
                o.siemens_table = Some(v.parse().map_err(|_| {
                    line.at(
                        kv,
                        "siemens-table",
                        format!("expected the number of an $AN_CEC table, got `{v}`"),
                    )
                })?)
            }
            "interpolation" => {
                o.interp = match v {
                    "linear" => Interpolation::Linear,
                    "monotone" => Interpolation::MonotoneCubic,
                    _ => {
                        return Err(line.at(
                            kv,
                            "interpolation",
                            format!("expected linear or monotone, got `{v}`"),
                        ))
                    }
                }
            }
            _ => {
                return Err(line.at(
                    kv,
                    k,
                    format!(
                        "unknown key `{k}`; expected axis, unit, file, format, interpolation, siemens-axis, siemens-output-axis or siemens-table"
                    ),
                ))
            }
        }
    }
    Ok(o)
}

/// Which table of a Siemens file a `table` line means.
struct SiemensPick<'a> {
    /// The control's name of the axis the table must read.
    axis: &'a str,
    /// The control's name of the axis the table's values correct (a CEC `_OUTPUT_AXIS`).
    output: &'a str,
    /// `siemens-table=`.
    number: Option<u32>,
}

/// The compensation table in `table_text`, read in `format` (a checked `format=` value). Of a
/// Siemens file, the table (or the `_DIRECTION` 1/−1 pair) that reads the row's axis
/// ([`select_siemens`]): a table declared for another input axis, or correcting another
/// output axis than `siemens-output-axis=`, is never applied.
fn read_table(
    table_path: &Path,
    table_text: &str,
    format: &str,
    wrap: Wrap,
    interp: Interpolation,
    pick: SiemensPick<'_>,
) -> Result<CompTable, InputError> {
    Ok(match format {
        "csv" => parse_csv(table_path, table_text, wrap, interp)?,
        "linuxcnc-0" | "linuxcnc-1" => {
            let ty = if format == "linuxcnc-0" {
                LinuxCncType::Positions
            } else {
                LinuxCncType::Trims
            };
            parse_linuxcnc(table_path, table_text, ty)?.to_table(interp)?
        }
        _ => {
            let all = parse_siemens(table_path, table_text, None)?;
            select_siemens(
                table_path,
                &all,
                Some(pick.axis),
                Some(pick.output),
                pick.number,
                interp,
            )?
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_kinematics::{Directions, Geometry};

    fn examples() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/kinematics")
    }

    const MACHINES: [&str; 4] = ["head-ac", "table-ac", "head-bc", "vmc-21"];

    /// A small deterministic generator (xorshift) so that the test needs no dependency.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn every_example_loads_and_transforms_both_ways() {
        for name in MACHINES {
            let dir = examples().join(name);
            let machine = crate::machine_file::load(&dir.join("machine.toml"))
                .unwrap()
                .machine;
            let with = load(&dir.join("kinematics.ktab"), Some(&machine)).unwrap();
            let without = load(&dir.join("kinematics.ktab"), None).unwrap();
            assert_eq!(with.chain.axes(), without.chain.axes(), "{name}");
            assert_eq!(
                with.machine_axis.as_deref(),
                Some(&[0, 1, 2, 3, 4][..with.chain.axes().len()])
            );
            let chain = &with.chain;
            let n = chain.axes().len();
            let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
            for i in 0..500 {
                let q: Vec<f64> = chain
                    .axes()
                    .iter()
                    .enumerate()
                    .map(|(j, a)| {
                        // Every fifth pose within 0.01° of the pole (rotary axis 3 at 0).
                        if j == 3 && i % 5 == 0 {
                            return (2.0 * rng.next() - 1.0) * 0.01;
                        }
                        let (lo, hi) = (a.travel_min.max(-100.0), a.travel_max.min(100.0));
                        let (lo, hi) = if a.kind == AxisKind::Linear {
                            (
                                a.travel_min * 0.7 + a.travel_max * 0.3,
                                a.travel_max * 0.7 + a.travel_min * 0.3,
                            )
                        } else {
                            (lo, hi)
                        };
                        lo + (hi - lo) * rng.next()
                    })
                    .collect();
                let target = chain
                    .forward(&q, 100.0, Directions(0), Geometry::Actual)
                    .unwrap();
                let prev: Vec<f64> = q.iter().map(|v| v + 0.3).collect();
                let mut out = vec![0.0; n];
                let rep = chain
                    .inverse(
                        &target,
                        100.0,
                        &prev,
                        Directions(0),
                        Geometry::Actual,
                        &mut out,
                    )
                    .unwrap_or_else(|e| panic!("{name}: {e} at {q:?}"));
                let got = chain
                    .forward(&out, 100.0, rep.directions, Geometry::Actual)
                    .unwrap();
                for k in 0..3 {
                    assert!(
                        (got.position[k] - target.position[k]).abs() < 1e-6,
                        "{name} {q:?}"
                    );
                    if n == 5 {
                        assert!(
                            (got.direction[k] - target.direction[k]).abs() < 1e-6,
                            "{name}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_head_ac_file_reads_as_written() {
        let k = load(&examples().join("head-ac/kinematics.ktab"), None).unwrap();
        assert_eq!(k.name, "head-ac");
        assert_eq!(k.tool_length_mm, 100.0);
        let rows = k.chain.rows();
        assert_eq!(
            rows[0],
            Row::Tool {
                dof: Dof::Z,
                sign: -1.0,
                offset: -150.0
            }
        );
        assert_eq!(
            rows[1],
            Row::Error {
                dof: Dof::X,
                offset: 0.0,
                table: 0
            }
        );
        assert_eq!(
            rows[3],
            Row::Axis {
                dof: Dof::A,
                axis: 3,
                sign: 1.0
            }
        );
        assert_eq!(
            rows[4],
            Row::Fixed {
                dof: Dof::X,
                value: 0.02
            }
        );
        // F_A_X(10°) = 12·sin 10° + 3·sin 40° = 2.0838 + 1.9284 = 4.0121 µm (rounded to 4 places
        // in the file).
        let t = &k.chain.tables()[0];
        assert_eq!(t.name, "F_A_X");
        let v = t
            .table
            .value(10.0, truepos_kinematics::table::Direction::Forward);
        assert!((v - 4.0121).abs() < 1e-4, "{v}");
        let t = load(&examples().join("table-ac/kinematics.ktab"), None).unwrap();
        assert_eq!(
            t.chain.rows()[6],
            Row::Axis {
                dof: Dof::A,
                axis: 3,
                sign: -1.0
            }
        );
        // The LinuxCNC and Siemens tables of the 3-axis example are read in µm.
        let v = load(&examples().join("vmc-21/kinematics.ktab"), None).unwrap();
        assert_eq!(v.chain.tables().len(), 21);
        let exx = v.chain.tables().iter().find(|t| t.name == "EXX").unwrap();
        assert!(exx.table.reverse().is_some());
    }

    fn err(text: &str) -> InputError {
        parse(Path::new("k.ktab"), text, None).unwrap_err()
    }

    #[test]
    fn malformed_files_name_line_and_column() {
        let head = "axis X linear 0 100\naxis A rotary -90 90\n";
        let e = err(&format!("{head}0 Trans Z -L -\n2 MachAxis X - -\n"));
        assert_eq!(e.position, Some((4, 1)));
        assert!(e.to_string().contains("expected row number 1"), "{e}");
        let e = err(&format!("{head}0 Trans Q 5 -\n"));
        assert_eq!(
            e.to_string(),
            "k.ktab:3:9: `Axis`: expected X, Y, Z, A, B or C, got `Q`"
        );
        let e = err(&format!("{head}0 Trans Z 5 F_NONE\n"));
        assert_eq!(e.position, Some((3, 13)));
        let e = err(&format!("{head}0 MachAxis A X -\n"));
        assert!(e.to_string().contains("axis `X` is linear"), "{e}");
        let e = err(&format!("{head}0 Trans A -L -\n"));
        assert_eq!(e.position, Some((3, 11)));
        let e = err(&format!("{head}0 Turn X 1 -\n"));
        assert!(e.to_string().contains("expected Trans or MachAxis"), "{e}");
        let e = err("axis X linear 5 1\n");
        assert_eq!(e.position, Some((1, 15)));
        let e = err("axis X\n");
        assert!(e.to_string().contains("no machine file"), "{e}");
        let e = err(&format!("{head}table T axis=Q unit=um file=t.csv\n"));
        assert_eq!(e.position, Some((3, 9)));
        let e = err(&format!("{head}table T axis=A unit=furlong file=t.csv\n"));
        assert!(e.to_string().contains("expected um, mm"), "{e}");
        let e = err(&format!(
            "{head}table T axis=A unit=um file=does-not-exist.csv\n"
        ));
        assert_eq!(e.position, Some((3, 24)));
        let e = err(&format!("{head}0 MachAxis X - -\n"));
        assert!(e.to_string().contains("axis `A` is driven by 0"), "{e}");
        let e = err(&format!("{head}speed = 3\n"));
        assert!(e.to_string().contains("unknown setting"), "{e}");
    }

    #[test]
    fn machine_file_must_agree() {
        let dir = examples().join("head-ac");
        let machine = crate::machine_file::load(&dir.join("machine.toml"))
            .unwrap()
            .machine;
        let e = parse(&dir.join("k.ktab"), "axis W\n", Some(&machine)).unwrap_err();
        assert!(e.to_string().contains("has no axis `W`"), "{e}");
        let e = parse(&dir.join("k.ktab"), "axis A linear 0 1\n", Some(&machine)).unwrap_err();
        assert!(e.to_string().contains("rotary in the machine"), "{e}");
    }
}
