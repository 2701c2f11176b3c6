//! The service's SQLite log as the store the publisher forwards from: a read-only connection
//! to the log's own tables (`meta`, `cycles`, `events`, `probes`), read after a cursor of row
//! ids and grouped into the units that become messages — one second's aggregates, one event,
//! or one accepted probe event.

use std::path::{Path, PathBuf};
use std::time::Duration;

use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};

/// Where forwarding stands: the last row of each table that is covered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Rows {
    /// Last covered rowid of `cycles` (0: none).
    pub cycles: i64,
    /// Last covered rowid of `events` (0: none).
    pub events: i64,
    /// Last covered rowid of `probes` (0: none; -1: not known, a cursor file written before
    /// probes were forwarded — the publisher starts such a cursor's probes where a new broker's
    /// would start).
    #[serde(default = "unknown_row")]
    pub probes: i64,
}

fn unknown_row() -> i64 {
    -1
}

/// What the service wrote about itself in the log's `meta` table.
#[derive(Debug, Clone, PartialEq)]
pub struct Meta {
    /// The machine's name.
    pub machine: String,
    /// Clock time of the service's time 0 (latest run), s since the Unix epoch.
    pub started_unix_s: f64,
    /// The model set's names, in order.
    pub models: Vec<String>,
}

/// One aggregated column: min, mean and max over a second's cycles (`None`: no value in it).
pub type Stat = Option<(f64, f64, f64)>;

/// One second of cycles.
#[derive(Debug, Clone, PartialEq)]
pub struct Second {
    /// Service time of the second's start, s (a whole number).
    pub second: f64,
    /// Its last row.
    pub last_row: i64,
    /// Cycles logged in it.
    pub cycles: u32,
    /// Of those, cycles whose state was `active` (compensation applied).
    pub active: u32,
    /// Per aggregated column ([`LogReader::columns`]), min/mean/max.
    pub stats: Vec<Stat>,
    /// The service's time went back before it: a new run appended to the log.
    pub new_run: bool,
}

/// One logged event.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// Its rowid.
    pub row: i64,
    /// Service time, s.
    pub time_s: f64,
    /// Kind, subject and detail, as the log has them.
    pub kind: String,
    /// What it concerns.
    pub subject: String,
    /// Details.
    pub detail: String,
}

/// One accepted probe event of the log's `probes` table.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Its rowid.
    pub row: i64,
    /// Service time, s.
    pub time_s: f64,
    /// The compensation state of its cycle.
    pub state: String,
    /// Per probe column ([`LogReader::probe_columns`]) its value (`None`: NULL, e.g. an axis
    /// not measured).
    pub values: Vec<Option<f64>>,
}

/// A unit of forwarding: what one NDATA message carries.
#[derive(Debug, Clone, PartialEq)]
pub enum Unit {
    /// A second's aggregates.
    Second(Second),
    /// An event.
    Event(Event),
    /// An accepted probe event.
    Probe(Probe),
}

impl Unit {
    /// The cursor once this unit is acknowledged, from the one before.
    pub fn after(&self, before: Rows) -> Rows {
        match self {
            Unit::Second(s) => Rows {
                cycles: s.last_row,
                ..before
            },
            Unit::Event(e) => Rows {
                events: e.row,
                ..before
            },
            Unit::Probe(p) => Rows {
                probes: p.row,
                ..before
            },
        }
    }
}

/// Rows read from `cycles` at once: at the default 10 records/s, 2000 s of data.
const CYCLE_BATCH: i64 = 20_000;

/// The log, opened read-only.
pub struct LogReader {
    conn: Connection,
    path: PathBuf,
    /// The aggregated columns of `cycles`: every numeric column but `time_s`, the paths'
    /// model numbers and the axes' targets, in table order.
    columns: Vec<String>,
    /// Their indices in `SELECT rowid, *`.
    indices: Vec<usize>,
    state_index: Option<usize>,
    /// The forwarded columns of `probes`: every numeric column after `state` but the paths'
    /// model numbers (probe, predicted, positions, temperatures, operating state); empty for a
    /// log without the table.
    probe_columns: Vec<String>,
    /// Their indices in `SELECT rowid, *` of `probes`, and those of `time_s`, `status`, `state`.
    probe_indices: Vec<usize>,
    probe_fixed: Option<(usize, usize, usize)>,
}

fn err(path: &Path) -> impl Fn(rusqlite::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

fn real(v: ValueRef<'_>) -> Option<f64> {
    // The logger writes REAL or NULL; anything else (a hand-edited log) counts as no value.
    match v {
        ValueRef::Real(x) if x.is_finite() => Some(x),
        ValueRef::Integer(i) => Some(i as f64),
        _ => None,
    }
}

fn text(v: ValueRef<'_>) -> String {
    match v {
        ValueRef::Text(t) => String::from_utf8_lossy(t).into_owned(),
        ValueRef::Integer(i) => i.to_string(),
        ValueRef::Real(x) => x.to_string(),
        _ => String::new(),
    }
}

/// The last rows of a log now; zeros when it does not exist yet or cannot be read.
pub fn last_rows(path: &Path) -> Rows {
    LogReader::open(path)
        .ok()
        .and_then(|r| r.last_rows().ok())
        .unwrap_or_default()
}

impl LogReader {
    /// Opens a log the service has created.
    pub fn open(path: &Path) -> Result<Self, String> {
        if !path.is_file() {
            return Err(format!("{}: no such log", path.display()));
        }
        // Read-only: the logger thread is the log's one writer.
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(err(path))?;
        conn.busy_timeout(Duration::from_secs(2))
            .map_err(err(path))?;
        let names: Vec<String> = conn
            .prepare("SELECT name FROM pragma_table_info('cycles')")
            .and_then(|mut s| {
                s.query_map([], |r| r.get::<_, String>(0))?
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(err(path))?;
        if names.is_empty() {
            return Err(format!(
                "{}: not a truepos log (no cycles table)",
                path.display()
            ));
        }
        let mut columns = Vec::new();
        let mut indices = Vec::new();
        let mut state_index = None;
        for (i, n) in names.iter().enumerate() {
            // `rowid` comes first in the query, so a column's index is one more than its position.
            match n.as_str() {
                "time_s" => {}
                "state" => state_index = Some(i + 1),
                _ if n.starts_with("model_path") => {}
                // The offsets say what reached the axes; a target differs from them only in a
                // blend, a hold or a clamp, which the fleet receives as events.
                _ if n.ends_with("_target_um") => {}
                _ => {
                    columns.push(n.clone());
                    indices.push(i + 1);
                }
            }
        }
        if names.first().map(String::as_str) != Some("time_s") {
            return Err(format!(
                "{}: not a truepos log (cycles without time_s first)",
                path.display()
            ));
        }
        let probe_names: Vec<String> = conn
            .prepare("SELECT name FROM pragma_table_info('probes')")
            .and_then(|mut s| {
                s.query_map([], |r| r.get::<_, String>(0))?
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(err(path))?;
        let (mut probe_columns, mut probe_indices) = (Vec::new(), Vec::new());
        let (mut time_i, mut status_i, mut pstate_i) = (None, None, None);
        for (i, n) in probe_names.iter().enumerate() {
            match n.as_str() {
                "time_s" => time_i = Some(i + 1),
                "status" => status_i = Some(i + 1),
                "state" => pstate_i = Some(i + 1),
                "reason" => {}
                _ if n.starts_with("model_path") => {}
                _ => {
                    probe_columns.push(n.clone());
                    probe_indices.push(i + 1);
                }
            }
        }
        let probe_fixed = match (time_i, status_i, pstate_i) {
            (Some(t), Some(s), Some(st)) => Some((t, s, st)),
            _ => {
                probe_columns.clear();
                probe_indices.clear();
                None
            }
        };
        Ok(LogReader {
            conn,
            path: path.to_path_buf(),
            columns,
            indices,
            state_index,
            probe_columns,
            probe_indices,
            probe_fixed,
        })
    }

    /// The forwarded columns of `probes`, in table order (empty: the log has no probe table).
    pub fn probe_columns(&self) -> &[String] {
        &self.probe_columns
    }

    /// Up to `limit` accepted probe events after row `after`, in order (a rejected one is
    /// never forwarded: it is in the log for the record, and nothing fits or judges on it).
    pub fn probes(&self, after: i64, limit: usize) -> Result<Vec<Probe>, String> {
        let Some((ti, si, sti)) = self.probe_fixed else {
            return Ok(Vec::new());
        };
        let mut stmt = self
            .conn
            .prepare_cached(
                "SELECT rowid, * FROM probes WHERE rowid > ?1 AND status = 'accepted' \
                 ORDER BY rowid LIMIT ?2",
            )
            .map_err(err(&self.path))?;
        let mut rows = stmt
            .query(rusqlite::params![after, limit as i64])
            .map_err(err(&self.path))?;
        let mut out = Vec::new();
        while let Some(r) = rows.next().map_err(err(&self.path))? {
            let g = |i: usize| r.get_ref(i).map_err(err(&self.path));
            debug_assert!(matches!(g(si)?, ValueRef::Text(b"accepted")));
            let mut values = Vec::with_capacity(self.probe_indices.len());
            for &i in &self.probe_indices {
                values.push(real(g(i)?));
            }
            out.push(Probe {
                row: r.get(0).map_err(err(&self.path))?,
                time_s: real(g(ti)?).unwrap_or(f64::NAN),
                state: text(g(sti)?),
                values,
            });
        }
        Ok(out)
    }

    /// The aggregated columns of `cycles`, in table order.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// The service's `meta` row.
    pub fn meta(&self) -> Result<Meta, String> {
        let json: String = self
            .conn
            .query_row("SELECT value FROM meta WHERE key = 'service'", [], |r| {
                r.get(0)
            })
            .map_err(err(&self.path))?;
        let v: serde_json::Value = serde_json::from_str(&json)
            .map_err(|e| format!("{}: meta: {e}", self.path.display()))?;
        Ok(Meta {
            machine: v["machine"].as_str().unwrap_or("").to_string(),
            started_unix_s: v["started_unix_s"].as_f64().unwrap_or(f64::NAN),
            models: v["models"]
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(|m| m.as_str().map(String::from))
                        .collect()
                })
                .unwrap_or_default(),
        })
    }

    /// The last rows of each table now.
    pub fn last_rows(&self) -> Result<Rows, String> {
        let last = |t: &str| {
            self.conn
                .query_row(
                    &format!("SELECT coalesce(max(rowid), 0) FROM {t}"),
                    [],
                    |r| r.get::<_, i64>(0),
                )
                .map_err(err(&self.path))
        };
        Ok(Rows {
            cycles: last("cycles")?,
            events: last("events")?,
            probes: if self.probe_fixed.is_some() {
                last("probes")?
            } else {
                0
            },
        })
    }

    /// Up to `limit` complete seconds of cycles after `after` (a second is complete once a
    /// later row exists; with `finished`, the log will not grow and the last second counts
    /// too). Reads only the rows those seconds need, so a publisher that may send one message
    /// reads one second's rows, however long the backlog.
    pub fn seconds(&self, after: i64, finished: bool, limit: usize) -> Result<Vec<Second>, String> {
        let mut stmt = self
            .conn
            .prepare_cached("SELECT rowid, * FROM cycles WHERE rowid > ?1 ORDER BY rowid LIMIT ?2")
            .map_err(err(&self.path))?;
        let mut rows = stmt
            .query(rusqlite::params![after, CYCLE_BATCH])
            .map_err(err(&self.path))?;
        let mut out: Vec<Second> = Vec::new();
        let mut open: Option<(Second, Vec<Acc>)> = None;
        // The row before the first one read: a run boundary right at the cursor is seen too.
        let mut previous_t = self
            .conn
            .query_row(
                "SELECT time_s FROM cycles WHERE rowid <= ?1 ORDER BY rowid DESC LIMIT 1",
                [after],
                |r| Ok(real(r.get_ref(0)?)),
            )
            .ok()
            .flatten()
            .unwrap_or(f64::NEG_INFINITY);
        let mut n = 0i64;
        let mut limited = false;
        let width = self.columns.len();
        while let Some(r) = rows.next().map_err(err(&self.path))? {
            n += 1;
            let row: i64 = r.get(0).map_err(err(&self.path))?;
            let Some(t) = real(r.get_ref(1).map_err(err(&self.path))?) else {
                continue; // a row without a time cannot be placed in a second
            };
            let second = t.floor();
            let starts = match &open {
                Some((s, _)) => s.second != second,
                None => true,
            };
            if starts {
                if let Some(done) = open.take() {
                    out.push(close(done));
                }
                if out.len() >= limit {
                    limited = true;
                    break;
                }
                let s = Second {
                    second,
                    last_row: row,
                    cycles: 0,
                    active: 0,
                    stats: Vec::new(),
                    new_run: t < previous_t,
                };
                open = Some((s, vec![(f64::INFINITY, 0.0, f64::NEG_INFINITY, 0); width]));
            }
            previous_t = t;
            let (s, acc) = open.as_mut().expect("opened above");
            s.last_row = row;
            s.cycles += 1;
            if let Some(i) = self.state_index {
                if matches!(r.get_ref(i), Ok(ValueRef::Text(b"active"))) {
                    s.active += 1;
                }
            }
            for (a, &i) in acc.iter_mut().zip(&self.indices) {
                if let Some(v) = real(r.get_ref(i).map_err(err(&self.path))?) {
                    a.0 = a.0.min(v);
                    a.1 += v;
                    a.2 = a.2.max(v);
                    a.3 += 1;
                }
            }
        }
        // The last second may still be growing, unless the log is final and was read whole.
        if let Some(done) = open {
            if finished && n < CYCLE_BATCH && !limited && out.len() < limit {
                out.push(close(done));
            }
        }
        Ok(out)
    }

    /// Up to `limit` events after row `after`, in order.
    pub fn events(&self, after: i64, limit: usize) -> Result<Vec<Event>, String> {
        let mut stmt = self
            .conn
            .prepare_cached(
                "SELECT rowid, time_s, kind, subject, detail FROM events WHERE rowid > ?1 \
                 ORDER BY rowid LIMIT ?2",
            )
            .map_err(err(&self.path))?;
        let rows = stmt
            .query_map(rusqlite::params![after, limit as i64], |r| {
                Ok(Event {
                    row: r.get(0)?,
                    time_s: real(r.get_ref(1)?).unwrap_or(f64::NAN),
                    kind: text(r.get_ref(2)?),
                    subject: text(r.get_ref(3)?),
                    detail: text(r.get_ref(4)?),
                })
            })
            .map_err(err(&self.path))?;
        rows.collect::<Result<Vec<_>, _>>().map_err(err(&self.path))
    }

    /// Up to `limit` units after `cursor`, seconds, events and probe events merged in time
    /// order (an event or a probe goes before the first second that ends after it; an event
    /// before a probe of the same time).
    pub fn units(&self, cursor: Rows, limit: usize, finished: bool) -> Result<Vec<Unit>, String> {
        let seconds = self.seconds(cursor.cycles, finished, limit)?;
        let events = self.events(cursor.events, limit)?;
        let probes = self.probes(cursor.probes.max(0), limit)?;
        let mut out = Vec::with_capacity(limit.min(seconds.len() + events.len() + probes.len()));
        let (mut s, mut e, mut p) = (
            seconds.into_iter().peekable(),
            events.into_iter().peekable(),
            probes.into_iter().peekable(),
        );
        // A time without a value (NaN) goes first rather than never.
        let key = |t: f64| if t.is_nan() { f64::NEG_INFINITY } else { t };
        while out.len() < limit {
            // The earliest of the next event and the next probe (the event on a tie).
            let loose = match (e.peek(), p.peek()) {
                (Some(ev), Some(pr)) => Some((
                    key(ev.time_s) <= key(pr.time_s),
                    key(ev.time_s).min(key(pr.time_s)),
                )),
                (Some(ev), None) => Some((true, key(ev.time_s))),
                (None, Some(pr)) => Some((false, key(pr.time_s))),
                (None, None) => None,
            };
            let take_loose = match (s.peek(), loose) {
                (Some(sec), Some((_, t))) => t < sec.second + 1.0,
                (None, Some(_)) => true,
                (Some(_), None) => false,
                (None, None) => break,
            };
            if !take_loose {
                out.extend(s.next().map(Unit::Second));
            } else if loose.is_some_and(|(event, _)| event) {
                out.extend(e.next().map(Unit::Event));
            } else {
                out.extend(p.next().map(Unit::Probe));
            }
        }
        Ok(out)
    }
}

/// A column's running least value, sum, largest value and count within a second.
type Acc = (f64, f64, f64, u32);

fn close((mut s, acc): (Second, Vec<Acc>)) -> Second {
    s.stats = acc
        .into_iter()
        .map(|(lo, sum, hi, n)| (n > 0).then(|| (lo, sum / f64::from(n), hi)))
        .collect();
    s
}
