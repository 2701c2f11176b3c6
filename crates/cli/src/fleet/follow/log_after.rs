//! Reads of the service's log after a cursor (a rowid), so that a round of `fleet follow`
//! reads what the log gained rather than all of it — through a read-only SQLite connection,
//! as the runtime's readers (`truepos_runtime::log`) do, while the service writes the log.

use std::path::Path;

use rusqlite::{Connection, OpenFlags};
use truepos_runtime::log::{self, LoggedEvent, ProbeTable};

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

/// The log's probes rows from rowid `from` on (that row included): the runtime's reader.
pub fn probes_from(path: &Path, from: i64) -> Result<ProbeTable, CliError> {
    log::read_probes_from(path, from).map_err(CliError::from)
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
