//! Reading a log for the live view while the service writes it: the cycles of a time window
//! downsampled in SQLite with min/max per bucket (peaks survive any downsampling), and the
//! events after a given row.

use std::path::Path;

use rusqlite::Connection;

use super::read::{has_table, open_read, LoggedEvent};
use super::{err, quote, LogError};

/// The cycles of a window, min/max per bucket.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct History {
    /// Service time of the window's start and end in s (NaN for an empty log).
    pub start_s: f64,
    /// End of the window: the latest logged cycle.
    pub end_s: f64,
    /// Width of a bucket in s.
    pub bucket_s: f64,
    /// The numeric columns of the `cycles` table (not `time_s`, not `state`), in table order.
    pub columns: Vec<String>,
    /// Buckets in time order; empty buckets are left out.
    pub buckets: Vec<Bucket>,
}

/// One bucket of [`History`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Bucket {
    /// Service time of its first and last cycle, s.
    pub t: [f64; 2],
    /// Cycles in it.
    pub rows: u64,
    /// Cycles in it whose state was not `active`.
    pub inactive: u64,
    /// Per column, the least value (`None`: no value).
    pub min: Vec<Option<f64>>,
    /// Per column, the largest value.
    pub max: Vec<Option<f64>>,
}

/// The last row of each table, as a reader's starting point: rows at or before belong to the
/// runs before (a log is appended to).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rows {
    /// Last rowid of `cycles` (0: none).
    pub cycles: i64,
    /// Last rowid of `events` (0: none).
    pub events: i64,
    /// Last rowid of `probes` (0: none, or a log without probes).
    pub probes: i64,
}

/// The last rows of a log now (zeros for a log not created yet).
pub fn last_rows(path: &Path) -> Rows {
    let Ok(conn) = open_read(path) else {
        return Rows::default();
    };
    let last = |table: &str| {
        conn.query_row(
            &format!("SELECT coalesce(max(rowid), 0) FROM {table}"),
            [],
            |r| r.get::<_, i64>(0),
        )
        .unwrap_or(0)
    };
    Rows {
        cycles: last("cycles"),
        events: last("events"),
        probes: last("probes"),
    }
}

/// The cycles logged after row `after` within the last `window_s` seconds of service time
/// (`None`: all of them), in at most `buckets` buckets with each column's min and max.
pub fn read_history(
    path: &Path,
    after: i64,
    window_s: Option<f64>,
    buckets: usize,
) -> Result<History, LogError> {
    let conn = open_read(path)?;
    let mut st = conn
        .prepare("SELECT name FROM pragma_table_info('cycles')")
        .map_err(err(path))?;
    let columns: Vec<String> = st
        .query_map([], |r| r.get::<_, String>(0))
        .map_err(err(path))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(err(path))?
        .into_iter()
        .filter(|c| c != "time_s" && c != "state")
        .collect();
    let (first, last): (Option<f64>, Option<f64>) = conn
        .query_row(
            "SELECT min(time_s), max(time_s) FROM cycles WHERE rowid > ?1",
            [after],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .map_err(err(path))?;
    let (Some(first), Some(end_s)) = (first, last) else {
        return Ok(History {
            start_s: f64::NAN,
            end_s: f64::NAN,
            bucket_s: f64::NAN,
            columns,
            buckets: Vec::new(),
        });
    };
    let start_s = match window_s {
        Some(w) if w.is_finite() && w > 0.0 => (end_s - w).max(first),
        _ => first,
    };
    let n = buckets.clamp(1, 100_000) as f64;
    let bucket_s = ((end_s - start_s) / n).max(1e-6);
    let aggregates: Vec<String> = columns
        .iter()
        .map(|c| format!("min({0}), max({0})", quote(c)))
        .collect();
    let sql = format!(
        "SELECT min(CAST((time_s - ?2) / ?3 AS INTEGER), ?4) AS b, min(time_s), max(time_s), count(*), \
         sum(state IS NOT 'active'){} FROM cycles WHERE rowid > ?1 AND time_s >= ?2 \
         GROUP BY b ORDER BY b",
        aggregates
            .iter()
            .map(|a| format!(", {a}"))
            .collect::<String>()
    );
    let mut st = conn.prepare(&sql).map_err(err(path))?;
    let width = columns.len();
    let rows = st
        // The last row (at the window's end) belongs to the last bucket, not a bucket of its own.
        .query_map(
            rusqlite::params![after, start_s, bucket_s, n as i64 - 1],
            |r| {
                let value = |i: usize| r.get::<_, Option<f64>>(i);
                let mut min = Vec::with_capacity(width);
                let mut max = Vec::with_capacity(width);
                for c in 0..width {
                    min.push(value(5 + 2 * c)?);
                    max.push(value(6 + 2 * c)?);
                }
                Ok(Bucket {
                    t: [value(1)?.unwrap_or(f64::NAN), value(2)?.unwrap_or(f64::NAN)],
                    rows: r.get::<_, i64>(3)?.max(0) as u64,
                    inactive: r.get::<_, Option<i64>>(4)?.unwrap_or(0).max(0) as u64,
                    min,
                    max,
                })
            },
        )
        .map_err(err(path))?;
    let buckets = rows.collect::<Result<Vec<_>, _>>().map_err(err(path))?;
    Ok(History {
        start_s,
        end_s,
        bucket_s,
        columns,
        buckets,
    })
}

/// At most `limit` events logged after row `after`, oldest first, each with its row.
pub fn read_events_after(
    path: &Path,
    after: i64,
    limit: usize,
) -> Result<Vec<(i64, LoggedEvent)>, LogError> {
    let limit = i64::try_from(limit).unwrap_or(i64::MAX);
    events_after(&open_read(path)?, path, after, limit)
}

/// Every event logged after row `after`, oldest first, each with its row: what a reader that
/// keeps a cursor (`truepos fleet follow`) reads each round. A file without an `events` table
/// has none (where [`read_events_after`] fails).
pub fn read_all_events_after(path: &Path, after: i64) -> Result<Vec<(i64, LoggedEvent)>, LogError> {
    let conn = open_read(path)?;
    if !has_table(&conn, path, "events")? {
        return Ok(Vec::new());
    }
    events_after(&conn, path, after, i64::MAX)
}

fn events_after(
    conn: &Connection,
    path: &Path,
    after: i64,
    limit: i64,
) -> Result<Vec<(i64, LoggedEvent)>, LogError> {
    let mut st = conn
        .prepare(
            "SELECT rowid, time_s, kind, subject, detail FROM events WHERE rowid > ?1 \
             ORDER BY rowid LIMIT ?2",
        )
        .map_err(err(path))?;
    let rows = st
        .query_map(rusqlite::params![after, limit], |r| {
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
        .map_err(err(path))?;
    rows.collect::<Result<Vec<_>, _>>().map_err(err(path))
}
