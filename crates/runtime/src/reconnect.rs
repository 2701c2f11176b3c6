//! What the network sources (MTConnect SHDR, Modbus TCP) share: reconnection with exponential
//! backoff, the state of a link as the cycle and the status line see it, and the mapping of a
//! received value onto a machine channel of the frame.
//!
//! A network source runs its own thread. When its connection is lost the thread stops publishing,
//! so the stamps of the channels it feeds stop advancing: the service's validation then sees
//! them as missing updates, i.e. bad sensors, and applies its policy. The thread meanwhile tries
//! to reconnect, waiting `initial_ms`, then twice as long after every failed attempt, up to
//! `max_ms`; a successful connection resets the wait.

use std::collections::VecDeque;
use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_queue::ArrayQueue;
use serde::Deserialize;
use truepos_model::Machine;

use crate::events::Reason;
use crate::frame::Frame;
use crate::io_traits::LinkError;

/// How long to wait between reconnection attempts (configuration, TOML).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackoffConfig {
    /// Wait after the first failed attempt in ms (default 100).
    #[serde(default = "default_initial_ms")]
    pub initial_ms: u64,
    /// Longest wait in ms, reached by doubling (default 5000).
    #[serde(default = "default_max_ms")]
    pub max_ms: u64,
}

fn default_initial_ms() -> u64 {
    100
}

fn default_max_ms() -> u64 {
    5000
}

impl Default for BackoffConfig {
    fn default() -> Self {
        Self {
            initial_ms: default_initial_ms(),
            max_ms: default_max_ms(),
        }
    }
}

impl BackoffConfig {
    /// Checks the bounds: `initial_ms` ≥ 1 and `max_ms` ≥ `initial_ms`.
    pub fn check(&self, key: &str) -> Result<(), ConfigError> {
        if self.initial_ms == 0 {
            return Err(ConfigError::new(
                format!("{key}.initial_ms"),
                "expected a wait of at least 1 ms",
            ));
        }
        if self.max_ms < self.initial_ms {
            return Err(ConfigError::new(
                format!("{key}.max_ms"),
                format!(
                    "expected at least initial_ms = {} ms, found {}",
                    self.initial_ms, self.max_ms
                ),
            ));
        }
        Ok(())
    }
}

/// Exponential backoff with a cap: the waits are `initial`, `2·initial`, `4·initial`, … up to
/// `max`, and start again at `initial` after [`Backoff::reset`].
#[derive(Debug, Clone)]
pub struct Backoff {
    config: BackoffConfig,
    next_ms: u64,
}

impl Backoff {
    /// A backoff whose next wait is `initial_ms`.
    pub fn new(config: BackoffConfig) -> Self {
        let initial = config.initial_ms.max(1);
        Self {
            config: BackoffConfig {
                initial_ms: initial,
                max_ms: config.max_ms.max(initial),
            },
            next_ms: initial,
        }
    }

    /// The wait before the next attempt; the one after it is twice as long, up to the cap.
    pub fn next_delay(&mut self) -> Duration {
        let now = self.next_ms;
        self.next_ms = now.saturating_mul(2).min(self.config.max_ms);
        Duration::from_millis(now)
    }

    /// After a successful connection: the next wait is `initial_ms` again.
    pub fn reset(&mut self) {
        self.next_ms = self.config.initial_ms;
    }
}

/// Sleeps `duration` in short slices, returning early (with `false`) once `stop` is set, so a
/// source thread always ends within about 20 ms of being asked to.
pub fn sleep_unless_stopped(duration: Duration, stop: &AtomicBool) -> bool {
    const SLICE: Duration = Duration::from_millis(20);
    let end = Instant::now() + duration;
    loop {
        if stop.load(Ordering::Acquire) {
            return false;
        }
        let now = Instant::now();
        if now >= end {
            return true;
        }
        std::thread::sleep((end - now).min(SLICE));
    }
}

/// Asks a source thread to stop and waits for it at most `limit`. A thread still busy after that
/// (inside a connection attempt, which std cannot interrupt) is left to end by itself: it holds
/// only shared state, checks `stop` as soon as the attempt returns, and nobody reads what it
/// publishes any more. So dropping a source never takes much longer than `limit`, whatever the
/// peer does. Returns whether the thread ended within the limit.
pub fn stop_thread(stop: &AtomicBool, thread: JoinHandle<()>, limit: Duration) -> bool {
    stop.store(true, Ordering::Release);
    let end = Instant::now() + limit;
    while !thread.is_finished() {
        if Instant::now() >= end {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = thread.join();
    true
}

/// How long dropping a network source waits for its thread (see [`stop_thread`]).
pub const STOP_LIMIT: Duration = Duration::from_millis(500);

/// Reads from `stream` until `buf` is full or `deadline` passes: the deadline covers the whole
/// answer, however the peer spreads its bytes. Waits in slices of at most 20 ms and gives up
/// with `Interrupted` once `stop` is set, so that a source thread stops promptly even while a
/// peer drips bytes. On a timeout the error is `TimedOut` and `filled` tells how many bytes came.
pub fn read_exact_until(
    stream: &mut std::net::TcpStream,
    buf: &mut [u8],
    deadline: Instant,
    stop: &AtomicBool,
    filled: &mut usize,
) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind, Read};
    const SLICE: Duration = Duration::from_millis(20);
    *filled = 0;
    while *filled < buf.len() {
        if stop.load(Ordering::Acquire) {
            return Err(Error::new(ErrorKind::Interrupted, "stopped"));
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(Error::new(ErrorKind::TimedOut, "timed out"));
        }
        stream.set_read_timeout(Some(
            (deadline - now).clamp(Duration::from_millis(1), SLICE),
        ))?;
        match stream.read(&mut buf[*filled..]) {
            Ok(0) => return Err(Error::new(ErrorKind::UnexpectedEof, "closed")),
            Ok(n) => *filled += n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// What happened on a link, for the event log and the status line.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkEvent {
    /// Service time in s.
    pub time_s: f64,
    /// What kind of event.
    pub kind: LinkEventKind,
    /// What happened, for a person.
    pub message: String,
}

/// The kinds of [`LinkEvent`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkEventKind {
    /// The connection is up.
    Connected,
    /// A connection attempt failed or an established connection was lost.
    Lost,
    /// Data arrived that could not be used (malformed line, Modbus exception, bad value); the
    /// channels concerned are not updated.
    BadData,
    /// The connection is up but the source does not deliver (every answer refused, only garbage,
    /// an adapter silent while answering PINGs): its channels go stale.
    Failing,
    /// The source delivers again on the same connection.
    Delivering,
}

/// The longest message a [`LinkEvent`] keeps (bytes; longer ones are cut), so that a peer
/// flooding long garbage cannot make the pending events grow beyond
/// `MAX_PENDING_EVENTS × MAX_EVENT_MESSAGE_BYTES`.
pub const MAX_EVENT_MESSAGE_BYTES: usize = 512;

/// The most events a link keeps before the oldest are dropped (and counted).
pub const MAX_PENDING_EVENTS: usize = 256;

/// The state of one link, shared by its thread (writer), the cycle (reads atomics and takes the
/// latest reason from a lock-free one-slot queue) and the status line (reads everything, off the
/// cycle).
#[derive(Debug)]
pub struct LinkStatus {
    connected: AtomicBool,
    /// Connected, but nothing usable arrives (see [`LinkEventKind::Failing`]).
    failing: AtomicBool,
    /// The reason of the latest loss or failure; the writer replaces it, the cycle takes it.
    reason: ArrayQueue<Reason>,
    /// Number of the current (or last) connection, 0 before the first.
    connections: AtomicU64,
    /// Failed attempts plus lost connections.
    failures: AtomicU64,
    /// Pieces of data that could not be used.
    bad_data: AtomicU64,
    /// Events dropped because nobody drained them.
    dropped_events: AtomicU64,
    events: Mutex<VecDeque<LinkEvent>>,
    last_error: Mutex<String>,
}

impl Default for LinkStatus {
    fn default() -> Self {
        Self {
            connected: AtomicBool::new(false),
            failing: AtomicBool::new(false),
            reason: ArrayQueue::new(1),
            connections: AtomicU64::new(0),
            failures: AtomicU64::new(0),
            bad_data: AtomicU64::new(0),
            dropped_events: AtomicU64::new(0),
            events: Mutex::new(VecDeque::new()),
            last_error: Mutex::new(String::new()),
        }
    }
}

/// A copy of a [`LinkStatus`] for the status line.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkSnapshot {
    /// Whether the connection is up.
    pub connected: bool,
    /// Whether the source fails to deliver although connected.
    pub failing: bool,
    /// Successful connections so far.
    pub connections: u64,
    /// Failed attempts plus lost connections.
    pub failures: u64,
    /// Pieces of data that could not be used.
    pub bad_data: u64,
    /// Events dropped because nobody drained them.
    pub dropped_events: u64,
    /// The last failure, empty if none.
    pub last_error: String,
}

impl LinkStatus {
    /// Whether the connection is up (lock-free; may be called on the cycle).
    pub fn is_connected(&self) -> bool {
        self.connected.load(Ordering::Acquire)
    }

    /// Whether the source fails to deliver although connected (lock-free).
    pub fn is_failing(&self) -> bool {
        self.failing.load(Ordering::Acquire)
    }

    /// Whether the source delivers: connected and not failing (lock-free).
    pub fn is_delivering(&self) -> bool {
        self.is_connected() && !self.is_failing()
    }

    /// Number of the current connection (lock-free), 0 before the first one.
    pub fn connection_number(&self) -> u64 {
        self.connections.load(Ordering::Acquire)
    }

    /// A copy of everything (takes short locks: not for the cycle).
    pub fn snapshot(&self) -> LinkSnapshot {
        LinkSnapshot {
            connected: self.is_connected(),
            failing: self.is_failing(),
            connections: self.connections.load(Ordering::Acquire),
            failures: self.failures.load(Ordering::Acquire),
            bad_data: self.bad_data.load(Ordering::Acquire),
            dropped_events: self.dropped_events.load(Ordering::Acquire),
            last_error: lock(&self.last_error).clone(),
        }
    }

    /// Takes the events recorded since the last call, oldest first (not for the cycle).
    pub fn drain_events(&self) -> Vec<LinkEvent> {
        lock(&self.events).drain(..).collect()
    }

    /// The source thread: the connection is up.
    pub fn set_connected(&self, time_s: f64, message: String) {
        self.connections.fetch_add(1, Ordering::AcqRel);
        self.failing.store(false, Ordering::Release);
        self.connected.store(true, Ordering::Release);
        self.push(time_s, LinkEventKind::Connected, message);
    }

    /// The source thread: an attempt failed or the connection was lost.
    pub fn set_lost(&self, time_s: f64, message: String) {
        // The reason first: a reader that sees the link down then finds it.
        self.reason.force_push(Reason::new(&message));
        self.connected.store(false, Ordering::Release);
        self.failures.fetch_add(1, Ordering::AcqRel);
        lock(&self.last_error).clone_from(&message);
        self.push(time_s, LinkEventKind::Lost, message);
    }

    /// The source thread: connected, but nothing usable arrives, for `message`'s reason. Call it
    /// when the reason appears or changes, not for every repetition.
    pub fn set_failing(&self, time_s: f64, message: String) {
        self.reason.force_push(Reason::new(&message));
        self.failing.store(true, Ordering::Release);
        lock(&self.last_error).clone_from(&message);
        self.push(time_s, LinkEventKind::Failing, message);
    }

    /// The source thread: usable data arrives again on the connection (no-op if not failing).
    pub fn set_delivering(&self, time_s: f64, message: String) {
        if self.failing.swap(false, Ordering::AcqRel) {
            self.push(time_s, LinkEventKind::Delivering, message);
        }
    }

    /// The source thread: received data that cannot be used.
    pub fn bad_data(&self, time_s: f64, message: String) {
        self.bad_data.fetch_add(1, Ordering::AcqRel);
        lock(&self.last_error).clone_from(&message);
        self.push(time_s, LinkEventKind::BadData, message);
    }

    fn push(&self, time_s: f64, kind: LinkEventKind, mut message: String) {
        if message.len() > MAX_EVENT_MESSAGE_BYTES {
            let mut cut = MAX_EVENT_MESSAGE_BYTES;
            while !message.is_char_boundary(cut) {
                cut -= 1;
            }
            message.truncate(cut);
            message.push('…');
        }
        let mut events = lock(&self.events);
        if events.len() >= MAX_PENDING_EVENTS {
            events.pop_front();
            self.dropped_events.fetch_add(1, Ordering::AcqRel);
        }
        events.push_back(LinkEvent {
            time_s,
            kind,
            message,
        });
    }

    /// The last failure or bad datum (not for the cycle).
    pub fn last_error(&self) -> String {
        lock(&self.last_error).clone()
    }
}

/// A poisoned lock only means another thread panicked while holding it; the data (events, a
/// message) stay usable.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Turns a link's state into the result of `Source::read` without allocating, locking or
/// blocking: `Ok` while the source delivers, otherwise `Disconnected` with the reason of the
/// latest loss or failure on every cycle (the service raises an event when it changes).
#[derive(Debug, Default)]
pub struct OutageReporter {
    reason: Reason,
}

impl OutageReporter {
    /// `Ok` while connected and delivering; `Err(Disconnected(reason))` otherwise.
    pub fn check(&mut self, status: &LinkStatus) -> Result<(), LinkError> {
        // The flags before the reason: the writer stores the reason before raising a flag.
        let delivering = status.is_delivering();
        if let Some(r) = status.reason.pop() {
            self.reason = r;
        }
        if delivering {
            return Ok(());
        }
        if self.reason.is_empty() {
            self.reason = Reason::new("not connected yet");
        }
        Err(LinkError::Disconnected(self.reason))
    }

    /// The reason last reported (empty before the first fault).
    pub fn reason(&self) -> Reason {
        self.reason
    }
}

/// A configuration mistake, naming the key and what was expected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    /// The key, e.g. `channel[2].register`.
    pub key: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl ConfigError {
    /// An error about `key`.
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.key, self.message)
    }
}

impl std::error::Error for ConfigError {}

/// The machine channel a received value feeds, resolved against the machine description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A temperature channel (index into `Machine::temperatures`), °C.
    Temperature(usize),
    /// An axis position (index into `Machine::axes`), mm or degrees.
    Position(usize),
    /// An operating-state channel (index into `Machine::operating`).
    Operating(usize),
}

impl Target {
    /// Resolves the configured channel names (exactly one of them must be given) against the
    /// machine; `key` names the configuration entry in errors.
    pub fn resolve(
        machine: &Machine,
        key: &str,
        temperature: Option<&str>,
        axis: Option<&str>,
        operating: Option<&str>,
    ) -> Result<Self, ConfigError> {
        let list = |names: Vec<&str>| names.join(", ");
        match (temperature, axis, operating) {
            (Some(id), None, None) => machine
                .temperature_index(id)
                .map(Target::Temperature)
                .ok_or_else(|| {
                    ConfigError::new(
                        format!("{key}.temperature"),
                        format!(
                            "expected a temperature channel of machine `{}` ({}), found `{id}`",
                            machine.name,
                            list(machine.temperatures.iter().map(|t| t.id.as_str()).collect())
                        ),
                    )
                }),
            (None, Some(name), None) => {
                machine
                    .axis_index(name)
                    .map(Target::Position)
                    .ok_or_else(|| {
                        ConfigError::new(
                            format!("{key}.axis"),
                            format!(
                                "expected an axis of machine `{}` ({}), found `{name}`",
                                machine.name,
                                list(machine.axes.iter().map(|a| a.name.as_str()).collect())
                            ),
                        )
                    })
            }
            (None, None, Some(id)) => machine
                .operating_index(id)
                .map(Target::Operating)
                .ok_or_else(|| {
                    ConfigError::new(
                        format!("{key}.operating"),
                        format!(
                            "expected an operating channel of machine `{}` ({}), found `{id}`",
                            machine.name,
                            list(machine.operating.iter().map(|o| o.id.as_str()).collect())
                        ),
                    )
                }),
            _ => Err(ConfigError::new(
                key,
                "expected exactly one of `temperature`, `axis` or `operating` naming the machine \
                 channel this value feeds",
            )),
        }
    }

    /// Writes a value and its stamp into the frame (no allocation; out-of-range indices are
    /// ignored, as the frame was built for the same machine).
    pub fn write(self, frame: &mut Frame, value: f64, stamp_s: f64) {
        let (values, stamps, i) = match self {
            Target::Temperature(i) => {
                (&mut frame.temperatures_c, &mut frame.temperature_stamp_s, i)
            }
            Target::Position(i) => (&mut frame.positions, &mut frame.position_stamp_s, i),
            Target::Operating(i) => (&mut frame.operating, &mut frame.operating_stamp_s, i),
        };
        if let (Some(v), Some(s)) = (values.get_mut(i), stamps.get_mut(i)) {
            *v = value;
            *s = stamp_s;
        }
    }
}

/// Refuses two configuration entries that feed the same machine channel.
pub fn check_unique_targets(targets: &[Target], keys: &[String]) -> Result<(), ConfigError> {
    for (j, t) in targets.iter().enumerate() {
        if let Some(i) = targets[..j].iter().position(|u| u == t) {
            return Err(ConfigError::new(
                keys[j].clone(),
                format!(
                    "expected each machine channel to be fed once; {} feeds the same one",
                    keys[i]
                ),
            ));
        }
    }
    Ok(())
}

/// The checks every network source's configuration shares, for its TOML `section`
/// (`modbus`, `shdr`): the address resolves, every time in `times_ms` (key, value) is at least
/// 1 ms, the backoff is sound and there is at least one of `channels` channels, each mapping
/// `what` to a machine channel. Returns the keys of the channels (`section.channel[1]`, …) for
/// their own errors.
pub fn check_source_config(
    section: &str,
    address: &str,
    times_ms: &[(&str, u64)],
    backoff: &BackoffConfig,
    channels: usize,
    what: &str,
) -> Result<Vec<String>, ConfigError> {
    resolve_address(address, &format!("{section}.address"))?;
    if let Some((key, _)) = times_ms.iter().find(|(_, v)| *v == 0) {
        return Err(ConfigError::new(
            format!("{section}.{key}"),
            "expected a time of at least 1 ms, found 0",
        ));
    }
    backoff.check(&format!("{section}.backoff"))?;
    if channels == 0 {
        return Err(ConfigError::new(
            format!("{section}.channel"),
            format!("expected at least one [[channel]] mapping {what} to a machine channel"),
        ));
    }
    Ok((1..=channels)
        .map(|i| format!("{section}.channel[{i}]"))
        .collect())
}

/// Resolves `host:port` to a socket address; `key` names the setting in errors.
pub fn resolve_address(address: &str, key: &str) -> Result<SocketAddr, ConfigError> {
    address
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| ConfigError::new(key, format!("expected host:port, found `{address}`")))
}

/// Seconds since `epoch` (the service clock when `epoch` is the service's start).
pub fn seconds_since(epoch: Instant) -> f64 {
    epoch.elapsed().as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_up_to_the_cap_and_resets() {
        let mut b = Backoff::new(BackoffConfig {
            initial_ms: 100,
            max_ms: 1000,
        });
        let waits: Vec<u64> = (0..7).map(|_| b.next_delay().as_millis() as u64).collect();
        // 100, 200, 400, 800, then capped at 1000.
        assert_eq!(waits, [100, 200, 400, 800, 1000, 1000, 1000]);
        b.reset();
        assert_eq!(b.next_delay(), Duration::from_millis(100));
    }

    #[test]
    fn backoff_config_bounds_are_checked() {
        let bad = BackoffConfig {
            initial_ms: 0,
            max_ms: 10,
        };
        assert_eq!(bad.check("backoff").unwrap_err().key, "backoff.initial_ms");
        let bad = BackoffConfig {
            initial_ms: 500,
            max_ms: 10,
        };
        let e = bad.check("backoff").unwrap_err();
        assert_eq!(
            e.to_string(),
            "backoff.max_ms: expected at least initial_ms = 500 ms, found 10"
        );
        assert!(BackoffConfig::default().check("backoff").is_ok());
    }

    #[test]
    fn sleep_stops_early_when_asked() {
        let stop = AtomicBool::new(true);
        let t = Instant::now();
        assert!(!sleep_unless_stopped(Duration::from_secs(10), &stop));
        assert!(t.elapsed() < Duration::from_secs(1));
        let go = AtomicBool::new(false);
        assert!(sleep_unless_stopped(Duration::from_millis(30), &go));
    }

    #[test]
    fn every_read_of_an_outage_carries_the_latest_reason() {
        let status = LinkStatus::default();
        let mut r = OutageReporter::default();
        let down =
            |why: &str| -> Result<(), LinkError> { Err(LinkError::Disconnected(why.into())) };
        assert_eq!(r.check(&status), down("not connected yet"));
        status.set_lost(1.0, "connection refused".into());
        assert_eq!(r.check(&status), down("connection refused"));
        assert_eq!(r.check(&status), down("connection refused"));
        status.set_connected(2.0, "up".into());
        assert_eq!(r.check(&status), Ok(()));
        status.set_lost(3.0, "no PONG".into());
        assert_eq!(r.check(&status), down("no PONG"));
        status.set_lost(3.5, "connection refused".into());
        assert_eq!(r.check(&status), down("connection refused"));
        // Connected but failing: not delivering, with the failure's reason.
        status.set_connected(4.0, "up".into());
        status.set_failing(4.1, "exception 02".into());
        assert_eq!(r.check(&status), down("exception 02"));
        status.set_delivering(4.2, "back".into());
        assert_eq!(r.check(&status), Ok(()));
        let events = status.drain_events();
        let kinds: Vec<_> = events.iter().map(|e| e.kind).collect();
        use LinkEventKind::*;
        assert_eq!(
            kinds,
            [Lost, Connected, Lost, Lost, Connected, Failing, Delivering]
        );
        assert!(status.drain_events().is_empty());
        let s = status.snapshot();
        assert_eq!((s.connected, s.connections, s.failures), (true, 2, 3));
        assert_eq!(s.last_error, "exception 02");
    }

    #[test]
    fn events_are_bounded() {
        let status = LinkStatus::default();
        for i in 0..MAX_PENDING_EVENTS + 10 {
            status.bad_data(i as f64, format!("bad {i}"));
        }
        let events = status.drain_events();
        assert_eq!(events.len(), MAX_PENDING_EVENTS);
        assert_eq!(events[0].message, "bad 10");
        assert_eq!(status.snapshot().dropped_events, 10);
    }

    #[test]
    fn targets_write_value_and_stamp() {
        let mut f = Frame::new(2, 3, 1);
        Target::Temperature(1).write(&mut f, 21.5, 4.0);
        Target::Position(2).write(&mut f, 120.0, 5.0);
        Target::Operating(0).write(&mut f, 8000.0, 6.0);
        Target::Position(9).write(&mut f, 1.0, 1.0); // ignored
        assert_eq!((f.temperatures_c[1], f.temperature_stamp_s[1]), (21.5, 4.0));
        assert_eq!((f.positions[2], f.position_stamp_s[2]), (120.0, 5.0));
        assert_eq!((f.operating[0], f.operating_stamp_s[0]), (8000.0, 6.0));
        assert!(f.temperatures_c[0].is_nan());
    }
}
