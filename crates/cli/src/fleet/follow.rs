//! `truepos fleet follow`: the sidecar beside a service that moves models between the fleet
//! store and the machine (docs/fleet.md, "The service follows the store"). The service's cycle
//! is not touched: the follower reads the service's log, talks to PostgreSQL and writes the
//! model file the service reloads on change.
//!
//! Each round:
//! 1. the store's active model is the file at `--model`: when they differ (an activation or a
//!    rollback, by hand or by this follower), the active model is fetched, checked (SHA-256,
//!    signature under `--trusted-keys`, loaded for the machine) and written with its `.sig`
//!    (the signature renamed into place first, both synced before either rename);
//! 2. a candidate is fetched and checked the same way: refused, it is retired with the reason
//!    (unless the refusal is this follower's setup: a key its trust list lacks, another file
//!    extension — then it stays a candidate); else it becomes the shadow;
//! 3. the accepted probe events the log gained (only the rows after the cursor are read) are
//!    evaluated with the shadow (and, after an activation, with the new model's parent until
//!    it is kept or rolled back) and stored (`fleet_shadow_probes`) under the version whose
//!    bytes the file holds — after a file written, only those after the service's
//!    `model-reloaded` event;
//! 4. the rules of `truepos_fleet_store::shadow` decide: activate or retire the shadow, keep
//!    or roll back the new model — a move only while the store's active model is still the
//!    one judged.
//!
//! The cursor in the log's probes, the awaited reload and the run of the log they belong to
//! live in `LOG.follow-cursor`, so a follower restarted, or run `--once` from a timer, goes on
//! where the last one stopped.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use truepos_fleet_store::models::{self, Change, ModelFile, State, Which};
use truepos_fleet_store::postgres::Client;
use truepos_fleet_store::shadow::{self, Rule, ShadowDecision, WatchDecision};
use truepos_fleet_store::shadow_probes;
use truepos_io::model_file::signature::{public_hex, signature_path, verify_line, TrustedKeys};
use truepos_model::config::MachineConfig;
use truepos_model::CompensationModel;
use truepos_runtime::log;

use super::{connect, store_error, Store};

mod after_write;
mod layout;
mod log_after;
use crate::error::CliError;
use after_write::after_write;
use layout::Layout;

/// Arguments of `truepos fleet follow`.
#[derive(clap::Args)]
pub struct FollowArgs {
    #[command(flatten)]
    store: Store,
    /// The machine (its node id in the store).
    #[arg(long)]
    machine: String,
    /// The machine description models are loaded for.
    #[arg(long, value_name = "FILE")]
    machine_file: PathBuf,
    /// The service's log (`truepos run --log`): its probe events and reload events are read.
    #[arg(long, value_name = "FILE")]
    log: PathBuf,
    /// The model file the service runs and reloads on change (`--models`); the follower writes
    /// the active model here, with its MODEL.sig.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// The public keys trusted to sign models (the service's `--trusted-keys`).
    #[arg(long, value_name = "FILE")]
    trusted_keys: PathBuf,
    /// Residuals (probe events × measured axes) before a shadow or a new model is judged.
    #[arg(long, default_value_t = Rule::DEFAULT.min_probes)]
    min_probes: usize,
    /// Relative margin of the rules (0.1: a shadow must be 10 % better, a new model is rolled
    /// back when 10 % worse than its parent).
    #[arg(long, default_value_t = Rule::DEFAULT.margin)]
    margin: f64,
    /// Seconds between rounds.
    #[arg(long, default_value_t = 5.0)]
    interval_s: f64,
    /// One round, then exit.
    #[arg(long)]
    once: bool,
    /// Stop after this many seconds (default: run until stopped).
    #[arg(long)]
    duration_s: Option<f64>,
    /// A shell command run after each model written (`sh -c` in a process group of its own,
    /// killed whole after 30 s): for a service
    /// that does not watch its file — beside `truepos-hal`, `halcmd setp truepos.model.reload 1;
    /// halcmd setp truepos.model.reload 0`. The written file is in `TRUEPOS_MODEL`, its
    /// version in `TRUEPOS_MODEL_VERSION`.
    #[arg(long, value_name = "COMMAND")]
    after_write: Option<String>,
    /// Who the store's history names for the follower's moves.
    #[arg(long, default_value = "truepos fleet follow")]
    by: String,
}

/// A model the follower evaluates: the shadow, or the parent of a new model.
struct Evaluated {
    version: i32,
    model: CompensationModel,
    /// Only the log's probes rows after this one count for it (a shadow: those logged after
    /// it arrived).
    from_row: i64,
}

/// A model activated while following, judged against its parent until kept or rolled back.
struct Watch {
    /// The active version watched.
    active: i32,
    /// Its parent, evaluated at every probe.
    parent: Evaluated,
}

/// The service's reload of the file this follower wrote last: until it is in the log, the
/// service's predictions are the previous model's, and no probe is judged.
struct Reload {
    /// The last event (rowid) read before the reload: it is looked for after it (the events
    /// before the file was written, then those already read).
    events_before: i64,
    /// Service time of the `model-reloaded` event of the file: probes from then on count.
    at_s: Option<f64>,
}

struct Follower {
    a: FollowArgs,
    rule: Rule,
    machine: MachineConfig,
    keys: TrustedKeys,
    db: Client,
    /// The log's probes rows read so far (rowid), kept in `LOG.follow-cursor`.
    cursor: i64,
    /// The run of the log the cursor and the reload belong to: its `started_unix_s` in the
    /// log's meta (a restarted service appends a new run, its service time from 0 again).
    run: Option<f64>,
    shadow: Option<Evaluated>,
    watch: Option<Watch>,
    /// The reload of the last file written (`None`: none written; every probe counts).
    reload: Option<Reload>,
    /// The active version last considered for watching (so each is considered once).
    considered: Option<i32>,
    /// The last thing said about waiting, so a round that changes nothing prints nothing.
    said: String,
}

/// `truepos fleet follow`.
pub fn follow(a: FollowArgs) -> Result<(), CliError> {
    let rule = Rule {
        min_probes: a.min_probes,
        margin: a.margin,
    };
    rule.check()
        .map_err(|why| CliError::refused(format!("--{why}")))?;
    if !(a.interval_s.is_finite() && (0.01..=3600.0).contains(&a.interval_s)) {
        return Err(CliError::refused("--interval-s: give 0.01-3600"));
    }
    let deadline = super::seconds("--duration-s", a.duration_s)?.map(|d| Instant::now() + d);
    let machine = truepos_io::machine_file::load(&a.machine_file)?;
    let keys = TrustedKeys::load(&a.trusted_keys)?;
    let db = connect(&a.store)?;
    // Where the last follower of this log stopped; without one, the log's end: probes already
    // in it came before anything this follower shadows.
    let loaded = load_cursor(&a.log);
    let fresh = loaded.is_none();
    let (cursor, reload, run) = loaded.unwrap_or_else(|| (last_probe_row(&a.log), None, None));
    // A cursor file of a follower before runs were kept: the run in the log now.
    let run = run.or_else(|| run_of(&a.log));
    let mut f = Follower {
        rule,
        machine,
        keys,
        db,
        cursor,
        run,
        shadow: None,
        watch: None,
        reload,
        considered: None,
        said: String::new(),
        a,
    };
    if fresh && f.a.log.exists() {
        // Kept at once: a `--once` run from a timer that reads nothing new leaves the next one
        // this log's end, not the end of the log as it will be then.
        f.save()?;
    }
    loop {
        if let Err(e) = f.round() {
            if f.a.once {
                return Err(e);
            }
            eprintln!("{}: round failed: {e}", f.a.machine);
            if f.db.is_closed() {
                match connect(&f.a.store) {
                    Ok(db) => f.db = db,
                    Err(e) => eprintln!("{}: {e}", f.a.machine),
                }
            }
        }
        if f.a.once || deadline.is_some_and(|d| Instant::now() >= d) {
            return Ok(());
        }
        std::thread::sleep(Duration::from_secs_f64(f.a.interval_s));
    }
}

/// The side file that keeps the follower's cursor in a log's probes.
fn cursor_path(log: &Path) -> PathBuf {
    let mut p = log.as_os_str().to_owned();
    p.push(".follow-cursor");
    PathBuf::from(p)
}

/// The cursor, the awaited reload and the run an earlier follower of this log left.
fn load_cursor(log: &Path) -> Option<(i64, Option<Reload>, Option<f64>)> {
    let text = std::fs::read_to_string(cursor_path(log)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let row = v["probes_row"].as_i64().filter(|&n| n >= 0)?;
    let reload = v["reload"]["events_before"].as_i64().map(|n| Reload {
        events_before: n,
        at_s: v["reload"]["at_s"].as_f64(),
    });
    Some((row, reload, v["run_started_unix_s"].as_f64()))
}

/// The run the log's service writes now: its `started_unix_s` (`None`: no log or meta yet).
fn run_of(log: &Path) -> Option<f64> {
    if !log.exists() {
        return None;
    }
    log::read_meta(log)
        .ok()
        .flatten()
        .and_then(|m| m["started_unix_s"].as_f64())
        .filter(|s| s.is_finite())
}

/// The probe rows of a run whose probes are judged, the run's start and its reload filter; the
/// predictions before an awaited reload are the previous model's and are not judged.
type Judged<'r> = (Vec<&'r log::ProbeRow>, f64, Option<f64>);

/// Splits the probes rows after the cursor (`prev_t`: the service time of the cursor's row)
/// between the run the cursor was in (started at `old_start`) and the newest run (started
/// at `new_start`), when the service started again in between. A row is the old run's while
/// the service time does not go back and its clock time (`old_start` + time) is not after the
/// new run's start; the newest run begins at the last time the service time went back. Rows
/// of runs between the two (their start is not in the log) are in neither.
fn split_runs<'r>(
    rows: &[&'r log::ProbeRow],
    prev_t: f64,
    old_start: f64,
    new_start: f64,
) -> (Vec<&'r log::ProbeRow>, Vec<&'r log::ProbeRow>) {
    let mut first_new = rows.len();
    let mut prev = prev_t;
    for (i, r) in rows.iter().enumerate() {
        if r.time_s.is_nan() {
            continue;
        }
        if r.time_s < prev || old_start + r.time_s > new_start {
            first_new = i;
            break;
        }
        prev = r.time_s;
    }
    let mut newest = first_new;
    let mut prev = f64::NEG_INFINITY;
    for (i, r) in rows.iter().enumerate().skip(first_new) {
        if r.time_s.is_nan() {
            continue;
        }
        if r.time_s < prev {
            newest = i;
        }
        prev = r.time_s;
    }
    (rows[..first_new].to_vec(), rows[newest..].to_vec())
}

/// The largest rowid of the log's probes (0 without a log or probes yet).
fn last_probe_row(path: &Path) -> i64 {
    log_after::last_probe_row(path).unwrap_or(0)
}

impl Follower {
    fn say(&self, what: &str) {
        println!("{}: {what}", self.a.machine);
    }

    fn round(&mut self) -> Result<(), CliError> {
        self.sync_active()?;
        self.take_candidate()?;
        self.read_probes()?;
        self.judge()
    }

    /// A stored model checked as the service would check its file: its bytes against their
    /// SHA-256, its signature under the trusted keys, loaded for the machine. `Err` says why.
    fn checked(&self, f: &ModelFile) -> Result<CompensationModel, String> {
        if models::sha256_hex(&f.bytes) != f.sha256 {
            return Err("the stored bytes do not match their sha256".into());
        }
        verify_line(&f.signature, &f.bytes, &self.keys.keys)
            .map_err(|why| format!("signature: {why}"))?;
        let text = std::str::from_utf8(&f.bytes).map_err(|_| "not UTF-8 text".to_string())?;
        // Parsed as the service parses the file it runs (its extension tells TOML from JSON).
        let entry = truepos_io::model_file::entry_of_text(&self.a.model, text, &self.machine, None)
            .map_err(|e| e.to_string())?;
        Ok(entry.model)
    }

    /// Why a stored model cannot be checked by this follower as it is set up — not a fault of
    /// the model: signed by a key `--trusted-keys` does not hold at all (another trust list
    /// may), or stored under a file name whose extension is not `--model`'s (this follower
    /// would parse it as the wrong format).
    fn local_refusal(&self, f: &ModelFile) -> Option<String> {
        let ext = |p: &Path| {
            p.extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default()
        };
        let (stored, ours) = (ext(Path::new(&f.file_name)), ext(&self.a.model));
        if stored != ours {
            return Some(format!(
                "stored as `{}`, and {} is a `.{ours}` file: this follower cannot run it (follow it with a --model of its kind)",
                f.file_name,
                self.a.model.display()
            ));
        }
        let key = f.signature.split_whitespace().nth(1)?.to_lowercase();
        if !self.keys.keys.iter().any(|k| public_hex(k) == key) {
            return Some(format!(
                "signed by {key}, a key not in {} (this follower's trust list)",
                self.keys.file.display()
            ));
        }
        None
    }

    /// Writes the store's active model into `--model` when the file is another one.
    fn sync_active(&mut self) -> Result<(), CliError> {
        let active = match models::fetch(&mut self.db, &self.a.machine, Which::State(State::Active))
        {
            Ok(f) => f,
            Err(models::ModelError::NoneInState { .. }) => {
                self.note("no active model in the store; the file stays as it is");
                return Ok(());
            }
            Err(e) => return Err(store_error(e)),
        };
        let on_disk = std::fs::read(&self.a.model)
            .ok()
            .map(|b| models::sha256_hex(&b));
        if on_disk.as_deref() == Some(active.sha256.as_str()) {
            if self.considered != Some(active.version) {
                // Written before this follower ran (a follower restarted after an
                // activation): judged from the cursor on, once the reload awaited (if any) is in
                // the log.
                self.watch_new(active.version)?;
            }
            return Ok(());
        }
        if let Err(why) = self.checked(&active) {
            self.note(&format!(
                "active version {} refused: {why}; {} left as it is",
                active.version,
                self.a.model.display()
            ));
            return Ok(());
        }
        let events_before = log_after::last_event_row(&self.a.log).unwrap_or(0);
        let sig = write_signed_model(&self.a.model, &active.bytes, &active.signature)?;
        self.say(&format!(
            "version {} written to {} (sha256 {}), with {}",
            active.version,
            self.a.model.display(),
            &active.sha256[..12],
            sig.display()
        ));
        if let Some(cmd) = &self.a.after_write {
            self.say(&after_write(cmd, &self.a.model, active.version));
        }
        self.reload = Some(Reload {
            events_before,
            at_s: None,
        });
        self.save()?;
        self.watch_new(active.version)
    }

    /// After the active model's file was written (judged once the service reloaded it) or
    /// found written (the service runs it): judge it against its parent, unless it is a model
    /// returned to by a rollback or has no parent.
    fn watch_new(&mut self, version: i32) -> Result<(), CliError> {
        self.watch = None;
        self.considered = Some(version);
        let all = models::list(&mut self.db, Some(&self.a.machine)).map_err(store_error)?;
        let Some(m) = all.iter().find(|m| m.version == version) else {
            return Ok(());
        };
        let history = models::history(&mut self.db, &self.a.machine).map_err(store_error)?;
        let times_active = history
            .iter()
            .filter(|c| c.version == version && c.to == State::Active)
            .count();
        let Some(parent) = m.parent else {
            self.say(&format!("version {version} has no parent: not watched"));
            return Ok(());
        };
        if times_active > 1 {
            self.say(&format!(
                "version {version} is active again (a rollback): not watched"
            ));
            return Ok(());
        }
        let file = models::fetch(&mut self.db, &self.a.machine, Which::Version(parent))
            .map_err(store_error)?;
        match self.checked(&file) {
            Ok(model) if !model.keeps_state() => {
                self.say(&format!(
                    "version {version} watched against its parent, version {parent}"
                ));
                self.watch = Some(Watch {
                    active: version,
                    parent: Evaluated {
                        version: parent,
                        model,
                        from_row: 0,
                    },
                });
            }
            Ok(_) => self.say(&format!(
                "version {version} not watched: its parent {parent} is a filtered model (its filters need every cycle replayed)"
            )),
            Err(why) => self.say(&format!(
                "version {version} not watched: its parent {parent} is refused: {why}"
            )),
        }
        Ok(())
    }

    /// The shadow, or a candidate made the shadow (refused ones retired with the reason).
    fn take_candidate(&mut self) -> Result<(), CliError> {
        if let Some(s) = &self.shadow {
            let all = models::list(&mut self.db, Some(&self.a.machine)).map_err(store_error)?;
            let still = all
                .iter()
                .any(|m| m.version == s.version && m.state == State::Shadow);
            if still {
                return Ok(());
            }
            // Moved by someone else (activated or retired by hand).
            self.say(&format!("version {} is no longer in shadow", s.version));
            self.shadow = None;
        }
        // A shadow left by a follower before this one first, else the newest candidate.
        let mut found = None;
        for state in [State::Shadow, State::Candidate] {
            match models::fetch(&mut self.db, &self.a.machine, Which::State(state)) {
                Ok(f) => {
                    found = Some((state, f));
                    break;
                }
                Err(models::ModelError::NoneInState { .. }) => {}
                Err(e) => return Err(store_error(e)),
            }
        }
        let Some((state, file)) = found else {
            return Ok(());
        };
        let Some(active) = self.active_version()? else {
            self.note(&format!(
                "version {} waits: no active model to shadow it beside",
                file.version
            ));
            return Ok(());
        };
        if let Some(why) = self.local_refusal(&file) {
            // This follower's setup, not the model: another follower may take it.
            self.note(&format!(
                "version {} not taken: {why}; left a {}",
                file.version, state
            ));
            return Ok(());
        }
        let model = self.checked(&file).and_then(|m| {
            if m.keeps_state() {
                Err(
                    "a filtered model: its filters carry state from cycle to cycle, and the \
                     follower does not replay the cycles through it (activate it by hand)"
                        .into(),
                )
            } else {
                Ok(m)
            }
        });
        let model = match model {
            Ok(m) => m,
            Err(why) => {
                let reason = format!("refused by fleet follow: {why}");
                models::retire(
                    &mut self.db,
                    &self.a.machine,
                    file.version,
                    &change(&self.a.by, &reason),
                )
                .map_err(store_error)?;
                self.say(&format!("version {} {reason}; retired", file.version));
                return Ok(());
            }
        };
        if state == State::Candidate {
            let reason =
                format!("fleet follow: signature verified, shadowed beside version {active}");
            models::shadow(
                &mut self.db,
                &self.a.machine,
                file.version,
                &change(&self.a.by, &reason),
            )
            .map_err(store_error)?;
        }
        self.say(&format!(
            "version {} in shadow beside version {active}",
            file.version
        ));
        self.shadow = Some(Evaluated {
            version: file.version,
            model,
            // A new shadow counts the probes logged from now on; one taken up again (a shadow
            // left by an earlier follower) those after the cursor.
            from_row: if state == State::Candidate {
                last_probe_row(&self.a.log)
            } else {
                0
            },
        });
        Ok(())
    }

    fn active_version(&mut self) -> Result<Option<i32>, CliError> {
        let all = models::list(&mut self.db, Some(&self.a.machine)).map_err(store_error)?;
        Ok(all
            .iter()
            .find(|m| m.state == State::Active)
            .map(|m| m.version))
    }

    /// The store's version whose SHA-256 is that of `--model`'s bytes on disk: the model the
    /// service runs. `None` (said once): no file, or bytes the store does not hold.
    fn running_version(&mut self) -> Result<Option<i32>, CliError> {
        let Ok(bytes) = std::fs::read(&self.a.model) else {
            self.note(&format!(
                "{} cannot be read: no probe is recorded",
                self.a.model.display()
            ));
            return Ok(None);
        };
        let sha = models::sha256_hex(&bytes);
        let all = models::list(&mut self.db, Some(&self.a.machine)).map_err(store_error)?;
        let found = all.iter().find(|m| m.sha256 == sha).map(|m| m.version);
        if found.is_none() {
            self.note(&format!(
                "{} (sha256 {}) is no model of the store: the service's predictions are not a stored version's, no probe is recorded",
                self.a.model.display(),
                &sha[..12]
            ));
        }
        Ok(found)
    }

    /// Says a waiting state once.
    fn note(&mut self, what: &str) {
        if self.said != what {
            self.say(what);
            self.said = what.to_string();
        }
    }

    /// How the probes of the reload state are filtered: `Some(from_s)` (service time after
    /// which they count, `None`: all), or `None`: not judged (a reload awaited).
    fn reload_filter(&self) -> Option<Option<f64>> {
        match &self.reload {
            None => Some(None),
            Some(Reload { at_s: Some(t), .. }) => Some(Some(*t)),
            Some(Reload { at_s: None, .. }) => None,
        }
    }

    /// The service started again (a new run in the log, `started`): what the follower kept of
    /// the old run's service time is dropped. When the file is the store's active model, the
    /// service loaded it at its start: the run's time 0 is the reload; otherwise every probe
    /// counts, filed under the version the file is (a write and its reload follow).
    fn new_run(&mut self, started: f64) -> Result<(), CliError> {
        let events = log_after::last_event_row(&self.a.log).unwrap_or(0);
        let on_disk = std::fs::read(&self.a.model)
            .ok()
            .map(|b| models::sha256_hex(&b));
        let active = match models::fetch(&mut self.db, &self.a.machine, Which::State(State::Active))
        {
            Ok(f) => Some(f.sha256),
            Err(models::ModelError::NoneInState { .. }) => None,
            Err(e) => return Err(store_error(e)),
        };
        let runs_active = on_disk.is_some() && on_disk == active;
        self.run = Some(started);
        self.reload = runs_active.then_some(Reload {
            events_before: events,
            at_s: Some(0.0),
        });
        self.say(&format!(
            "the service started again (a new run in {}): {}",
            self.a.log.display(),
            if runs_active {
                "it loaded the active model at its start"
            } else {
                "its file is not the active model"
            }
        ));
        self.save()
    }

    /// Evaluates the probes the log gained with the shadow and the watched parent, and stores
    /// them.
    fn read_probes(&mut self) -> Result<(), CliError> {
        if !self.a.log.exists() {
            return Ok(());
        }
        // A new run since the cursor: the old run's rows after the cursor keep its start and
        // its reload; the new run's get their own.
        let (old_run, old_from) = (self.run, self.reload_filter());
        let started = run_of(&self.a.log);
        let restarted = match (old_run, started) {
            (Some(r), Some(s)) if r != s => Some(s),
            (None, Some(s)) => {
                self.run = Some(s);
                None
            }
            _ => None,
        };
        if let Some(s) = restarted {
            self.new_run(s)?;
        }
        self.await_reload()?;
        // Only the rows from the cursor's on (its own for its service time).
        let table = log_after::probes_from(&self.a.log, self.cursor)?;
        let Some(last) = table.rows.last().map(|r| r.row) else {
            if self.cursor > 0 {
                // The cursor's row is gone: a new log in the same place, read from its start.
                return self.advance(0);
            }
            return Ok(());
        };
        if last <= self.cursor {
            if last < self.cursor {
                // A new log in the same place: read it from its start.
                return self.advance(0);
            }
            return Ok(());
        }
        // The version the service runs: the store's model whose bytes are the file's (the store's
        // active one may have been refused by this follower, the file left as it was).
        let Some(active) = self.running_version()? else {
            return self.advance(last);
        };
        let layout = Layout::of(&table.columns, &self.machine)
            .map_err(|m| CliError::refused(format!("{}: {m}", self.a.log.display())))?;
        let after: Vec<&log::ProbeRow> =
            table.rows.iter().filter(|r| r.row > self.cursor).collect();
        let old_start = old_run.or(started).unwrap_or(0.0);
        let mut runs: Vec<Judged<'_>> = Vec::new();
        match restarted {
            None => {
                if let Some(from) = old_from {
                    runs.push((after, old_start, from));
                }
            }
            Some(new_start) => {
                let prev_t = table
                    .rows
                    .iter()
                    .find(|r| r.row == self.cursor)
                    .map_or(f64::NEG_INFINITY, |r| r.time_s);
                let (old, new) = split_runs(&after, prev_t, old_start, new_start);
                if let Some(from) = old_from {
                    runs.push((old, old_start, from));
                }
                if let Some(from) = self.reload_filter() {
                    runs.push((new, new_start, from));
                }
            }
        }
        for (rows, _, _) in &mut runs {
            rows.retain(|r| r.accepted);
        }
        self.record_probes(&layout, &runs, active)?;
        self.advance(last)
    }

    /// Stores the residuals of the judged runs' probes: the shadow's since it began, and the
    /// watched parent's while the model it watches is still the one running.
    fn record_probes(
        &mut self,
        layout: &Layout,
        runs: &[Judged<'_>],
        active: i32,
    ) -> Result<(), CliError> {
        if let Some(s) = &mut self.shadow {
            let mut probes = Vec::new();
            for (rows, start, from_s) in runs {
                let since: Vec<&log::ProbeRow> = rows
                    .iter()
                    .filter(|r| r.row > s.from_row)
                    .copied()
                    .collect();
                probes.extend(layout.residuals(&since, &mut s.model, *start, *from_s));
            }
            shadow_probes::record(&mut self.db, &self.a.machine, s.version, active, &probes)
                .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
        }
        if let Some(w) = &mut self.watch {
            if w.active == active {
                let mut probes = Vec::new();
                for (rows, start, from_s) in runs {
                    probes.extend(layout.residuals(rows, &mut w.parent.model, *start, *from_s));
                }
                shadow_probes::record(
                    &mut self.db,
                    &self.a.machine,
                    w.parent.version,
                    active,
                    &probes,
                )
                .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
            }
        }
        Ok(())
    }

    /// While a reload is awaited, looks through the events logged since the last look for the
    /// service reloading the followed file (from then on its probes are the new model's) or
    /// failing to, and says which.
    fn await_reload(&mut self) -> Result<(), CliError> {
        if let Some(r) = &mut self.reload {
            if r.at_s.is_none() {
                for (row, e) in log_after::events_after(&self.a.log, r.events_before)? {
                    // Read once: the next round goes on after it.
                    r.events_before = row;
                    if e.kind == "model-reloaded" && same_file(&e.detail, &self.a.model) {
                        r.at_s = Some(e.time_s);
                        println!(
                            "{}: the service reloaded {} at its {:.1} s",
                            self.a.machine, e.detail, e.time_s
                        );
                        break;
                    }
                    if e.kind == "model-reload-failed"
                        && e.detail.contains(&file_name(&self.a.model))
                    {
                        println!(
                            "{}: the service's reload failed: {}",
                            self.a.machine, e.detail
                        );
                    }
                }
            }
        }
        Ok(())
    }

    /// Moves the cursor and keeps it beside the log.
    fn advance(&mut self, row: i64) -> Result<(), CliError> {
        self.cursor = row;
        self.save()
    }

    /// Writes the cursor and the awaited reload beside the log (whole), for the next follower.
    fn save(&self) -> Result<(), CliError> {
        let reload = self
            .reload
            .as_ref()
            .map(|r| serde_json::json!({ "events_before": r.events_before, "at_s": r.at_s }));
        let text = serde_json::json!({
            "probes_row": self.cursor,
            "reload": reload,
            "run_started_unix_s": self.run,
        })
        .to_string();
        crate::write::write_whole(&cursor_path(&self.a.log), text + "\n", &[])
    }

    /// The rules on what is stored.
    fn judge(&mut self) -> Result<(), CliError> {
        let Some(active) = self.active_version()? else {
            return Ok(());
        };
        let (m, margin) = (self.a.machine.clone(), self.rule.margin);
        if let Some(s) = &self.shadow {
            let version = s.version;
            let pairs = shadow_probes::pairs(&mut self.db, &m, version, active)
                .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
            match shadow::judge_shadow(&self.rule, &pairs) {
                ShadowDecision::Wait(_) => {}
                ShadowDecision::Activate(f) => {
                    let reason = format!(
                        "fleet follow: better than version {active} in shadow, {f}; rule: below (1 − {margin}) × the active RMS after {} residuals",
                        self.rule.min_probes
                    );
                    // Only while the model it was judged beside is still the active one.
                    match models::activate_if(
                        &mut self.db,
                        &m,
                        version,
                        Some(active),
                        &change(&self.a.by, &reason),
                    ) {
                        Ok(_) => self.say(&format!("version {version} activated: {f}")),
                        Err(e @ models::ModelError::Conflict { .. }) => {
                            // Moved by someone else: the next round writes what is active now
                            // and judges the shadow beside it.
                            self.say(&format!("version {version} not activated: {e}"));
                            return Ok(());
                        }
                        Err(e) => self.say(&format!("version {version} not activated: {e}")),
                    }
                    self.shadow = None;
                    // Written now, watched from the next round (the watch below is of the
                    // model this round began with).
                    return self.sync_active();
                }
                ShadowDecision::Retire(f) => {
                    let reason = format!(
                        "fleet follow: not better than version {active} by the margin {margin} in shadow, {f}"
                    );
                    match models::retire(&mut self.db, &m, version, &change(&self.a.by, &reason)) {
                        Ok(()) => self.say(&format!("version {version} retired: {f}")),
                        Err(e) => self.say(&format!("version {version} not retired: {e}")),
                    }
                    self.shadow = None;
                }
            }
        }
        let Some(w) = &self.watch else {
            return Ok(());
        };
        if w.active != active {
            // Moved by someone else: the next round writes and watches what is active now.
            self.watch = None;
            return Ok(());
        }
        let parent = w.parent.version;
        let pairs = shadow_probes::pairs(&mut self.db, &m, parent, active)
            .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
        let f = match shadow::judge_rollback(&self.rule, &pairs) {
            WatchDecision::Wait(_) => return Ok(()),
            WatchDecision::Keep(f) => {
                // Decided: the watch ends (its residuals stop being evaluated and stored).
                self.say(&format!(
                    "version {active} kept: not worse than its parent {parent} by the margin {margin}, {f}; no longer watched"
                ));
                self.watch = None;
                return Ok(());
            }
            WatchDecision::Rollback(f) => f,
        };
        let reason = format!(
            "fleet follow: version {active} worse than its parent {parent} on the probes since its reload, {f}; rule: above (1 + {margin}) × the parent's RMS after {} residuals",
            self.rule.min_probes
        );
        self.watch = None;
        // Only while the model judged is still the active one (a conflict: someone moved it;
        // the next round writes and watches what is active now).
        match models::rollback_if(&mut self.db, &m, Some(active), &change(&self.a.by, &reason)) {
            Ok((retired, now)) => {
                self.say(&format!(
                    "version {retired} rolled back to version {now}: {f}"
                ));
                self.sync_active()?;
            }
            Err(e) => self.say(&format!("rollback of version {active} refused: {e}")),
        }
        Ok(())
    }
}

/// Writes a signed model as a service reloading on change should see it: the model and its
/// signature line (`MODEL.sig`) both written and synced to temporary files, then the signature
/// renamed into place first and at once the model — a reload reads the model before its
/// signature, so it never loads new bytes with the old signature accepted (one between the
/// two renames reads the old model with the new signature: refused, and followed by the good
/// one). Returns the signature's path. Used by `fleet follow` and `fleet models get`.
pub(super) fn write_signed_model(
    model: &Path,
    bytes: &[u8],
    signature: &str,
) -> Result<PathBuf, CliError> {
    let sig = signature_path(model);
    let line = format!("{}\n", signature.trim());
    crate::write::write_all_whole(&[(&sig, line.as_bytes()), (model, bytes)], &[])?;
    Ok(sig)
}

/// The follower's move, for the store's history.
fn change<'a>(by: &'a str, reason: &'a str) -> Change<'a> {
    Change {
        by: Some(by),
        reason,
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default()
}

/// Whether an event's file is `--model`: the same path once both are made absolute, or — the
/// service may have been started from another directory — the same file name.
fn same_file(detail: &str, model: &Path) -> bool {
    let d = Path::new(detail);
    match (d.canonicalize(), model.canonicalize()) {
        (Ok(a), Ok(b)) if a == b => true,
        _ => !file_name(model).is_empty() && file_name(d) == file_name(model),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(row: i64, time_s: f64) -> log::ProbeRow {
        log::ProbeRow {
            row,
            time_s,
            accepted: true,
            reason: String::new(),
            values: Vec::new(),
        }
    }

    fn rows_of(rows: &[&log::ProbeRow]) -> Vec<i64> {
        rows.iter().map(|r| r.row).collect()
    }

    #[test]
    fn rows_after_the_cursor_are_split_between_the_old_run_and_the_newest() {
        // The cursor at row 2, 100 s into a run started at 1000; rows 3-4 are its tail, the
        // service started again at 1300: rows 5-6 (time from 0 again).
        let all = [row(3, 110.0), row(4, 120.0), row(5, 5.0), row(6, 15.0)];
        let refs: Vec<&log::ProbeRow> = all.iter().collect();
        let (old, new) = split_runs(&refs, 100.0, 1000.0, 1300.0);
        assert_eq!((rows_of(&old), rows_of(&new)), (vec![3, 4], vec![5, 6]));
        // No tail: the new run's first probe later in its run than the cursor's, told by the
        // clock (1000 + 400 is after 1300).
        let all = [row(5, 400.0), row(6, 410.0)];
        let refs: Vec<&log::ProbeRow> = all.iter().collect();
        let (old, new) = split_runs(&refs, 100.0, 1000.0, 1300.0);
        assert_eq!((rows_of(&old), rows_of(&new)), (vec![], vec![5, 6]));
        // Two restarts: the run between (its start unknown) is left out.
        let all = [row(3, 110.0), row(4, 50.0), row(5, 60.0), row(6, 7.0)];
        let refs: Vec<&log::ProbeRow> = all.iter().collect();
        let (old, new) = split_runs(&refs, 100.0, 1000.0, 1300.0);
        assert_eq!((rows_of(&old), rows_of(&new)), (vec![3], vec![6]));
    }
}
