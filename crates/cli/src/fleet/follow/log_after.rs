//! Reads of the service's log after a cursor (a rowid), so that a round of `fleet follow`
//! reads what the log gained rather than all of it — through a read-only SQLite connection,
//! as the runtime's readers (`truepos_runtime::log`) do, while the service writes the log.

use std::path::Path;

use rusqlite::types::Value;
use rusqlite::{Connection, OpenFlags};
use truepos_runtime::log::{LoggedEvent, ProbeRow, ProbeTable};

use crate::error::CliError;

fn failed(path: &Path) -> impl Fn(rusqlite::Error) -> CliError + '_ {
    move |e| CliError::refused(format!("{}: {e}", path.display()))
}

/// The log opened read-only; a log in WAL mode the reader cannot make a `-shm` file for, with
/// no `-wal` file (every commit in the database file), is read as immutable.
fn open(path: &Path) -> Result<Connection, CliError> {
    let first = |c: &Connection| c.query_row("SELECT count(*) FROM sqlite_master", [], |_| Ok(()));
    let conn = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY)
        .and_then(|c| first(&c).map(|()| c));
    let mut wal = path.as_os_str().to_owned();
    wal.push("-wal");
    match conn {
        Ok(c) => Ok(c),
        Err(e) if !Path::new(&wal).exists() => {
            let mut uri = String::from("file:");
            for b in path.as_os_str().as_encoded_bytes() {
                match b {
                    b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' | b'/' | b'-' | b'_' | b'.' | b'~' => {
                        uri.push(char::from(*b))
                    }
                    _ => uri.push_str(&format!("%{b:02X}")),
                }
            }
            uri.push_str("?immutable=1");
            let c = Connection::open_with_flags(
                &uri,
                OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_URI,
            )
            .map_err(|_| failed(path)(e))?;
            first(&c).map_err(failed(path))?;
            Ok(c)
        }
        Err(e) => Err(failed(path)(e)),
    }
}

fn has_table(c: &Connection, path: &Path, name: &str) -> Result<bool, CliError> {
    c.query_row(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
        [name],
        |r| r.get::<_, i64>(0),
    )
    .map(|n| n > 0)
    .map_err(failed(path))
}

/// The largest rowid of a table of the log (0: no log, no table or no rows).
fn last_row(path: &Path, table: &str) -> Result<i64, CliError> {
    if !path.exists() {
        return Ok(0);
    }
    let c = open(path)?;
    if !has_table(&c, path, table)? {
        return Ok(0);
    }
    c.query_row(&format!("SELECT max(rowid) FROM {table}"), [], |r| {
        r.get::<_, Option<i64>>(0)
    })
    .map(|n| n.unwrap_or(0))
    .map_err(failed(path))
}

/// The largest rowid of the log's probes.
pub fn last_probe_row(path: &Path) -> Result<i64, CliError> {
    last_row(path, "probes")
}

/// The largest rowid of the log's events.
pub fn last_event_row(path: &Path) -> Result<i64, CliError> {
    last_row(path, "events")
}

/// The log's probes rows from rowid `from` on (that row included), in the layout of
/// `truepos_runtime::log::read_probes`.
pub fn probes_from(path: &Path, from: i64) -> Result<ProbeTable, CliError> {
    let c = open(path)?;
    if !has_table(&c, path, "probes")? {
        return Ok(ProbeTable {
            columns: Vec::new(),
            rows: Vec::new(),
        });
    }
    let mut st = c
        .prepare("SELECT rowid, * FROM probes WHERE rowid >= ?1 ORDER BY rowid")
        .map_err(failed(path))?;
    let names: Vec<String> = st.column_names().iter().map(|s| s.to_string()).collect();
    // rowid, time_s, status, reason, state, then the numbers.
    const FIRST_NUMBER: usize = 5;
    if names.get(1..FIRST_NUMBER)
        != Some(&["time_s", "status", "reason", "state"].map(String::from)[..])
    {
        return Err(CliError::refused(format!(
            "{}: the probes table has the columns [{}]; expected time_s, status, reason, state first",
            path.display(),
            names[1..].join(", ")
        )));
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
        .map_err(failed(path))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(failed(path))?;
    Ok(ProbeTable {
        columns: names[FIRST_NUMBER..].to_vec(),
        rows,
    })
}

/// The log's events after rowid `after`, oldest first, each with its rowid.
pub fn events_after(path: &Path, after: i64) -> Result<Vec<(i64, LoggedEvent)>, CliError> {
    let c = open(path)?;
    if !has_table(&c, path, "events")? {
        return Ok(Vec::new());
    }
    let mut st = c
        .prepare(
            "SELECT rowid, time_s, kind, subject, detail FROM events WHERE rowid > ?1 ORDER BY rowid",
        )
        .map_err(failed(path))?;
    let rows = st
        .query_map([after], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                LoggedEvent {
                    time_s: r.get::<_, Option<f64>>(1)?.unwrap_or(f64::NAN),
                    kind: r.get(2)?,
                    subject: r.get(3)?,
                    detail: r.get(4)?,
                },
            ))
        })
        .map_err(failed(path))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(failed(path))?;
    Ok(rows)
}
