//! The publisher thread: forwards the log to a broker as Sparkplug B, store-and-forward.
//!
//! Per connection: CONNECT with the NDEATH (next `bdSeq`) as will, NBIRTH (`seq` 0), then one
//! NDATA per unit of the log after the cursor (a second, an event, an accepted probe event) (`seq` 1, 2, … mod 256), at most [`WINDOW`]
//! unacknowledged. The cursor advances over the acknowledged prefix only; on any error the
//! connection is dropped, unacknowledged messages are forgotten and read again from the log
//! after the reconnect, with everything the log held at the reconnect marked historical and
//! sent at most `replay_per_s` messages a second. The cycle never waits on any of this: the
//! thread's only link to the service is the log file.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use crate::cursor::{self, Cursor};
use crate::mqtt::{BrokerUrl, Connection, Incoming, Will};
use crate::sparkplug::{self, MessageType, Metric, Payload, Value, DOUBLE, STRING};
use crate::store::{LogReader, Rows, Unit};

/// Messages in flight (sent, not yet acknowledged) at most.
pub const WINDOW: usize = 32;
/// Longest wait between two connection attempts.
pub const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// How to forward a log.
#[derive(Debug, Clone)]
pub struct Config {
    /// The broker.
    pub broker: BrokerUrl,
    /// The service's log.
    pub log: PathBuf,
    /// Sparkplug group id.
    pub group: String,
    /// Sparkplug edge node id (`None`: the machine's name from the log).
    pub node: Option<String>,
    /// Where forwarding starts when this broker has no cursor yet (the rows of earlier runs
    /// the operator did not ask to send; zeros: the whole log).
    pub start_after: Rows,
    /// Historical messages per second at most, after a reconnect.
    pub replay_per_s: f64,
    /// MQTT keep-alive, s.
    pub keep_alive_s: u16,
}

impl Config {
    /// Defaults: group `truepos`, the machine's name, the whole log, 100 messages/s, 10 s.
    pub fn new(broker: BrokerUrl, log: PathBuf) -> Self {
        Config {
            broker,
            log,
            group: "truepos".into(),
            node: None,
            start_after: Rows::default(),
            replay_per_s: 100.0,
            keep_alive_s: 10,
        }
    }

    /// A service's `--mqtt URL`, `--mqtt-group` and `--mqtt-node`, checked before the service
    /// starts: `None` without a URL; refused for a bad URL or a service without a log (the
    /// publisher forwards the log). The log's rows of the runs before this one are not sent to a
    /// broker that has no cursor yet.
    pub fn for_service(
        url: Option<&str>,
        group: &str,
        node: Option<&str>,
        log: Option<&Path>,
    ) -> Result<Option<Self>, String> {
        let Some(url) = url else { return Ok(None) };
        let broker = BrokerUrl::parse(url)?;
        sparkplug::check_id("--mqtt-group", group)?;
        if let Some(node) = node {
            sparkplug::check_id("--mqtt-node", node)?;
        }
        let log = log.ok_or("--mqtt forwards the log: give --log FILE as well (docs/fleet.md)")?;
        let mut c = Config::new(broker, log.to_path_buf());
        c.group = group.to_string();
        c.node = node.map(str::to_string);
        c.start_after = crate::last_rows(log);
        Ok(Some(c))
    }
}

/// A service's `--mqtt` options as every process running the service takes them (`truepos
/// run`, `truepos-hal run`; feature `clap`), checked by [`MqttOptions::config`].
#[cfg(feature = "clap")]
#[derive(Debug, Clone, clap::Args)]
pub struct MqttOptions {
    /// Forward the log to an MQTT broker as Sparkplug B, `mqtt://HOST[:PORT]`: 1 s aggregates
    /// and events at QoS 1, store-and-forward across outages (needs --log; docs/fleet.md).
    #[arg(long, value_name = "URL")]
    pub mqtt: Option<String>,
    /// Sparkplug group id of --mqtt.
    #[arg(long, default_value = "truepos")]
    pub mqtt_group: String,
    /// Sparkplug edge node id of --mqtt (default: the machine's name in the machine file). Give
    /// each machine its own when several run one machine file.
    #[arg(long, value_name = "NAME")]
    pub mqtt_node: Option<String>,
}

#[cfg(feature = "clap")]
impl MqttOptions {
    /// [`Config::for_service`] of these options and the service's log.
    pub fn config(&self, log: Option<&Path>) -> Result<Option<Config>, String> {
        Config::for_service(
            self.mqtt.as_deref(),
            &self.mqtt_group,
            self.mqtt_node.as_deref(),
            log,
        )
    }
}

/// Counters the thread keeps, readable from any thread.
#[derive(Debug, Default)]
struct Shared {
    connected: AtomicBool,
    connects: AtomicU64,
    published: AtomicU64,
    acknowledged: AtomicU64,
    historical: AtomicU64,
    bytes: AtomicU64,
    last_error: Mutex<Option<String>>,
}

/// What the publisher did, for a summary line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Summary {
    /// Connected now.
    pub connected: bool,
    /// Connections made.
    pub connects: u64,
    /// NDATA messages sent (a message sent again after a reconnect counts again).
    pub published: u64,
    /// NDATA messages the broker acknowledged.
    pub acknowledged: u64,
    /// Of those sent, marked historical.
    pub historical: u64,
    /// Payload bytes of the NDATA messages sent.
    pub bytes: u64,
    /// The last connection error, if any.
    pub last_error: Option<String>,
    /// Everything the log holds was acknowledged when the thread ended.
    pub caught_up: bool,
    /// The cursor when the thread ended.
    pub cursor: Rows,
}

/// The running publisher.
pub struct Publisher {
    shared: Arc<Shared>,
    finish: Arc<Mutex<Option<Instant>>>,
    thread: Option<JoinHandle<(bool, Rows)>>,
}

impl Publisher {
    /// Opens the log (which must exist: the service creates it before its first cycle) and its
    /// cursor, then starts the thread. Errors are sentences naming the file or the broker.
    pub fn start(config: Config) -> Result<Self, String> {
        let reader = LogReader::open(&config.log)?;
        let meta = reader.meta()?;
        let cursor_path = cursor::path_for(&config.log, &config.broker);
        let cursor = match cursor::load(&cursor_path)? {
            // A cursor written before probes were forwarded: its probes start where a new
            // broker's would (the current run's first, for a service).
            Some(mut c) if c.rows.probes < 0 => {
                c.rows.probes = config.start_after.probes.max(0);
                c
            }
            Some(c) => c,
            None => Cursor {
                broker: config.broker.to_string(),
                rows: config.start_after,
                run_start_unix_s: meta.started_unix_s,
                bd_seq: 255,
            },
        };
        let node = sparkplug::sanitize_id(config.node.as_deref().unwrap_or(&meta.machine));
        let group = sparkplug::sanitize_id(&config.group);
        let shared = Arc::new(Shared::default());
        let finish = Arc::new(Mutex::new(None));
        let state = State {
            reader,
            models: meta.models.join(", "),
            machine: meta.machine,
            topic_data: sparkplug::topic(&group, MessageType::NData, &node),
            topic_birth: sparkplug::topic(&group, MessageType::NBirth, &node),
            topic_death: sparkplug::topic(&group, MessageType::NDeath, &node),
            client_id: format!("truepos-{group}-{node}"),
            cursor_path,
            cursor,
            config,
            shared: Arc::clone(&shared),
            finish: Arc::clone(&finish),
        };
        // A small stack, as the live view's threads: the LinuxCNC component locks all its
        // memory (mlockall), every thread's stack included.
        let thread = std::thread::Builder::new()
            .name("truepos-mqtt".into())
            .stack_size(512 * 1024)
            .spawn(move || state.run())
            .map_err(|e| format!("cannot start the MQTT thread: {e}"))?;
        Ok(Publisher {
            shared,
            finish,
            thread: Some(thread),
        })
    }

    /// The counters now.
    pub fn summary(&self) -> Summary {
        let s = &self.shared;
        Summary {
            connected: s.connected.load(Ordering::Relaxed),
            connects: s.connects.load(Ordering::Relaxed),
            published: s.published.load(Ordering::Relaxed),
            acknowledged: s.acknowledged.load(Ordering::Relaxed),
            historical: s.historical.load(Ordering::Relaxed),
            bytes: s.bytes.load(Ordering::Relaxed),
            last_error: s.last_error.lock().map(|e| e.clone()).unwrap_or(None),
            caught_up: false,
            cursor: Rows::default(),
        }
    }

    /// Says the log is final (the service stopped), lets the thread forward what is left for at
    /// most `drain`, then sends NDEATH, disconnects and saves the cursor. What is not
    /// acknowledged by then stays in the log for the next start.
    pub fn stop(mut self, drain: Duration) -> Summary {
        if let Ok(mut f) = self.finish.lock() {
            *f = Some(Instant::now() + drain);
        }
        let (caught_up, cursor) = self
            .thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        Summary {
            caught_up,
            cursor,
            ..self.summary()
        }
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            if let Ok(mut f) = self.finish.lock() {
                *f = Some(Instant::now());
            }
            let _ = t.join();
        }
    }
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// One message sent and not yet acknowledged.
struct InFlight {
    packet_id: u16,
    acked: bool,
    /// The cursor once it and everything before is acknowledged (`None`: NBIRTH).
    after: Option<Rows>,
}

/// One connection's state.
struct Session {
    conn: Connection,
    seq: u64,
    next_id: u16,
    in_flight: VecDeque<InFlight>,
    /// Rows read and sent: the next read starts here.
    sent: Rows,
    /// Rows the log held at connect: units up to them are historical.
    historical_upto: Rows,
    next_historical: Instant,
    last_send: Instant,
    ping_since: Option<Instant>,
    /// The last read found nothing new.
    idle: bool,
    /// The last read was of the final log (the service stopped) and found nothing new.
    drained: bool,
}

struct State {
    reader: LogReader,
    machine: String,
    models: String,
    topic_data: String,
    topic_birth: String,
    topic_death: String,
    client_id: String,
    cursor_path: PathBuf,
    cursor: Cursor,
    config: Config,
    shared: Arc<Shared>,
    finish: Arc<Mutex<Option<Instant>>>,
}

impl State {
    fn error(&self, e: String) {
        if let Ok(mut l) = self.shared.last_error.lock() {
            *l = Some(e);
        }
    }

    fn finish_at(&self) -> Option<Instant> {
        self.finish
            .lock()
            .map(|f| *f)
            .unwrap_or(Some(Instant::now()))
    }

    /// The thread: (re)connect with backoff, forward, and at the end say goodbye.
    fn run(mut self) -> (bool, Rows) {
        let mut backoff = Duration::from_millis(250);
        let mut next_try = Instant::now();
        let mut session: Option<Session> = None;
        let mut saved = self.cursor.clone();
        let mut last_save = Instant::now();
        let mut caught_up = false;
        loop {
            let finish = self.finish_at();
            let finished = finish.is_some();
            if let Some(s) = &session {
                caught_up = s.drained && s.in_flight.is_empty();
            }
            if finish.is_some_and(|f| caught_up || Instant::now() >= f) {
                break;
            }
            if session.is_none() {
                if Instant::now() < next_try {
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                }
                match self.connect() {
                    Ok(s) => {
                        backoff = Duration::from_millis(250);
                        session = Some(s);
                    }
                    Err(e) => {
                        self.error(e);
                        next_try = Instant::now() + backoff;
                        backoff = (backoff * 2).min(MAX_BACKOFF);
                        continue;
                    }
                }
            }
            let s = session.as_mut().expect("connected above");
            if let Err(e) = self.step(s, finished) {
                self.error(e);
                self.shared.connected.store(false, Ordering::Relaxed);
                session = None;
                next_try = Instant::now() + backoff;
                continue;
            }
            if self.cursor != saved && last_save.elapsed() >= Duration::from_secs(1) {
                self.save(&mut saved);
                last_save = Instant::now();
            }
        }
        if let Some(s) = session {
            self.goodbye(s);
        }
        self.save(&mut saved);
        (caught_up, self.cursor.rows)
    }

    fn save(&self, saved: &mut Cursor) {
        if *saved == self.cursor {
            return;
        }
        match cursor::save(&self.cursor_path, &self.cursor) {
            Ok(()) => *saved = self.cursor.clone(),
            Err(e) => self.error(format!("cursor not saved: {e}")),
        }
    }

    fn death_payload(&self) -> Vec<u8> {
        Payload {
            timestamp_ms: now_ms(),
            seq: None,
            metrics: vec![Metric::new(
                "bdSeq",
                Value::UInt64(u64::from(self.cursor.bd_seq)),
            )],
        }
        .encode()
    }

    fn connect(&mut self) -> Result<Session, String> {
        // Each connection takes the next bdSeq, kept in the cursor file across restarts, so a
        // host application can tell this NBIRTH's NDEATH from an older one.
        self.cursor.bd_seq = self.cursor.bd_seq.wrapping_add(1);
        let will = self.death_payload();
        let mut conn = Connection::connect(
            &self.config.broker,
            &self.client_id,
            self.config.keep_alive_s,
            Will {
                topic: &self.topic_death,
                payload: &will,
            },
            Duration::from_secs(5),
        )?;
        let birth = self.birth().encode();
        conn.publish(&self.topic_birth, 1, &birth)?;
        self.shared.connects.fetch_add(1, Ordering::Relaxed);
        self.shared.connected.store(true, Ordering::Relaxed);
        let mut in_flight = VecDeque::with_capacity(WINDOW + 1);
        in_flight.push_back(InFlight {
            packet_id: 1,
            acked: false,
            after: None,
        });
        Ok(Session {
            conn,
            seq: 0,
            next_id: 2,
            in_flight,
            sent: self.cursor.rows,
            historical_upto: self.reader.last_rows()?,
            next_historical: Instant::now(),
            last_send: Instant::now(),
            ping_since: None,
            idle: false,
            drained: false,
        })
    }

    /// NBIRTH: every metric NDATA will carry ([`birth_payload`]).
    fn birth(&self) -> Payload {
        birth_payload_with_probes(
            self.cursor.bd_seq,
            &self.machine,
            &self.models,
            self.reader.columns(),
            self.reader.probe_columns(),
            now_ms(),
        )
    }

    /// One turn: send what the window allows, read acknowledgements, keep the link alive.
    fn step(&mut self, s: &mut Session, finished: bool) -> Result<(), String> {
        let room = WINDOW.saturating_sub(s.in_flight.len());
        // Replaying at the bounded rate: the time until the next historical message may go.
        let mut rate_wait = None;
        if room > 0 {
            let units = self.reader.units(s.sent, room, finished)?;
            s.idle = units.is_empty();
            s.drained = finished && s.idle;
            for u in units {
                let historical = match &u {
                    Unit::Second(x) => x.last_row <= s.historical_upto.cycles,
                    Unit::Event(e) => e.row <= s.historical_upto.events,
                    Unit::Probe(p) => p.row <= s.historical_upto.probes,
                };
                if historical {
                    let now = Instant::now();
                    if now < s.next_historical {
                        s.idle = false;
                        s.drained = false;
                        rate_wait = Some(s.next_historical - now);
                        break;
                    }
                    // A burst after a pause is bounded to one second's worth.
                    s.next_historical = (s.next_historical
                        + Duration::from_secs_f64(1.0 / self.config.replay_per_s.max(0.1)))
                    .max(now.checked_sub(Duration::from_secs(1)).unwrap_or(now));
                }
                self.send(s, &u, historical)?;
            }
        }
        let mut incoming = Vec::new();
        let wait = match rate_wait {
            Some(w) => w.clamp(Duration::from_millis(1), Duration::from_millis(100)),
            None if s.idle => Duration::from_millis(100),
            None => Duration::from_millis(5),
        };
        s.conn.poll(wait, &mut incoming)?;
        for p in incoming {
            match p {
                Incoming::PubAck(id) => {
                    if let Some(m) = s.in_flight.iter_mut().find(|m| m.packet_id == id) {
                        m.acked = true;
                    }
                }
                Incoming::PingResp => s.ping_since = None,
                // Nothing was subscribed: a broker that sends these is not talking to us.
                Incoming::SubAck(..) | Incoming::Publish { .. } => {
                    return Err(format!("{}: an unexpected packet", self.config.broker))
                }
            }
        }
        while s.in_flight.front().is_some_and(|m| m.acked) {
            let m = s.in_flight.pop_front().expect("checked");
            if let Some(rows) = m.after {
                self.cursor.rows = rows;
                self.shared.acknowledged.fetch_add(1, Ordering::Relaxed);
            }
        }
        let keep_alive = Duration::from_secs(u64::from(self.config.keep_alive_s.max(1)));
        if let Some(since) = s.ping_since {
            if since.elapsed() > keep_alive {
                return Err(format!(
                    "{}: no answer to PINGREQ within {keep_alive:?}",
                    self.config.broker
                ));
            }
        } else if s.last_send.elapsed() >= keep_alive / 2 {
            s.conn.ping()?;
            s.ping_since = Some(Instant::now());
            s.last_send = Instant::now();
        }
        Ok(())
    }

    fn send(&mut self, s: &mut Session, u: &Unit, historical: bool) -> Result<(), String> {
        s.seq = (s.seq + 1) % 256;
        let payload = self.data(u, s.seq, historical).encode();
        let id = s.next_id;
        s.next_id = s.next_id.checked_add(1).unwrap_or(1);
        s.conn.publish(&self.topic_data, id, &payload)?;
        s.last_send = Instant::now();
        s.sent = u.after(s.sent);
        s.in_flight.push_back(InFlight {
            packet_id: id,
            acked: false,
            after: Some(s.sent),
        });
        self.shared.published.fetch_add(1, Ordering::Relaxed);
        self.shared
            .bytes
            .fetch_add(payload.len() as u64, Ordering::Relaxed);
        if historical {
            self.shared.historical.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }

    /// The clock time in ms of service time `t`: the run's start plus `t`.
    fn stamp(&self, t: f64) -> u64 {
        let ms = (self.cursor.run_start_unix_s + t) * 1000.0;
        if ms.is_finite() && ms >= 0.0 {
            ms.round() as u64
        } else {
            now_ms()
        }
    }

    fn data(&mut self, u: &Unit, seq: u64, historical: bool) -> Payload {
        let ts = match u {
            Unit::Second(x) => {
                if x.new_run {
                    // The service time restarted: a later run appended to the log. The latest
                    // run's start is what the log's meta holds now.
                    if let Ok(m) = self.reader.meta() {
                        self.cursor.run_start_unix_s = m.started_unix_s;
                    }
                }
                self.stamp(x.second)
            }
            Unit::Event(e) => self.stamp(e.time_s),
            Unit::Probe(p) => self.stamp(p.time_s),
        };
        unit_payload(
            u,
            self.reader.columns().len(),
            ts,
            seq,
            historical,
            now_ms(),
        )
    }

    /// A clean end: NDEATH published by us (Sparkplug: the will is not sent on DISCONNECT),
    /// its acknowledgement awaited briefly, then DISCONNECT.
    fn goodbye(&mut self, mut s: Session) {
        let death = self.death_payload();
        let id = s.next_id;
        if s.conn.publish(&self.topic_death, id, &death).is_ok() {
            let deadline = Instant::now() + Duration::from_secs(2);
            let mut incoming = Vec::new();
            while Instant::now() < deadline && !incoming.contains(&Incoming::PubAck(id)) {
                if s.conn
                    .poll(Duration::from_millis(50), &mut incoming)
                    .is_err()
                {
                    break;
                }
            }
        }
        s.conn.disconnect();
        self.shared.connected.store(false, Ordering::Relaxed);
    }
}

/// The NBIRTH a service sends: `bdSeq`, `Node Control/Rebirth`, the machine and its models,
/// then every metric NDATA will carry for the log's `columns`, with its type and alias (values
/// null until the first data). The alias of a metric is its index here; NDATA follows
/// `data_alias`. Public so that a load generator sends exactly what a service sends. A log
/// with probe events declares their metrics too: [`birth_payload_with_probes`].
pub fn birth_payload(
    bd_seq: u8,
    machine: &str,
    models: &str,
    columns: &[String],
    now_ms: u64,
) -> Payload {
    birth_payload_with_probes(bd_seq, machine, models, columns, &[], now_ms)
}

/// [`birth_payload`] with, after the event's fields, the metrics of a probe event:
/// `Probe/state` (text) and `Probe/<column>` (double) for each of the log's `probe_columns`
/// (none: the log has no probe table).
pub fn birth_payload_with_probes(
    bd_seq: u8,
    machine: &str,
    models: &str,
    columns: &[String],
    probe_columns: &[String],
    now_ms: u64,
) -> Payload {
    let mut metrics = vec![
        Metric::new("bdSeq", Value::UInt64(u64::from(bd_seq))),
        Metric::new("Node Control/Rebirth", Value::Boolean(false)),
        Metric::new("Properties/Machine", Value::String(machine.to_string())),
        Metric::new("Properties/Models", Value::String(models.to_string())),
        Metric::new("Cycles", Value::Null(7)),
        Metric::new("Active cycles", Value::Null(7)),
    ];
    for c in columns {
        for s in STATS {
            metrics.push(Metric::new(metric_name(c, s), Value::Null(DOUBLE)));
        }
    }
    for f in EVENT_FIELDS {
        metrics.push(Metric::new(format!("Event/{f}"), Value::Null(STRING)));
    }
    if !probe_columns.is_empty() {
        metrics.push(Metric::new("Probe/state", Value::Null(STRING)));
        for c in probe_columns {
            metrics.push(Metric::new(format!("Probe/{c}"), Value::Null(DOUBLE)));
        }
    }
    for (i, m) in metrics.iter_mut().enumerate() {
        m.alias = Some(i as u64);
    }
    Payload {
        timestamp_ms: now_ms,
        seq: Some(0),
        metrics,
    }
}

/// The NDATA a service sends for one unit of its log (a second's aggregates or an event) of a
/// log with `columns` columns: metrics by alias, each stamped `data_ms` (the data's clock
/// time), the payload stamped `now_ms` (when the message was made).
pub fn unit_payload(
    u: &Unit,
    columns: usize,
    data_ms: u64,
    seq: u64,
    historical: bool,
    now_ms: u64,
) -> Payload {
    let mut metrics = Vec::new();
    let mut push = |slot: DataSlot, value: Value| {
        metrics.push(Metric {
            alias: Some(data_alias(slot, columns)),
            timestamp_ms: Some(data_ms),
            historical,
            ..Metric::new("", value)
        })
    };
    match u {
        Unit::Second(x) => {
            push(DataSlot::Cycles, Value::UInt32(x.cycles));
            push(DataSlot::Active, Value::UInt32(x.active));
            for (c, st) in x.stats.iter().enumerate() {
                let parts = st.map_or([None; 3], |t| [Some(t.0), Some(t.1), Some(t.2)]);
                for (k, v) in parts.into_iter().enumerate() {
                    push(
                        DataSlot::Stat(c, k),
                        v.map_or(Value::Null(DOUBLE), Value::Double),
                    );
                }
            }
        }
        Unit::Event(e) => {
            for (k, v) in [&e.kind, &e.subject, &e.detail].into_iter().enumerate() {
                push(DataSlot::Event(k), Value::String(v.clone()));
            }
        }
        Unit::Probe(p) => {
            push(DataSlot::ProbeState, Value::String(p.state.clone()));
            for (i, v) in p.values.iter().enumerate() {
                push(
                    DataSlot::Probe(i),
                    v.map_or(Value::Null(DOUBLE), Value::Double),
                );
            }
        }
    }
    Payload {
        timestamp_ms: now_ms,
        seq: Some(seq),
        metrics,
    }
}

/// The statistics of a column, in the order of their metrics.
const STATS: [&str; 3] = ["min", "mean", "max"];
/// The fields of an event, in the order of their metrics.
const EVENT_FIELDS: [&str; 3] = ["Kind", "Subject", "Detail"];

/// A metric NDATA carries.
#[derive(Clone, Copy)]
enum DataSlot {
    Cycles,
    Active,
    /// Column, statistic ([`STATS`]).
    Stat(usize, usize),
    /// Field ([`EVENT_FIELDS`]).
    Event(usize),
    /// A probe event's state.
    ProbeState,
    /// A probe event's column.
    Probe(usize),
}

/// The alias NBIRTH gave a metric: its index in the birth (bdSeq, Rebirth, Machine, Models,
/// then Cycles at 4, Active cycles, the columns' statistics, the event's fields, the probe's
/// state and columns).
fn data_alias(slot: DataSlot, columns: usize) -> u64 {
    let i = match slot {
        DataSlot::Cycles => 4,
        DataSlot::Active => 5,
        DataSlot::Stat(c, k) => 6 + 3 * c + k,
        DataSlot::Event(k) => 6 + 3 * columns + k,
        DataSlot::ProbeState => 6 + 3 * columns + 3,
        DataSlot::Probe(i) => 6 + 3 * columns + 4 + i,
    };
    i as u64
}

/// The metric name of a `cycles` column's statistic: offsets under `Offsets/`, every other
/// column (temperatures, operating state, positions) under `Inputs/`.
pub fn metric_name(column: &str, stat: &str) -> String {
    if column.ends_with("_offset_um") {
        format!("Offsets/{column}/{stat}")
    } else {
        format!("Inputs/{column}/{stat}")
    }
}
