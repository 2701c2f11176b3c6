//! The log: an embedded SQLite database (WAL mode) of inputs, outputs and events, written by its
//! own thread from the lock-free queues of the cycle.
//!
//! Durability: the logger commits one transaction every `commit_every` ([`COMMIT_EVERY`], 250 ms,
//! for every service the [`crate::host::ServiceHost`] starts).
//! With WAL and `synchronous = NORMAL`, a committed transaction survives the process being
//! killed at any moment (only a power loss may take the last commits), and SQLite's journal
//! keeps the file consistent; so a SIGKILL loses at most the records of the last interval.
//!
//! Failures: a write that fails (a full disk, an I/O error) leaves what was drained in a bounded
//! buffer of the thread; the thread retries with a backoff (250 ms doubling up to
//! [`MAX_BACKOFF`]) and, when a write succeeds again, writes the buffer, a `log-failed` event
//! (the reason, at the service time it happened) and a `log-resumed` event counting what did
//! not fit in the buffer. Meanwhile [`Logger::health`] shows the failure; compensation never
//! waits for the log.
//!
//! A log belongs to one machine: [`Logger::start`] refuses a file whose `meta` names another
//! machine, or whose `cycles` table has other columns.
//!
//! The `cycles` table has one column per channel, named as in a run CSV (`X_mm`, sensor ids,
//! operating ids) plus `<axis>_offset_um`, so `truepos log --csv` gives a run `truepos fit` reads.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_queue::ArrayQueue;
use rusqlite::{params_from_iter, Connection};

mod history;
mod probes;
mod read;

pub use history::{
    last_rows, read_all_events_after, read_events_after, read_history, Bucket, History, Rows,
};
pub use probes::{
    axis_columns as probe_axis_columns, read_probes, read_probes_from, ProbeRow, ProbeTable,
};
use read::open_read;
pub use read::{integrity_check, read_cycles, read_events, read_meta, CycleTable, LoggedEvent};

use crate::config::MachineConfig;
use crate::events::{Event, EventKind, EventQueue};
use crate::probe::ProbeRecord;
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

pub(crate) fn err(file: &Path) -> impl Fn(rusqlite::Error) -> LogError + '_ {
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
    operating: Vec<String>,
    sources: Vec<String>,
    sinks: Vec<String>,
    models: Vec<String>,
}

/// The columns of the `cycles` table, in order.
fn cycle_columns(machine: &MachineConfig, paths: usize) -> Vec<String> {
    let m = &machine.machine;
    let mut cols = vec!["time_s".to_string(), "state".to_string()];
    cols.extend((1..=paths).map(|p| format!("model_path{p}")));
    cols.extend(input_columns(machine));
    cols.extend(m.axes.iter().map(|a| format!("{}_offset_um", a.name)));
    cols.extend(target_columns(machine));
    cols
}

/// How many of the last `columns` are targets.
fn target_columns_count(columns: &[String]) -> usize {
    let last = columns.iter().rev();
    last.take_while(|c| c.ends_with("_target_um")).count()
}

/// The columns of the axes' targets, last in `cycles`: a log written before they were logged
/// gets them added ([`check_owner`]).
fn target_columns(machine: &MachineConfig) -> impl Iterator<Item = String> + '_ {
    let axes = machine.machine.axes.iter();
    axes.map(|a| format!("{}_target_um", a.name))
}

/// The columns of a cycle's inputs, as the `cycles` and `probes` tables name them: the axis
/// positions, the temperatures and the operating state, as many as a record holds.
fn input_columns(machine: &MachineConfig) -> impl Iterator<Item = String> + '_ {
    let m = &machine.machine;
    let positions = m.axes.iter().map(|a| a.position_column());
    let temperatures = m.temperatures.iter().take(MAX_LOG_TEMPERATURES);
    let operating = m.operating.iter().take(MAX_LOG_OPERATING);
    positions
        .chain(temperatures.map(|t| t.id.clone()))
        .chain(operating.map(|o| o.id.clone()))
}

pub(crate) fn quote(name: &str) -> String {
    format!("\"{}\"", name.replace('"', "\"\""))
}

/// Longest wait between two attempts to write a failing log.
pub const MAX_BACKOFF: Duration = Duration::from_secs(2);
/// Cycle records the thread keeps while the log fails (at the default 10 records/s, 1.8 h);
/// more are counted as dropped.
pub const MAX_PENDING_RECORDS: usize = 1 << 16;
/// Events the thread keeps while the log fails; more are counted as dropped.
pub const MAX_PENDING_EVENTS: usize = 1 << 14;
/// Probe events the thread keeps while the log fails (a probe cycle every minute for 2.7
/// days); more are counted as dropped.
pub const MAX_PENDING_PROBES: usize = 1 << 12;

/// The interval between commits of every service's log (ARCHITECTURE.md: a SIGKILL loses at
/// most this much, and a failing write shows within it).
pub const COMMIT_EVERY: Duration = Duration::from_millis(250);

/// How the log is doing, for status lines and the end of a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LogHealth {
    /// Why writing fails now (`None`: the last write succeeded).
    pub failing: Option<String>,
    /// Service time (of the latest record seen) when the current failure began.
    pub failing_since_s: Option<f64>,
    /// Failures in this run that later resumed.
    pub resumed: u64,
    /// The first failure of this run: service time and reason.
    pub first_failure: Option<(f64, String)>,
    /// Records, events and probe events waiting in the thread's buffer.
    pub pending: usize,
    /// Records dropped because the buffer was full while the log failed.
    pub records_dropped: u64,
    /// Events dropped because the buffer was full while the log failed.
    pub events_dropped: u64,
    /// Probe events dropped because the buffer was full while the log failed.
    pub probes_dropped: u64,
}

/// What the logger thread shares with the rest of the process (never with the cycle).
#[derive(Debug, Default)]
struct Shared {
    health: Mutex<LogHealth>,
    /// The figures of `health` a real-time thread may read: no lock, no allocation.
    failing: AtomicBool,
    pending: AtomicU64,
    dropped: AtomicU64,
    /// Events from outside the cycle (a model reload), with their full text.
    notes: Mutex<Vec<Note>>,
    /// Page limit to apply (0: none asked).
    page_limit: AtomicU64,
}

/// An event the logger writes as given: (service time, kind, subject, detail).
type Note = (f64, &'static str, String, String);

/// The logger thread; stop it with [`Logger::stop`] (dropping it stops it too).
pub struct Logger {
    stop: Arc<AtomicBool>,
    shared: Arc<Shared>,
    handle: Option<JoinHandle<Result<(), LogError>>>,
}

/// Refuses a log written for another machine or with another layout of cycles: appending would
/// mix two machines' records under one `meta`, and the inserts would fail only later. A log
/// written before the axes' targets were logged gets their columns.
fn check_owner(
    conn: &Connection,
    path: &Path,
    machine: &str,
    columns: &[String],
) -> Result<(), LogError> {
    let refuse = |message: String| LogError {
        file: path.to_path_buf(),
        message,
    };
    let meta: Option<String> = conn
        .query_row("SELECT value FROM meta WHERE key = 'service'", [], |r| {
            r.get(0)
        })
        .ok();
    if let Some(meta) = meta {
        let v: serde_json::Value = serde_json::from_str(&meta).unwrap_or_default();
        let other = v["machine"].as_str().unwrap_or("(unnamed)");
        if other != machine {
            return Err(refuse(format!(
                "this log belongs to machine `{other}`, not to `{machine}` that this service runs; \
                 refusing to mix two machines in one log (give another --log file)"
            )));
        }
    }
    let mut st = conn
        .prepare("SELECT name FROM pragma_table_info('cycles')")
        .map_err(err(path))?;
    let existing = st
        .query_map([], |r| r.get::<_, String>(0))
        .map_err(err(path))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(err(path))?;
    let targets = target_columns_count(columns);
    let before_targets = &columns[..columns.len() - targets];
    if !existing.is_empty() && existing == before_targets {
        // A log without the target columns: its rows keep none, later rows have one. All
        // columns are added or none, so a failure leaves the layout as it was.
        let adds: String = columns[before_targets.len()..]
            .iter()
            .map(|c| format!("ALTER TABLE cycles ADD COLUMN {} REAL; ", quote(c)))
            .collect();
        let tx = conn.unchecked_transaction().map_err(err(path))?;
        tx.execute_batch(&adds).map_err(err(path))?;
        tx.commit().map_err(err(path))?;
        return Ok(());
    }
    if !existing.is_empty() && existing != columns {
        return Err(refuse(format!(
            "this log's cycles have the columns [{}], machine `{machine}` needs [{}] \
             (another machine file, or another number of paths); give another --log file",
            existing.join(", "),
            columns.join(", ")
        )));
    }
    Ok(())
}

/// What the logger is told at start.
pub struct LogSetup<'a> {
    /// Database file (created if missing; an existing log is appended to).
    pub path: &'a Path,
    /// The machine.
    pub machine: &'a MachineConfig,
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
        Self::start_with_probes(setup, events, records, Arc::new(ArrayQueue::new(1)))
    }

    /// [`Logger::start`], also draining the service's probe events into the `probes` table.
    pub fn start_with_probes(
        setup: LogSetup<'_>,
        events: Arc<EventQueue>,
        records: Arc<ArrayQueue<CycleRecord>>,
        probes: Arc<ArrayQueue<ProbeRecord>>,
    ) -> Result<Self, LogError> {
        let mut writer = Writer::open(&setup)?;
        let stop = Arc::new(AtomicBool::new(false));
        let stop_thread = Arc::clone(&stop);
        let shared = Arc::new(Shared::default());
        let shared_thread = Arc::clone(&shared);
        let every = setup.commit_every;
        let handle = std::thread::Builder::new()
            .name("truepos-log".into())
            .spawn(move || {
                let queues = Queues {
                    events: &events,
                    records: &records,
                    probes: &probes,
                };
                writer.run(&stop_thread, &shared_thread, queues, every)
            })
            .map_err(|e| LogError {
                file: setup.path.to_path_buf(),
                message: format!("cannot start the log thread: {e}"),
            })?;
        Ok(Self {
            stop,
            shared,
            handle: Some(handle),
        })
    }

    /// How the log is doing now (written by the thread after every attempt).
    pub fn health(&self) -> LogHealth {
        match self.shared.health.lock() {
            Ok(h) => h.clone(),
            Err(p) => p.into_inner().clone(),
        }
    }

    /// Whether writing fails now, what waits in the buffer and what was dropped (records, events
    /// and probe events): [`Self::health`]'s figures without its lock or its texts, so that a
    /// real-time thread may read them between cycles.
    pub fn figures(&self) -> (bool, u64, u64) {
        let s = &self.shared;
        (
            s.failing.load(Ordering::Relaxed),
            s.pending.load(Ordering::Relaxed),
            s.dropped.load(Ordering::Relaxed),
        )
    }

    /// Logs an event that does not come from the cycle (a model reload, from the host's loop
    /// between cycles), with its full text. Takes a lock the logger thread shares: never call
    /// it inside a cycle.
    pub fn note(&self, time_s: f64, kind: &'static str, subject: String, detail: String) {
        let mut notes = match self.shared.notes.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        notes.push((time_s, kind, subject, detail));
    }

    /// Caps the database at `pages` pages (SQLite's `max_page_count`, applied by the thread
    /// before its next write): beyond it a write fails with SQLITE_FULL exactly as on a full
    /// disk, and raising the cap lets it resume. For a bounded log, and for testing the
    /// failure path without filling a disk.
    pub fn set_page_limit(&self, pages: u64) {
        self.shared.page_limit.store(pages, Ordering::Release);
    }

    /// Writes what is still queued and stops the thread.
    pub fn stop(mut self) -> Result<(), LogError> {
        self.finish()
    }

    /// Like [`Logger::stop`], and how the log did over the run (after the last attempt).
    pub fn stop_with_health(mut self) -> (Result<(), LogError>, LogHealth) {
        let result = self.finish();
        (result, self.health())
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

/// What the cycle queues for the logger.
#[derive(Clone, Copy)]
struct Queues<'a> {
    events: &'a EventQueue,
    records: &'a ArrayQueue<CycleRecord>,
    probes: &'a ArrayQueue<ProbeRecord>,
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
    probe_insert: String,
    names: Names,
    layout: Layout,
    dropped_seen: u64,
    last_time: f64,
    /// Drained and not yet committed (kept across failed attempts, bounded).
    records: Vec<CycleRecord>,
    events: Vec<Event>,
    probes: Vec<ProbeRecord>,
    /// The logger's own events (failure, resumption, drops) as (time, kind, subject, detail).
    notes: Vec<Note>,
    /// The current failure: when, why, and when to try again after how long a wait.
    failure: Option<Failure>,
    health: LogHealth,
    page_limit: u64,
    /// Dropped from the full buffer since the last successful write.
    records_dropped: u64,
    events_dropped: u64,
    probes_dropped: u64,
    /// Bounds of the buffer ([`MAX_PENDING_RECORDS`], [`MAX_PENDING_EVENTS`]).
    max_records: usize,
    max_events: usize,
}

struct Failure {
    since_s: f64,
    reason: String,
    retry_at: Instant,
    backoff: Duration,
}

/// A float for SQLite: NaN and ∞ become NULL.
pub(crate) fn real(v: f64) -> rusqlite::types::Value {
    if v.is_finite() {
        rusqlite::types::Value::Real(v)
    } else {
        rusqlite::types::Value::Null
    }
}

impl Writer {
    /// Opens (or creates) the log for this service, refusing one of another machine.
    fn open(setup: &LogSetup<'_>) -> Result<Self, LogError> {
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
        let has_meta: bool = conn
            .query_row(
                "SELECT count(*) FROM sqlite_master WHERE name = 'meta'",
                [],
                |r| r.get::<_, i64>(0),
            )
            .map_err(err(&path))?
            > 0;
        if has_meta {
            check_owner(&conn, &path, &m.name, &columns)?;
        }
        conn.execute_batch(&format!(
            "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS events (time_s REAL NOT NULL, kind TEXT NOT NULL,
                 subject TEXT NOT NULL, detail TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS cycles ({});",
            defs.join(", ")
        ))
        .map_err(err(&path))?;
        let (create_probes, probe_insert) =
            probes::statements(&probes::columns(setup.machine, paths));
        conn.execute_batch(&create_probes).map_err(err(&path))?;
        let names = Names {
            axes: m.axes.iter().map(|a| a.name.clone()).collect(),
            sensors: m.temperatures.iter().map(|t| t.id.clone()).collect(),
            operating: m.operating.iter().map(|o| o.id.clone()).collect(),
            sources: setup.sources.clone(),
            sinks: setup.sinks.clone(),
            models: setup.models.clone(),
        };
        // The clock time of the service's start (its time 0: the log opens before the first
        // cycle), so that readers can show clock times; an appended log keeps the latest start.
        let started_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(f64::NAN, |d| d.as_secs_f64());
        let meta = serde_json::json!({
            "started_unix_s": started_unix_s,
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
        Ok(Self {
            conn,
            path,
            insert,
            probe_insert,
            names,
            layout,
            dropped_seen: 0,
            last_time: 0.0,
            records: Vec::new(),
            events: Vec::new(),
            probes: Vec::new(),
            notes: Vec::new(),
            failure: None,
            health: LogHealth::default(),
            page_limit: 0,
            records_dropped: 0,
            events_dropped: 0,
            probes_dropped: 0,
            max_records: MAX_PENDING_RECORDS,
            max_events: MAX_PENDING_EVENTS,
        })
    }

    /// The thread's loop: drain the queues every `every`, write when no backoff is running,
    /// publish the health; on stop, one last attempt whatever the backoff.
    fn run(
        &mut self,
        stop: &AtomicBool,
        shared: &Shared,
        queues: Queues<'_>,
        every: Duration,
    ) -> Result<(), LogError> {
        loop {
            let stopping = stop.load(Ordering::Acquire);
            self.collect(queues);
            self.take_notes(shared);
            let limit = shared.page_limit.load(Ordering::Acquire);
            if limit != 0 && limit != self.page_limit {
                // A failed pragma leaves the old cap; the next write shows what that means.
                if self
                    .conn
                    .pragma_update(None, "max_page_count", limit)
                    .is_ok()
                {
                    self.page_limit = limit;
                }
            }
            let due = match &self.failure {
                None => true,
                Some(f) => stopping || Instant::now() >= f.retry_at,
            };
            if due {
                self.attempt();
            }
            self.publish(shared);
            if stopping {
                return match &self.failure {
                    None => Ok(()),
                    Some(f) => Err(LogError {
                        file: self.path.clone(),
                        message: format!(
                            "writing the log failed since service time {:.1} s and never resumed: {}; \
                             {} records and {} events not written, and {} probe events",
                            f.since_s,
                            f.reason,
                            self.records.len() as u64 + self.records_dropped,
                            self.events.len() as u64 + self.events_dropped,
                            self.probes.len() as u64 + self.probes_dropped
                        ),
                    }),
                };
            }
            std::thread::sleep(every);
        }
    }

    /// Moves what the cycle queued into the buffer; beyond its bound, counts the drop.
    fn collect(&mut self, queues: Queues<'_>) {
        let Queues {
            events,
            records,
            probes,
        } = queues;
        while let Some(p) = probes.pop() {
            self.last_time = self.last_time.max(p.time_s);
            if self.probes.len() < MAX_PENDING_PROBES {
                self.probes.push(p);
            } else {
                self.health.probes_dropped += 1;
                self.probes_dropped += 1;
            }
        }
        while let Some(r) = records.pop() {
            self.last_time = self.last_time.max(r.time_s);
            if self.records.len() < self.max_records {
                self.records.push(r);
            } else {
                self.health.records_dropped += 1;
                self.records_dropped += 1;
            }
        }
        while let Some(e) = events.pop() {
            self.last_time = self.last_time.max(e.time_s);
            if self.events.len() < self.max_events {
                self.events.push(e);
            } else {
                self.health.events_dropped += 1;
                self.events_dropped += 1;
            }
        }
        let dropped = events.dropped();
        if dropped > self.dropped_seen {
            self.notes.push((
                self.last_time,
                "events-dropped",
                "log".into(),
                format!(
                    "{} events were dropped: the log fell behind",
                    dropped - self.dropped_seen
                ),
            ));
            self.dropped_seen = dropped;
        }
    }

    /// Moves the notes given from outside the cycle into the buffer.
    fn take_notes(&mut self, shared: &Shared) {
        let mut notes = match shared.notes.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        for n in notes.drain(..) {
            self.last_time = self.last_time.max(n.0);
            self.notes.push(n);
        }
    }

    /// One attempt to write the buffer; on failure, starts or extends the backoff.
    fn attempt(&mut self) {
        // While failing, the resumption note rides in the same transaction as the buffer, so
        // it is written exactly when the buffer is.
        let resumed = self.failure.as_ref().map(|f| {
            (
                self.last_time,
                "log-resumed",
                "log".to_string(),
                format!(
                    "writing resumed after failing since {:.1} s; {} records and {} events \
                     dropped meanwhile, and {} probe events (the buffer holds {} records, {} \
                     events and {MAX_PENDING_PROBES} probe events)",
                    f.since_s,
                    self.records_dropped,
                    self.events_dropped,
                    self.probes_dropped,
                    self.max_records,
                    self.max_events
                ),
            )
        });
        let had = self.notes.len();
        self.notes.extend(resumed);
        match self.write_buffer() {
            Ok(()) => {
                if self.failure.take().is_some() {
                    self.health.resumed += 1;
                }
                self.records.clear();
                self.events.clear();
                self.probes.clear();
                self.notes.clear();
                self.records_dropped = 0;
                self.events_dropped = 0;
                self.probes_dropped = 0;
            }
            Err(e) => {
                self.notes.truncate(had);
                let reason = e.to_string();
                match &mut self.failure {
                    Some(f) => {
                        f.backoff = (f.backoff * 2).min(MAX_BACKOFF);
                        f.retry_at = Instant::now() + f.backoff;
                        f.reason = reason;
                    }
                    None => {
                        let backoff = Duration::from_millis(250);
                        self.notes.push((
                            self.last_time,
                            "log-failed",
                            "log".into(),
                            reason.clone(),
                        ));
                        self.health
                            .first_failure
                            .get_or_insert((self.last_time, reason.clone()));
                        self.failure = Some(Failure {
                            since_s: self.last_time,
                            reason,
                            retry_at: Instant::now() + backoff,
                            backoff,
                        });
                    }
                }
            }
        }
    }

    fn publish(&mut self, shared: &Shared) {
        let h = &mut self.health;
        h.failing = self.failure.as_ref().map(|f| f.reason.clone());
        h.failing_since_s = self.failure.as_ref().map(|f| f.since_s);
        h.pending = self.records.len() + self.events.len() + self.probes.len();
        shared.failing.store(h.failing.is_some(), Ordering::Relaxed);
        shared.pending.store(h.pending as u64, Ordering::Relaxed);
        let dropped = h.records_dropped + h.events_dropped + h.probes_dropped;
        shared.dropped.store(dropped, Ordering::Relaxed);
        let mut out = match shared.health.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        *out = h.clone();
    }

    /// Writes the buffer in one transaction (rolled back whole on any error).
    fn write_buffer(&mut self) -> Result<(), rusqlite::Error> {
        let tx = self.conn.transaction()?;
        {
            let mut insert = tx.prepare_cached(&self.insert)?;
            let l = &self.layout;
            for r in &self.records {
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
                values.extend(r.targets_um[..l.axes].iter().map(|&v| real(v)));
                insert.execute(params_from_iter(values))?;
            }
            let mut probe = tx.prepare_cached(&self.probe_insert)?;
            for p in &self.probes {
                let values = probes::values(p, l.axes, l.temperatures, l.operating, l.paths);
                probe.execute(params_from_iter(values))?;
            }
            let mut ev = tx.prepare_cached(
                "INSERT INTO events (time_s, kind, subject, detail) VALUES (?1, ?2, ?3, ?4)",
            )?;
            for e in &self.events {
                let (kind, subject, detail) = describe(e, &self.names);
                ev.execute(rusqlite::params![e.time_s, kind, subject, detail])?;
            }
            for (time_s, kind, subject, detail) in &self.notes {
                ev.execute(rusqlite::params![time_s, kind, subject, detail])?;
            }
        }
        tx.commit()
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
            "position not a number, not current or beyond reach".into(),
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
        EventKind::Extrapolating {
            path,
            input,
            value,
            limit,
        } => ("extrapolating", format!("path {path}"), {
            let (what, unit) = match input {
                truepos_model::MachineInput::Temperature(c) => (name(&n.sensors, c), " °C"),
                truepos_model::MachineInput::Operating(c) => (name(&n.operating, c), ""),
            };
            format!(
                    "{what} at {value:.2}{unit} is beyond the model's training range (widened) by {:.2}{unit}: clamped to {limit:.2}{unit}, the output capped",
                    (value - limit).abs()
                )
        }),
        EventKind::ExtrapolationEnded { path } => (
            "extrapolation-ended",
            format!("path {path}"),
            "every input back inside the model's training range".into(),
        ),
        EventKind::SourceLost { source, reason } => {
            ("source-lost", name(&n.sources, source), reason.to_string())
        }
        EventKind::SourceBack { source } => {
            ("source-back", name(&n.sources, source), String::new())
        }
        EventKind::SinkFailed { sink, reason } => (
            "sink-failed",
            name(&n.sinks, sink),
            reason.as_str().to_string(),
        ),
        EventKind::SinkBack { sink } => ("sink-back", name(&n.sinks, sink), String::new()),
        EventKind::Overrun { late_us } => ("overrun", "cycle".into(), format!("{late_us} µs late")),
    }
}

#[cfg(test)]
mod tests;
