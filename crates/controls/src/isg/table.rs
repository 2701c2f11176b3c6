//! ISG kernel (Beckhoff TwinCAT CNC) leadscrew error compensation lists (`kw.ssfk.*`, the
//! compensation value list of an axis), read into exactly what they say ([`IsgSsfk`]) and
//! converted to and from [`CompTable`].
//!
//! The layout relied on is ISG's public kernel documentation ("Axis compensation",
//! leadscrew error compensation, P-COMP-00001/00002 and P-COMP-00017 … 00022; the example
//! compensation value list there): lines `name value`, the header `kopf.achs_nr` (logical
//! axis number) and `kopf.log_achs_name`, the management data `kw.ssfk.unit` (1: metric, in
//! 0.1 µm), `kw.ssfk.interval` (distance between interpolation points; 0: each point's
//! position given in `kw.ssfk.table[i].setpoint`), `kw.ssfk.kw_startpos`, `kw.ssfk.kw_nr_max`
//! (number of entries), `kw.ssfk.bilateral` (1: a table per direction of travel),
//! `kw.ssfk.modulo`, and per entry `kw.ssfk.table[i].pos` (and `.neg`), the compensation value
//! Δs = actual − set-point (the documentation's example computes it so): the error, in
//! 0.1 µm. Comments are `#` lines and `/* … */` after a value. truepos writes and reads the
//! metric unit only (encoder increments need the encoder's resolution).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};

use crate::table::{ExportError, Origin};
use truepos_files::InputError;

/// A leadscrew error compensation list exactly as written (positions and values in 0.1 µm).
#[derive(Debug, Clone, PartialEq)]
pub struct IsgSsfk {
    /// `kopf.achs_nr`: the logical axis number.
    pub axis_nr: i64,
    /// `kopf.log_achs_name`, if given.
    pub axis_name: Option<String>,
    /// `kw.ssfk.interval` (0: positions in `setpoints`).
    pub interval: i64,
    /// `kw.ssfk.kw_startpos`.
    pub startpos: i64,
    /// `kw.ssfk.bilateral`.
    pub bilateral: bool,
    /// `kw.ssfk.modulo`.
    pub modulo: bool,
    /// `kw.ssfk.table[i].setpoint` (only with interval 0).
    pub setpoints: Vec<i64>,
    /// `kw.ssfk.table[i].pos`: the error moving in the positive direction (or both).
    pub pos: Vec<i64>,
    /// `kw.ssfk.table[i].neg` (only bilateral).
    pub neg: Vec<i64>,
    /// The file and the line of each entry's `pos`.
    pub origin: Origin,
}

/// 0.1 µm per mm.
const PER_MM: f64 = 10_000.0;

fn tenths(v: f64, what: &str, exact: bool) -> Result<i64, ExportError> {
    let t = v * PER_MM;
    let r = t.round();
    if !r.is_finite() || r.abs() > f64::from(i32::MAX) {
        return Err(ExportError::Isg(format!(
            "{what} {v} does not fit a 32-bit count of 0.1 µm"
        )));
    }
    if exact && (t - r).abs() > 1e-6 {
        return Err(ExportError::Isg(format!(
            "{what} {v} mm is not a whole number of 0.1 µm"
        )));
    }
    Ok(r as i64)
}

impl IsgSsfk {
    /// The list of an error table in µm over mm (or degrees) for logical axis `axis_nr`:
    /// equidistant points as `interval`, others with their set-points; a directional table
    /// bilateral. Values are rounded to 0.1 µm (at most 0.05 µm lost).
    pub fn from_table(
        table: &CompTable,
        axis_nr: i64,
        axis_name: Option<&str>,
    ) -> Result<Self, ExportError> {
        let p = table.positions();
        let pts: Vec<i64> = p
            .iter()
            .map(|&x| tenths(x, "position", true))
            .collect::<Result<_, _>>()?;
        let span = p[p.len() - 1] - p[0];
        let step = table.step(1e-9 * (1.0 + span.abs()));
        let values = |col: &[f64]| -> Result<Vec<i64>, ExportError> {
            col.iter()
                .map(|&v| tenths(v / 1000.0, "value", false))
                .collect()
        };
        let (interval, setpoints) = match step {
            Some(s) => (tenths(s, "interval", true)?, vec![]),
            None => (0, pts.clone()),
        };
        Ok(Self {
            axis_nr,
            axis_name: axis_name.map(str::to_string),
            interval,
            startpos: pts[0],
            bilateral: table.reverse().is_some(),
            modulo: table.wrap() == Wrap::Rotary,
            setpoints,
            pos: values(table.forward())?,
            neg: table.reverse().map(values).transpose()?.unwrap_or_default(),
            origin: Origin::default(),
        })
    }

    /// The error table in µm; an error names the entry's line.
    pub fn to_table(&self, interpolation: Interpolation) -> Result<CompTable, InputError> {
        let positions: Vec<f64> = if self.interval == 0 {
            self.setpoints.iter().map(|&s| s as f64 / PER_MM).collect()
        } else {
            (0..self.pos.len())
                .map(|i| (self.startpos + self.interval * i as i64) as f64 / PER_MM)
                .collect()
        };
        let um = |c: &[i64]| c.iter().map(|&v| v as f64 / 10.0).collect::<Vec<_>>();
        let wrap = if self.modulo {
            Wrap::Rotary
        } else {
            Wrap::Hold
        };
        let built = if self.bilateral {
            CompTable::directional(positions, um(&self.pos), um(&self.neg), wrap, interpolation)
        } else {
            CompTable::new(positions, um(&self.pos), wrap, interpolation)
        };
        built.map_err(|e| self.origin.table_error("kw.ssfk.table", e))
    }

    /// The list's text.
    pub fn write(&self) -> String {
        let mut out = String::from("# leadscrew error compensation (SSFK), written by truepos\n");
        let mut line = |k: &str, v: &dyn std::fmt::Display| {
            let _ = writeln!(out, "{k:<36} {v}");
        };
        line("kopf.achs_nr", &self.axis_nr);
        if let Some(n) = &self.axis_name {
            line("kopf.log_achs_name", n);
        }
        line("kw.ssfk.unit", &1);
        line("kw.ssfk.interval", &self.interval);
        line("kw.ssfk.kw_startpos", &self.startpos);
        line("kw.ssfk.kw_nr_max", &self.pos.len());
        line("kw.ssfk.bilateral", &u8::from(self.bilateral));
        line("kw.ssfk.modulo", &u8::from(self.modulo));
        for (i, s) in self.setpoints.iter().enumerate() {
            line(&format!("kw.ssfk.table[{i}].setpoint"), s);
        }
        for (i, v) in self.pos.iter().enumerate() {
            line(&format!("kw.ssfk.table[{i}].pos"), v);
        }
        for (i, v) in self.neg.iter().enumerate() {
            line(&format!("kw.ssfk.table[{i}].neg"), v);
        }
        out
    }
}

/// One value of the list: its text, line and column.
type Entry<'a> = (&'a str, usize, usize);

/// Reads a leadscrew error compensation list. Every key is known and given once, values are
/// integers, the entries are complete (0 … `kw_nr_max` − 1); errors name line and column.
pub fn parse_isg(path: &Path, text: &str) -> Result<IsgSsfk, InputError> {
    let mut scalars: BTreeMap<&str, Entry> = BTreeMap::new();
    let mut columns: BTreeMap<(&str, usize), Entry> = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        let n = i + 1;
        let code = raw.split("/*").next().unwrap_or("");
        let t = code.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let col = code.len() - code.trim_start().len() + 1;
        let mut parts = t.split_whitespace();
        let (Some(key), Some(value), None) = (parts.next(), parts.next(), parts.next()) else {
            return Err(InputError::at(
                path,
                n,
                col,
                "",
                format!("expected `name value`, got `{t}`"),
            ));
        };
        let vcol = col + t.find(value).unwrap_or(0);
        let twice = || InputError::at(path, n, col, key, "given twice");
        if let Some(rest) = key.strip_prefix("kw.ssfk.table[") {
            let (idx, field) = rest.split_once("].").unwrap_or(("", ""));
            let Ok(idx) = idx.parse::<usize>() else {
                return Err(InputError::at(
                    path,
                    n,
                    col,
                    key,
                    "expected kw.ssfk.table[i].pos, .neg or .setpoint",
                ));
            };
            let field = match field {
                "pos" => "pos",
                "neg" => "neg",
                "setpoint" => "setpoint",
                _ => {
                    return Err(InputError::at(
                        path,
                        n,
                        col,
                        key,
                        "expected kw.ssfk.table[i].pos, .neg or .setpoint",
                    ))
                }
            };
            if columns.insert((field, idx), (value, n, vcol)).is_some() {
                return Err(twice());
            }
            continue;
        }
        const KEYS: [&str; 8] = [
            "kopf.achs_nr",
            "kopf.log_achs_name",
            "kw.ssfk.unit",
            "kw.ssfk.interval",
            "kw.ssfk.kw_startpos",
            "kw.ssfk.kw_nr_max",
            "kw.ssfk.bilateral",
            "kw.ssfk.modulo",
        ];
        let Some(k) = KEYS.iter().find(|k| **k == key) else {
            return Err(InputError::at(
                path,
                n,
                col,
                key,
                format!(
                    "unknown name; expected one of {} or kw.ssfk.table[i].…",
                    KEYS.join(", ")
                ),
            ));
        };
        if scalars.insert(k, (value, n, vcol)).is_some() {
            return Err(twice());
        }
    }
    assemble(path, &scalars, &columns)
}

/// The list from its values: each an integer where one is expected, the entries complete.
fn assemble(
    path: &Path,
    scalars: &BTreeMap<&str, Entry>,
    columns: &BTreeMap<(&str, usize), Entry>,
) -> Result<IsgSsfk, InputError> {
    let int = |(v, l, c): Entry, key: &str| -> Result<i64, InputError> {
        v.parse::<i64>()
            .ok()
            .filter(|x| x.unsigned_abs() <= i32::MAX as u64)
            .ok_or_else(|| {
                InputError::at(
                    path,
                    l,
                    c,
                    key,
                    format!("expected a 32-bit integer, got `{v}`"),
                )
            })
    };
    let get = |key: &str| -> Result<i64, InputError> {
        let e = scalars
            .get(key)
            .ok_or_else(|| InputError::file(path, format!("no {key}; expected one")))?;
        int(*e, key)
    };
    let flag = |key: &str| -> Result<bool, InputError> {
        match scalars.get(key) {
            None => Ok(false),
            Some(&(v, l, c)) => match v {
                "0" => Ok(false),
                "1" => Ok(true),
                _ => Err(InputError::at(
                    path,
                    l,
                    c,
                    key,
                    format!("expected 0 or 1, got `{v}`"),
                )),
            },
        }
    };
    if let Some(&(v, l, c)) = scalars.get("kw.ssfk.unit") {
        if v != "1" {
            return Err(InputError::at(path, l, c, "kw.ssfk.unit", format!("unit {v}: truepos reads metric lists (1, in 0.1 µm) only; encoder increments need the encoder's resolution")));
        }
    }
    let count = get("kw.ssfk.kw_nr_max")?;
    let bilateral = flag("kw.ssfk.bilateral")?;
    let interval = get("kw.ssfk.interval")?;
    if !(2..=100_000).contains(&count) {
        let (_, l, c) = scalars["kw.ssfk.kw_nr_max"];
        return Err(InputError::at(
            path,
            l,
            c,
            "kw.ssfk.kw_nr_max",
            format!("{count} entries; expected 2 to 100000"),
        ));
    }
    let col = |field: &str| -> Result<(Vec<i64>, Vec<usize>), InputError> {
        let mut v = Vec::new();
        let mut lines = Vec::new();
        for i in 0..count as usize {
            let key = format!("kw.ssfk.table[{i}].{field}");
            let e = columns.get(&(field, i)).ok_or_else(|| {
                InputError::file(
                    path,
                    format!(
                        "no {key}; expected entries 0 to {} (kw.ssfk.kw_nr_max {count})",
                        count - 1
                    ),
                )
            })?;
            v.push(int(*e, &key)?);
            lines.push(e.1);
        }
        Ok(v).map(|v| (v, lines))
    };
    let extra = columns.keys().find(|(f, i)| {
        *i >= count as usize || (*f == "neg" && !bilateral) || (*f == "setpoint" && interval != 0)
    });
    if let Some(k) = extra {
        let (_, l, c) = columns[k];
        return Err(InputError::at(path, l, c, format!("kw.ssfk.table[{}].{}", k.1, k.0), "entry beyond kw_nr_max, a .neg of a unilateral list or a .setpoint with an interval; expected none"));
    }
    let (pos, lines) = col("pos")?;
    let neg = if bilateral { col("neg")?.0 } else { vec![] };
    let setpoints = if interval == 0 {
        col("setpoint")?.0
    } else {
        vec![]
    };
    Ok(IsgSsfk {
        axis_nr: get("kopf.achs_nr")?,
        axis_name: scalars.get("kopf.log_achs_name").map(|e| e.0.to_string()),
        interval,
        startpos: if interval == 0 {
            setpoints[0]
        } else {
            get("kw.ssfk.kw_startpos")?
        },
        bilateral,
        modulo: flag("kw.ssfk.modulo")?,
        setpoints,
        pos,
        neg,
        origin: Origin::read(path, lines),
    })
}
