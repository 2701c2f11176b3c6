//! The kinematics table file (`*.ktab`): seed B's Fig. 2c as text, plus the axes and the
//! compensation tables it references.
//!
//! ```text
//! # seed B's head: A swivels in a fork on C; the head rides on Z, Y, X
//! name = head-ac
//! tool_length = 100                      # mm, used when no tool length is given
//! axis X linear -1000 1000               # set-point order; travel in mm / degrees
//! axis A rotary -110 110                 # (travel may be left out when a machine file is given)
//! table F_A_X axis=A unit=um file=tables/F_A_X.csv        # format=csv|linuxcnc-0|linuxcnc-1|siemens
//! table F_A_B axis=A unit=urad file=tables/F_A_B.csv interpolation=monotone
//! # Nr  Key       Axis  Delta      KompFile
//!   0   Trans     Z     -L-150     -        # tool length L enters here
//!   1   Trans     X     0          F_A_X    # error row: Delta + table value
//!   2   Trans     B     0          F_A_B
//!   3   MachAxis  A     -          -        # Delta of a MachAxis row: the axis name (- = the letter)
//! ```
//!
//! Rows run from the TCP towards the workpiece (see [`truepos_model::kinematics`] for the
//! convention). A `MachAxis` whose axis letter carries a minus (`-C`) moves the workpiece.
//! Table files are read relative to the kinematics file. Every error names the file, line,
//! column and what was expected.

use std::path::{Path, PathBuf};

use truepos_model::kinematics::{Chain, Dof, ErrorTable, ErrorUnit, KinAxis, Row};
use truepos_model::table::{Interpolation, Wrap};
use truepos_model::{AxisKind, Machine};

use crate::comp_table::{parse_csv, parse_linuxcnc, parse_siemens, LinuxCncType};
use crate::error::{read_text, InputError};

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
    let text = read_text(path)?;
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
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut name = String::new();
    let mut tool_length_mm = 0.0;
    let mut axes: Vec<KinAxis> = Vec::new();
    let mut machine_axis: Vec<usize> = Vec::new();
    let mut tables: Vec<ErrorTable> = Vec::new();
    let mut rows: Vec<Row> = Vec::new();
    let mut row_lines: Vec<usize> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let ln = i + 1;
        let line = raw.split('#').next().unwrap_or("");
        let f = split_fields(line);
        if f.is_empty() {
            continue;
        }
        let at = |field: &Field<'_>, key: &str, msg: String| {
            InputError::at(path, ln, field.col, key, msg)
        };
        if let Some((key, value)) = line.split_once('=').filter(|_| f[0].text != "table") {
            let key = key.trim();
            let value = value.trim();
            match key {
                "name" => name = value.to_string(),
                "tool_length" => {
                    let vf = Field {
                        col: raw
                            .find('=')
                            .map_or(1, |c| raw[..c + 1].chars().count() + 1),
                        text: value,
                    };
                    tool_length_mm = number(path, ln, &vf, "tool_length")?;
                }
                _ => {
                    return Err(at(
                        &f[0],
                        key,
                        format!("unknown setting `{key}`; expected name or tool_length"),
                    ))
                }
            }
            continue;
        }
        match f[0].text {
            "axis" => {
                let Some(nf) = f.get(1) else {
                    return Err(at(
                        &f[0],
                        "axis",
                        "expected `axis NAME [linear|rotary MIN MAX]`".into(),
                    ));
                };
                let axis_name = nf.text;
                if axes.iter().any(|a| a.name == axis_name) {
                    return Err(at(nf, "axis", format!("axis `{axis_name}` declared twice")));
                }
                let declared = if f.len() >= 5 {
                    let kind = match f[2].text {
                        "linear" => AxisKind::Linear,
                        "rotary" => AxisKind::Rotary,
                        other => {
                            return Err(at(
                                &f[2],
                                "axis",
                                format!("expected linear or rotary, got `{other}`"),
                            ))
                        }
                    };
                    let lo = number(path, ln, &f[3], "axis travel")?;
                    let hi = number(path, ln, &f[4], "axis travel")?;
                    if hi <= lo {
                        return Err(at(
                            &f[3],
                            "axis travel",
                            format!("expected MIN < MAX, got {lo} {hi}"),
                        ));
                    }
                    Some((kind, lo, hi))
                } else if f.len() == 2 {
                    None
                } else {
                    return Err(at(
                        &f[0],
                        "axis",
                        "expected `axis NAME` or `axis NAME linear|rotary MIN MAX`".into(),
                    ));
                };
                let from_machine = match machine {
                    Some(m) => {
                        let Some(idx) = m.axis_index(axis_name) else {
                            let names: Vec<&str> = m.axes.iter().map(|a| a.name.as_str()).collect();
                            return Err(at(
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
                                return Err(at(
                                    &f[2],
                                    "axis",
                                    format!(
                                        "axis `{axis_name}` is {:?} in the machine description",
                                        a.kind
                                    )
                                    .to_lowercase(),
                                ));
                            }
                        }
                        machine_axis.push(idx);
                        Some((a.kind, a.travel_min, a.travel_max))
                    }
                    None => None,
                };
                let Some((kind, lo, hi)) = from_machine.or(declared) else {
                    return Err(at(
                        nf,
                        "axis",
                        format!("axis `{axis_name}` needs `linear|rotary MIN MAX` when no machine file is given"),
                    ));
                };
                axes.push(KinAxis {
                    name: axis_name.to_string(),
                    kind,
                    travel_min: lo,
                    travel_max: hi,
                });
            }
            "table" => {
                let Some(nf) = f.get(1) else {
                    return Err(at(
                        &f[0],
                        "table",
                        "expected `table NAME axis=… unit=… file=…`".into(),
                    ));
                };
                let (mut axis, mut unit, mut file, mut format, mut interp) =
                    (None, None, None, "csv", Interpolation::Linear);
                for kv in &f[2..] {
                    let Some((k, v)) = kv.text.split_once('=') else {
                        return Err(at(
                            kv,
                            "table",
                            format!("expected key=value, got `{}`", kv.text),
                        ));
                    };
                    match k {
                        "axis" => {
                            let Some(idx) = axes.iter().position(|a| a.name == v) else {
                                return Err(at(
                                    kv,
                                    "axis",
                                    format!("unknown axis `{v}`; declare it with an `axis` line first"),
                                ));
                            };
                            axis = Some(idx);
                        }
                        "unit" => {
                            unit = Some(ErrorUnit::parse(v).ok_or_else(|| {
                                at(kv, "unit", format!("expected um, mm, urad, arcsec or deg, got `{v}`"))
                            })?)
                        }
                        "file" => file = Some((kv, v)),
                        "format" => {
                            if !matches!(v, "csv" | "linuxcnc-0" | "linuxcnc-1" | "siemens") {
                                return Err(at(
                                    kv,
                                    "format",
                                    format!("expected csv, linuxcnc-0, linuxcnc-1 or siemens, got `{v}`"),
                                ));
                            }
                            format = v;
                        }
                        "interpolation" => {
                            interp = match v {
                                "linear" => Interpolation::Linear,
                                "monotone" => Interpolation::MonotoneCubic,
                                _ => {
                                    return Err(at(
                                        kv,
                                        "interpolation",
                                        format!("expected linear or monotone, got `{v}`"),
                                    ))
                                }
                            }
                        }
                        _ => {
                            return Err(at(
                                kv,
                                k,
                                format!("unknown key `{k}`; expected axis, unit, file, format or interpolation"),
                            ))
                        }
                    }
                }
                let (Some(axis), Some(unit), Some((file_field, file))) = (axis, unit, file) else {
                    return Err(at(nf, "table", "expected axis=…, unit=… and file=…".into()));
                };
                if tables.iter().any(|t| t.name == nf.text) {
                    return Err(at(
                        nf,
                        "table",
                        format!("table `{}` declared twice", nf.text),
                    ));
                }
                let wrap = match axes[axis].kind {
                    AxisKind::Linear => Wrap::Hold,
                    AxisKind::Rotary => Wrap::Rotary,
                };
                let table_path: PathBuf = dir.join(file);
                let table_text = read_text(&table_path)
                    .map_err(|e| at(file_field, "file", format!("table `{}`: {}", nf.text, e)))?;
                let built = match format {
                    "csv" => parse_csv(&table_path, &table_text, wrap, interp)?,
                    "linuxcnc-0" | "linuxcnc-1" => {
                        let ty = if format == "linuxcnc-0" {
                            LinuxCncType::Positions
                        } else {
                            LinuxCncType::Trims
                        };
                        parse_linuxcnc(&table_path, &table_text, ty)?
                            .to_table(interp)
                            .map_err(|e| InputError::file(&table_path, e))?
                    }
                    _ => {
                        let mut all = parse_siemens(&table_path, &table_text, None)?;
                        if all.len() != 1 {
                            return Err(InputError::file(
                                &table_path,
                                format!(
                                    "{} tables; a kinematics row references exactly one",
                                    all.len()
                                ),
                            ));
                        }
                        all.remove(0)
                            .to_table(interp)
                            .map_err(|e| InputError::file(&table_path, e))?
                    }
                };
                if built.wrap() != wrap {
                    return Err(at(
                        nf,
                        "table",
                        "a modulo (rotary) table on a linear axis or the other way round".into(),
                    ));
                }
                if format != "csv" && unit != ErrorUnit::Micrometre {
                    return Err(at(
                        nf,
                        "unit",
                        "LinuxCNC and Siemens tables hold lengths in mm, read as µm: expected unit=um".into(),
                    ));
                }
                tables.push(ErrorTable {
                    name: nf.text.to_string(),
                    axis,
                    unit,
                    table: built,
                });
            }
            nr => {
                if nr.parse::<usize>().ok() != Some(rows.len()) {
                    return Err(at(
                        &f[0],
                        "Nr",
                        format!(
                            "expected row number {} (rows count from 0 without gaps) or a setting, `axis` or `table` line, got `{nr}`",
                            rows.len()
                        ),
                    ));
                }
                if f.len() != 5 {
                    return Err(at(
                        &f[0],
                        "",
                        format!(
                            "expected 5 columns `Nr Key Axis Delta KompFile`, got {}",
                            f.len()
                        ),
                    ));
                }
                let (key, axis_f, delta, komp) = (&f[1], &f[2], &f[3], &f[4]);
                let (neg, letter) = match axis_f.text.strip_prefix('-') {
                    Some(l) => (true, l),
                    None => (false, axis_f.text),
                };
                let Some(dof) = Dof::parse(letter) else {
                    return Err(at(
                        axis_f,
                        "Axis",
                        format!("expected X, Y, Z, A, B or C, got `{}`", axis_f.text),
                    ));
                };
                let row = match key.text {
                    "Trans" => {
                        if neg {
                            return Err(at(
                                axis_f,
                                "Axis",
                                "a Trans row takes no sign on its axis; put the sign on Delta"
                                    .into(),
                            ));
                        }
                        if komp.text != "-" {
                            let Some(t) = tables.iter().position(|t| t.name == komp.text) else {
                                return Err(at(
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
                                number(path, ln, delta, "Delta")?
                            };
                            if tables[t].unit.is_angle() != dof.is_rotation() {
                                return Err(at(
                                    komp,
                                    "KompFile",
                                    format!(
                                        "table `{}` is in {}, which does not fit direction {}",
                                        komp.text,
                                        tables[t].unit.name(),
                                        dof.name()
                                    ),
                                ));
                            }
                            Row::Error {
                                dof,
                                offset,
                                table: t,
                            }
                        } else if let Some((sign, offset)) = tool_expression(delta.text) {
                            if dof.is_rotation() {
                                return Err(at(
                                    delta,
                                    "Delta",
                                    "the tool length L can only enter a translation (X, Y, Z)"
                                        .into(),
                                ));
                            }
                            Row::Tool { dof, sign, offset }
                        } else {
                            Row::Fixed {
                                dof,
                                value: number(path, ln, delta, "Delta")?,
                            }
                        }
                    }
                    "MachAxis" => {
                        let axis_name = if delta.text == "-" {
                            letter
                        } else {
                            delta.text
                        };
                        let Some(axis) = axes.iter().position(|a| a.name == axis_name) else {
                            return Err(at(
                                if delta.text == "-" { axis_f } else { delta },
                                "Axis",
                                format!("unknown machine axis `{axis_name}`; declare it with an `axis` line first"),
                            ));
                        };
                        if (axes[axis].kind == AxisKind::Rotary) != dof.is_rotation() {
                            return Err(at(
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
                            return Err(at(
                                komp,
                                "KompFile",
                                "a MachAxis row takes no table; put error rows next to it".into(),
                            ));
                        }
                        Row::Axis {
                            dof,
                            axis,
                            sign: if neg { -1.0 } else { 1.0 },
                        }
                    }
                    other => {
                        return Err(at(
                            key,
                            "Key",
                            format!("expected Trans or MachAxis, got `{other}`"),
                        ))
                    }
                };
                rows.push(row);
                row_lines.push(ln);
            }
        }
    }
    if rows.is_empty() {
        return Err(InputError::file(
            path,
            "no rows; expected `0 Trans …` lines",
        ));
    }
    let chain = Chain::new(axes, tables, rows).map_err(|e| {
        use truepos_model::kinematics::ChainError as E;
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
        name,
        tool_length_mm,
        chain,
        machine_axis: machine.map(|_| machine_axis),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_model::kinematics::{Directions, Geometry};

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
    fn seed_b_rows_read_as_written() {
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
            .value(10.0, truepos_model::table::Direction::Forward);
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
