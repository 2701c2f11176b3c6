//! The `probes` table of the log: one row per probe event the service saw, accepted or
//! rejected, with the inputs of its cycle (docs/formats.md). `truepos reidentify --log` reads
//! the accepted rows back ([`read_probes`]).

use std::path::Path;

use rusqlite::types::Value;

use super::read::has_table;
use super::{err, open_read, quote, real, LogError};
use crate::config::MachineConfig;
use crate::probe::ProbeRecord;
use crate::replay::state_name;
use crate::service::MAX_PATHS;

/// Column names of an axis' probe values: where it touched, the measured error, the error the
/// model in effect predicted there.
pub fn axis_columns(axis: &str) -> [String; 3] {
    let a = axis.to_lowercase();
    [
        format!("probe_{a}_mm"),
        format!("probe_d{a}_um"),
        format!("predicted_d{a}_um"),
    ]
}

/// The columns of the `probes` table, in order: `time_s`, `status` (`accepted`/`rejected`),
/// `reason`, `state`, `model_path<p>`, the probe columns of every axis, then the cycle's axis
/// positions, temperatures and operating state named as in the `cycles` table.
pub(super) fn columns(machine: &MachineConfig, paths: usize) -> Vec<String> {
    let m = &machine.machine;
    let mut cols: Vec<String> = ["time_s", "status", "reason", "state"]
        .map(String::from)
        .to_vec();
    cols.extend((1..=paths.min(MAX_PATHS)).map(|p| format!("model_path{p}")));
    cols.extend(m.axes.iter().flat_map(|a| axis_columns(&a.name)));
    cols.extend(super::input_columns(machine));
    cols
}

/// `CREATE TABLE IF NOT EXISTS probes (…)` and the insert statement for these columns.
pub(super) fn statements(columns: &[String]) -> (String, String) {
    let text = ["status", "reason", "state"];
    let defs: Vec<String> = columns
        .iter()
        .map(|c| {
            let ty = if text.contains(&c.as_str()) {
                "TEXT"
            } else {
                "REAL"
            };
            format!("{} {ty}", quote(c))
        })
        .collect();
    let names: Vec<String> = columns.iter().map(|c| quote(c)).collect();
    (
        format!("CREATE TABLE IF NOT EXISTS probes ({});", defs.join(", ")),
        format!(
            "INSERT INTO probes ({}) VALUES ({})",
            names.join(", "),
            vec!["?"; columns.len()].join(", ")
        ),
    )
}

/// The values of one record in column order; `axes`, `temperatures`, `operating`, `paths` are
/// the counts the table has.
pub(super) fn values(
    r: &ProbeRecord,
    axes: usize,
    temperatures: usize,
    operating: usize,
    paths: usize,
) -> Vec<Value> {
    let mut v = vec![
        real(r.time_s),
        Value::Text(
            if r.rejected.is_empty() {
                "accepted"
            } else {
                "rejected"
            }
            .into(),
        ),
        Value::Text(r.rejected.as_str().into()),
        Value::Text(state_name(r.state).into()),
    ];
    v.extend(r.model_per_path[..paths].iter().map(|&m| {
        if m < 0 {
            Value::Null
        } else {
            Value::Integer(i64::from(m))
        }
    }));
    for a in 0..axes {
        let measured = r.probe.measured[a];
        v.push(real(r.probe.position_mm[a]));
        // An axis not measured has no error; a measured NaN is NULL too, its reason says so.
        v.push(if measured {
            real(r.probe.deviation_um[a])
        } else {
            Value::Null
        });
        v.push(real(r.predicted_um[a]));
    }
    v.extend(r.positions[..axes].iter().map(|&x| real(x)));
    v.extend(r.temperatures_c[..temperatures].iter().map(|&x| real(x)));
    v.extend(r.operating[..operating].iter().map(|&x| real(x)));
    v
}

/// The probe events of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeTable {
    /// Names of the numeric columns, in the order of [`ProbeRow::values`] (everything after
    /// `state`: `model_path<p>`, probe columns, positions, temperatures, operating state).
    pub columns: Vec<String>,
    /// The rows in the order they were written.
    pub rows: Vec<ProbeRow>,
}

/// One row of the `probes` table.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeRow {
    /// SQLite row id (for messages: `probes row 12`).
    pub row: i64,
    /// Service time in s (NaN if NULL).
    pub time_s: f64,
    /// Whether the service accepted the event.
    pub accepted: bool,
    /// Why it was rejected (empty if accepted).
    pub reason: String,
    /// The numeric columns, `None` where NULL.
    pub values: Vec<Option<f64>>,
}

/// Reads the `probes` table of a log (also while the service writes it). A log written before
/// probes were logged has none: an empty table.
pub fn read_probes(path: &Path) -> Result<ProbeTable, LogError> {
    read_probes_from(path, 0)
}

/// [`read_probes`] from rowid `from` on (that row included): what a reader that keeps a
/// cursor (`truepos fleet follow`) reads each round, rather than the whole table.
pub fn read_probes_from(path: &Path, from: i64) -> Result<ProbeTable, LogError> {
    let conn = open_read(path)?;
    if !has_table(&conn, path, "probes")? {
        return Ok(ProbeTable {
            columns: Vec::new(),
            rows: Vec::new(),
        });
    }
    let mut st = conn
        .prepare("SELECT rowid, * FROM probes WHERE rowid >= ?1 ORDER BY rowid")
        .map_err(err(path))?;
    let names: Vec<String> = st.column_names().iter().map(|s| s.to_string()).collect();
    // rowid, time_s, status, reason, state, then the numbers.
    const FIRST_NUMBER: usize = 5;
    if names.get(1..FIRST_NUMBER)
        != Some(&["time_s", "status", "reason", "state"].map(String::from)[..])
    {
        return Err(LogError {
            file: path.to_path_buf(),
            message: format!(
                "the probes table has the columns [{}]; expected time_s, status, reason, state first",
                names[1..].join(", ")
            ),
        });
    }
    let width = names.len();
    let rows = st
        .query_map([from], |r| {
            let number = |i: usize| -> rusqlite::Result<Option<f64>> {
                Ok(match r.get::<_, Value>(i)? {
                    Value::Real(f) => Some(f),
                    Value::Integer(n) => Some(n as f64),
                    _ => None,
                })
            };
            Ok(ProbeRow {
                row: r.get(0)?,
                time_s: number(1)?.unwrap_or(f64::NAN),
                accepted: r.get::<_, Option<String>>(2)?.as_deref() == Some("accepted"),
                reason: r.get::<_, Option<String>>(3)?.unwrap_or_default(),
                values: (FIRST_NUMBER..width)
                    .map(number)
                    .collect::<rusqlite::Result<_>>()?,
            })
        })
        .map_err(err(path))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(err(path))?;
    Ok(ProbeTable {
        columns: names[FIRST_NUMBER..].to_vec(),
        rows,
    })
}
