//! Reading a log back (also while the service writes it): events, the service's meta, the
//! cycles, SQLite's own consistency check.

use std::path::Path;

use rusqlite::Connection;

use super::{err, LogError};

/// One logged event.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LoggedEvent {
    /// Service time in s.
    pub time_s: f64,
    /// Kind (`sensor-fault`, `model-selected`, …).
    pub kind: String,
    /// What it concerns (a sensor id, an axis, a path).
    pub subject: String,
    /// Details.
    pub detail: String,
}

pub(crate) fn open_read(path: &Path) -> Result<Connection, LogError> {
    if let Err(e) = truepos_files::read::open(path, truepos_files::LOG) {
        return Err(LogError {
            file: path.to_path_buf(),
            message: if e.is_not_found() {
                "no such log".into()
            } else {
                match e.source {
                    Some(why) => format!("{}: {why}", e.message),
                    None => e.message,
                }
            },
        });
    }
    let conn = Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .and_then(|c| probe(&c).map(|()| c));
    match conn {
        Ok(c) => Ok(c),
        // A WAL log opened read-only needs its `-shm` file, which SQLite cannot create in a
        // directory the reader may not write (an operator's account reading the service's
        // log). Without a `-wal` file every commit is in the database file itself, so reading
        // it as immutable shows all of it; with one, the error stands rather than showing an
        // old state.
        Err(e) if !wal_file(path).exists() => open_immutable(path).map_err(|_| err(path)(e)),
        Err(e) => Err(err(path)(e)),
    }
}

/// Whether the log has a table of that name (one written before a table was logged has not).
pub(crate) fn has_table(c: &Connection, path: &Path, name: &str) -> Result<bool, LogError> {
    c.query_row(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
        [name],
        |r| r.get::<_, i64>(0),
    )
    .map(|n| n > 0)
    .map_err(err(path))
}

/// A first read, so that a database that cannot be read fails here (SQLite opens lazily).
fn probe(c: &Connection) -> rusqlite::Result<()> {
    c.query_row("SELECT count(*) FROM sqlite_master", [], |_| Ok(()))
}

fn wal_file(path: &Path) -> std::path::PathBuf {
    let mut p = path.as_os_str().to_owned();
    p.push("-wal");
    p.into()
}

/// Opens the log with SQLite's `immutable=1`: no lock, no `-shm` file, nothing written.
pub(crate) fn open_immutable(path: &Path) -> Result<Connection, LogError> {
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
    let flags = rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_URI;
    let c = Connection::open_with_flags(&uri, flags).map_err(err(path))?;
    probe(&c).map_err(err(path))?;
    Ok(c)
}

/// Reads the events of a log (also while the service writes it).
pub fn read_events(path: &Path) -> Result<Vec<LoggedEvent>, LogError> {
    let conn = open_read(path)?;
    let mut st = conn
        .prepare("SELECT time_s, kind, subject, detail FROM events ORDER BY rowid")
        .map_err(err(path))?;
    let rows = st
        .query_map([], |r| {
            Ok(LoggedEvent {
                time_s: r.get::<_, Option<f64>>(0)?.unwrap_or(f64::NAN),
                kind: r.get(1)?,
                subject: r.get(2)?,
                detail: r.get(3)?,
            })
        })
        .map_err(err(path))?;
    rows.collect::<Result<Vec<_>, _>>().map_err(err(path))
}

/// The `meta` a service wrote at start (machine, axes, sensors, models, sources, sinks), or
/// `None` for a log without one.
pub fn read_meta(path: &Path) -> Result<Option<serde_json::Value>, LogError> {
    let conn = open_read(path)?;
    let text: Option<String> = conn
        .query_row("SELECT value FROM meta WHERE key = 'service'", [], |r| {
            r.get(0)
        })
        .ok();
    Ok(text.and_then(|t| serde_json::from_str(&t).ok()))
}

/// The cycles of a log as (column names, rows); NULL becomes NaN, the state column its text.
pub type CycleTable = (Vec<String>, Vec<Vec<String>>);

/// Reads the `cycles` table (optionally only the last `last` rows) as text cells.
pub fn read_cycles(path: &Path, last: Option<usize>) -> Result<CycleTable, LogError> {
    let conn = open_read(path)?;
    let sql = match last {
        Some(n) => format!(
            "SELECT * FROM (SELECT rowid AS r, * FROM cycles ORDER BY rowid DESC LIMIT {n}) ORDER BY r"
        ),
        None => "SELECT 0 AS r, * FROM cycles ORDER BY rowid".to_string(),
    };
    let mut st = conn.prepare(&sql).map_err(err(path))?;
    let names: Vec<String> = st
        .column_names()
        .iter()
        .skip(1)
        .map(|s| s.to_string())
        .collect();
    let width = names.len();
    let rows = st
        .query_map([], |r| {
            (1..=width)
                .map(|i| {
                    let v: rusqlite::types::Value = r.get(i)?;
                    Ok(match v {
                        rusqlite::types::Value::Null => String::new(),
                        rusqlite::types::Value::Integer(i) => i.to_string(),
                        rusqlite::types::Value::Real(f) => f.to_string(),
                        rusqlite::types::Value::Text(t) => t,
                        rusqlite::types::Value::Blob(_) => String::new(),
                    })
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .map_err(err(path))?;
    let rows = rows.collect::<Result<Vec<_>, _>>().map_err(err(path))?;
    Ok((names, rows))
}

/// Runs SQLite's own consistency check; `Ok("ok")` for a sound file.
pub fn integrity_check(path: &Path) -> Result<String, LogError> {
    let conn = open_read(path)?;
    conn.query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .map_err(err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The read-only fallback itself, forced: root (CI, the service's account) can write any
    /// directory, so a chmod cannot make the first open fail here; the cli's red-team test
    /// `a_log_in_a_read_only_directory_is_read` mounts a read-only directory where it can.
    #[test]
    fn a_log_opened_immutable_reads_every_commit() {
        let d = std::env::temp_dir().join(format!("truepos-log-immutable-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let path = d.join("a b%.db");
        let c = Connection::open(&path).unwrap();
        c.execute_batch("PRAGMA journal_mode=WAL; CREATE TABLE t(x); INSERT INTO t VALUES (7);")
            .unwrap();
        drop(c);
        assert!(!wal_file(&path).exists());
        let r = open_immutable(&path).unwrap();
        let x: i64 = r.query_row("SELECT x FROM t", [], |r| r.get(0)).unwrap();
        assert_eq!(x, 7);
        drop(r);
        assert!(!wal_file(&path).exists());
        let _ = std::fs::remove_dir_all(&d);
    }
}
