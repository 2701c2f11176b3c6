//! The log: an embedded SQLite database (WAL mode) of inputs, outputs and events, written by its
//! own thread from the lock-free queues of the cycle.
//!
//! Durability: the logger commits one transaction every `commit_every` (250 ms by default).
//! With WAL and `synchronous = NORMAL`, a committed transaction survives the process being
//! killed at any moment (only a power loss may take the last commits), and SQLite's journal
//! keeps the file consistent; so a SIGKILL loses at most the records of the last interval.
//!
//! The `cycles` table has one column per channel, named as in a run CSV (`X_mm`, sensor ids,
//! operating ids) plus `<axis>_offset_um`, so `truepos log --csv` gives a run `truepos fit` reads.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_queue::ArrayQueue;
use rusqlite::{params_from_iter, Connection};
use truepos_io::cycles::position_column;
use truepos_io::machine_file::MachineFile;

use crate::events::{Event, EventKind, EventQueue};
use crate::replay::state_name;
use crate::service::{CycleRecord, MAX_LOG_OPERATING, MAX_LOG_TEMPERATURES, MAX_PATHS};

/// A log that cannot be opened, written or read.
#[derive(Debug)]
pub struct LogError {
    /// The database file.
    pub file: PathBuf,
    /// What went wrong.
    pub message: String,
}

impl std::fmt::Display for LogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.file.display(), self.message)
    }
}

impl std::error::Error for LogError {}

fn err(file: &Path) -> impl Fn(rusqlite::Error) -> LogError + '_ {
    move |e| LogError {
        file: file.to_path_buf(),
        message: e.to_string(),
    }
}

/// Names of everything a log refers to by index.
#[derive(Debug, Clone)]
struct Names {
    axes: Vec<String>,
    sensors: Vec<String>,
    sources: Vec<String>,
    sinks: Vec<String>,
    models: Vec<String>,
}

/// The columns of the `cycles` table, in order.
fn cycle_columns(machine: &MachineFile, paths: usize) -> Vec<String> {
    let m = &machine.machine;
    let mut cols = vec!["time_s".to_string(), "state".to_string()];
    cols.extend((1..=paths).map(|p| format!("model_path{p}")));
    cols.extend((0..m.axes.len()).map(|a| position_column(m, a)));
    cols.extend(
        m.temperatures
            .iter()
            .take(MAX_LOG_TEMPERATURES)
            .map(|t| t.id.clone()),
    );
    cols.extend(
        m.operating
            .iter()
            .take(MAX_LOG_OPERATING)
            .map(|o| o.id.clone()),
    );
    cols.extend(m.axes.iter().map(|a| format!("{}_offset_um", a.name)));
    cols
}

fn quote(name: &str) -> String {
    format!("\"{}\"", name.replace('"', "\"\""))
}

/// The logger thread; stop it with [`Logger::stop`] (dropping it stops it too).
pub struct Logger {
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<(), LogError>>>,
}

/// What the logger is told at start.
pub struct LogSetup<'a> {
    /// Database file (created if missing; an existing log is appended to).
    pub path: &'a Path,
    /// The machine.
    pub machine: &'a MachineFile,
    /// Names of the models of the set, in set order.
    pub models: Vec<String>,
    /// Names of the sources, in service order.
    pub sources: Vec<String>,
    /// Names of the sinks, in service order.
    pub sinks: Vec<String>,
    /// Number of paths.
    pub paths: usize,
    /// Interval between commits.
    pub commit_every: Duration,
}

impl Logger {
    /// Opens (or creates) the log and starts the thread that drains the queues into it.
    pub fn start(
        setup: LogSetup<'_>,
        events: Arc<EventQueue>,
        records: Arc<ArrayQueue<CycleRecord>>,
    ) -> Result<Self, LogError> {
        let path = setup.path.to_path_buf();
        let conn = Connection::open(&path).map_err(err(&path))?;
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(err(&path))?;
        conn.pragma_update(None, "synchronous", "NORMAL")
            .map_err(err(&path))?;
        let m = &setup.machine.machine;
        let paths = setup.paths.min(MAX_PATHS);
        let columns = cycle_columns(setup.machine, paths);
        let defs: Vec<String> = columns
            .iter()
            .map(|c| {
                let ty = if c == "state" { "TEXT" } else { "REAL" };
                format!("{} {ty}", quote(c))
            })
            .collect();
        conn.execute_batch(&format!(
            "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS events (time_s REAL NOT NULL, kind TEXT NOT NULL,
                 subject TEXT NOT NULL, detail TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS cycles ({});",
            defs.join(", ")
        ))
        .map_err(err(&path))?;
        let names = Names {
            axes: m.axes.iter().map(|a| a.name.clone()).collect(),
            sensors: m.temperatures.iter().map(|t| t.id.clone()).collect(),
            sources: setup.sources,
            sinks: setup.sinks,
            models: setup.models,
        };
        let meta = serde_json::json!({
            "machine": m.name,
            "axes": names.axes,
            "sensors": names.sensors,
            "models": names.models,
            "sources": names.sources,
            "sinks": names.sinks,
        });
        conn.execute(
            "INSERT OR REPLACE INTO meta (key, value) VALUES ('service', ?1)",
            [meta.to_string()],
        )
        .map_err(err(&path))?;
        let insert = format!(
            "INSERT INTO cycles ({}) VALUES ({})",
            columns
                .iter()
                .map(|c| quote(c))
                .collect::<Vec<_>>()
                .join(", "),
            vec!["?"; columns.len()].join(", ")
        );
        let layout = Layout {
            axes: m.axes.len(),
            temperatures: m.temperatures.len().min(MAX_LOG_TEMPERATURES),
            operating: m.operating.len().min(MAX_LOG_OPERATING),
            paths,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let stop_thread = Arc::clone(&stop);
        let every = setup.commit_every;
        let handle = std::thread::Builder::new()
            .name("truepos-log".into())
            .spawn(move || {
                let mut writer = Writer {
                    conn,
                    path,
                    insert,
                    names,
                    layout,
                    dropped_seen: 0,
                    last_time: 0.0,
                };
                loop {
                    let stopping = stop_thread.load(Ordering::Acquire);
                    writer.drain(&events, &records)?;
                    if stopping {
                        return Ok(());
                    }
                    std::thread::sleep(every);
                }
            })
            .map_err(|e| LogError {
                file: setup.path.to_path_buf(),
                message: format!("cannot start the log thread: {e}"),
            })?;
        Ok(Self {
            stop,
            handle: Some(handle),
        })
    }

    /// Writes what is still queued and stops the thread.
    pub fn stop(mut self) -> Result<(), LogError> {
        self.finish()
    }

    fn finish(&mut self) -> Result<(), LogError> {
        self.stop.store(true, Ordering::Release);
        match self.handle.take() {
            Some(h) => h.join().unwrap_or_else(|_| {
                Err(LogError {
                    file: PathBuf::new(),
                    message: "the log thread panicked".into(),
                })
            }),
            None => Ok(()),
        }
    }
}

impl Drop for Logger {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

struct Layout {
    axes: usize,
    temperatures: usize,
    operating: usize,
    paths: usize,
}

struct Writer {
    conn: Connection,
    path: PathBuf,
    insert: String,
    names: Names,
    layout: Layout,
    dropped_seen: u64,
    last_time: f64,
}

/// A float for SQLite: NaN and ∞ become NULL.
fn real(v: f64) -> rusqlite::types::Value {
    if v.is_finite() {
        rusqlite::types::Value::Real(v)
    } else {
        rusqlite::types::Value::Null
    }
}

impl Writer {
    fn drain(
        &mut self,
        events: &EventQueue,
        records: &ArrayQueue<CycleRecord>,
    ) -> Result<(), LogError> {
        let tx = self.conn.transaction().map_err(err(&self.path))?;
        {
            let mut insert = tx.prepare_cached(&self.insert).map_err(err(&self.path))?;
            while let Some(r) = records.pop() {
                self.last_time = r.time_s;
                let l = &self.layout;
                let mut values: Vec<rusqlite::types::Value> = Vec::new();
                values.push(real(r.time_s));
                values.push(rusqlite::types::Value::Text(state_name(r.state).into()));
                for m in &r.model_per_path[..l.paths] {
                    values.push(if *m < 0 {
                        rusqlite::types::Value::Null
                    } else {
                        rusqlite::types::Value::Integer(i64::from(*m))
                    });
                }
                values.extend(r.positions[..l.axes].iter().map(|&v| real(v)));
                values.extend(r.temperatures_c[..l.temperatures].iter().map(|&v| real(v)));
                values.extend(r.operating[..l.operating].iter().map(|&v| real(v)));
                values.extend(r.offsets_um[..l.axes].iter().map(|&v| real(v)));
                insert
                    .execute(params_from_iter(values))
                    .map_err(err(&self.path))?;
            }
            let mut ev = tx
                .prepare_cached(
                    "INSERT INTO events (time_s, kind, subject, detail) VALUES (?1, ?2, ?3, ?4)",
                )
                .map_err(err(&self.path))?;
            while let Some(e) = events.pop() {
                self.last_time = self.last_time.max(e.time_s);
                let (kind, subject, detail) = describe(&e, &self.names);
                ev.execute(rusqlite::params![e.time_s, kind, subject, detail])
                    .map_err(err(&self.path))?;
            }
            let dropped = events.dropped();
            if dropped > self.dropped_seen {
                ev.execute(rusqlite::params![
                    self.last_time,
                    "events-dropped",
                    "log",
                    format!(
                        "{} events were dropped: the log fell behind",
                        dropped - self.dropped_seen
                    )
                ])
                .map_err(err(&self.path))?;
                self.dropped_seen = dropped;
            }
        }
        tx.commit().map_err(err(&self.path))
    }
}

/// (kind, subject, detail) of an event, with names instead of indices.
fn describe(e: &Event, n: &Names) -> (&'static str, String, String) {
    let name = |list: &[String], i: usize| list.get(i).cloned().unwrap_or_else(|| format!("#{i}"));
    match e.kind {
        EventKind::SensorFault { channel, fault } => {
            ("sensor-fault", name(&n.sensors, channel), fault.to_string())
        }
        EventKind::SensorRecovered { channel } => {
            ("sensor-recovered", name(&n.sensors, channel), String::new())
        }
        EventKind::PositionFault { axis } => (
            "position-fault",
            name(&n.axes, axis),
            "position not a number or not current".into(),
        ),
        EventKind::PositionRecovered => ("position-recovered", "axes".into(), String::new()),
        EventKind::ModelSelected { path, model } => (
            "model-selected",
            format!("path {path}"),
            name(&n.models, model),
        ),
        EventKind::ModelSubstituted { path, from, to } => (
            "model-substituted",
            format!("path {path}"),
            format!(
                "{} → {} (a sensor of the first is bad)",
                name(&n.models, from),
                name(&n.models, to)
            ),
        ),
        EventKind::NoModel { path, target } => (
            "no-model",
            format!("path {path}"),
            format!(
                "no model has the axis-combination index [{}, {}, {}]",
                target[0], target[1], target[2]
            ),
        ),
        EventKind::Holding { path } => (
            "holding",
            format!("path {path}"),
            "no valid model: holding the last compensation and ramping it to zero".into(),
        ),
        EventKind::AxisSwitch => ("axis-switch", "control".into(), String::new()),
        EventKind::Enabled(on) => (
            if on { "enabled" } else { "disabled" },
            "compensation".into(),
            String::new(),
        ),
        EventKind::Clamped { axis, rate } => (
            "clamped",
            name(&n.axes, axis),
            if rate {
                "rate limit".into()
            } else {
                "magnitude limit".into()
            },
        ),
        EventKind::ClampReleased { axis } => ("clamp-released", name(&n.axes, axis), String::new()),
        EventKind::SourceLost { source, reason } => {
            ("source-lost", name(&n.sources, source), reason.to_string())
        }
        EventKind::SourceBack { source } => {
            ("source-back", name(&n.sources, source), String::new())
        }
        EventKind::SinkFailed { sink } => ("sink-failed", name(&n.sinks, sink), String::new()),
        EventKind::Overrun { late_us } => ("overrun", "cycle".into(), format!("{late_us} µs late")),
    }
}

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

fn open_read(path: &Path) -> Result<Connection, LogError> {
    if !path.exists() {
        return Err(LogError {
            file: path.to_path_buf(),
            message: "no such log".into(),
        });
    }
    Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(err(path))
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
