//! MTConnect SHDR input: a TCP client to an MTConnect adapter, reading axis positions
//! (`POSITION`, `ANGLE`) and temperatures (`TEMPERATURE`) from its SHDR lines.
//!
//! SHDR ("simple hierarchical data representation") is the line protocol between an MTConnect
//! adapter and an agent, as described by the MTConnect Institute's reference agent
//! documentation (cppagent, "Adapter Agent Protocol"): the adapter listens on TCP, and each line
//! it sends is `timestamp|dataItemId|value|dataItemId|value…`, with the value `UNAVAILABLE` when
//! it does not know it. An adapter sends a value when it changes (and all values when a client
//! connects). The client sends `* PING`; the adapter answers `* PONG <ms>`, announcing the
//! longest time the client should wait for the next answer. Lines starting with `*` are protocol
//! commands (`* shdrVersion: 2`).
//!
//! [`parse_line`] is a pure function: every malformed line gives an [`ShdrError`], never a
//! panic (property-tested with a million inputs, `tests/fuzz_network.rs`).
//!
//! [`ShdrSource`] runs the client on its own thread and implements [`Source`]. The stamp of a
//! value is the last time the adapter confirmed it: when it arrived, or later when any line or
//! `PONG` arrived on the same connection (an adapter only re-sends changed values, so a live
//! connection confirms the unchanged ones). When the connection is lost — the socket closes, or
//! no `PONG` comes within the announced interval after a `PING` — the stamps stop advancing and
//! the client reconnects with backoff ([`crate::reconnect`]).
//!
//! Limits: data items are read as `id|value` pairs, so CONDITION (six fields), MESSAGE and
//! time-series items must be on lines of their own (as adapters usually send them); a line whose
//! pairing fails is reported as bad data and skipped. Multi-line assets (`--multiline--`) are
//! skipped. The adapter's timestamp is not used: values are stamped on the service clock when
//! they arrive.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::Deserialize;
use truepos_model::Machine;

use crate::frame::{Frame, NEVER};
use crate::io_traits::{LinkError, SharedChannels, Source};
use crate::reconnect::{
    check_source_config, check_unique_targets, resolve_address, seconds_since,
    sleep_unless_stopped, stop_thread, Backoff, BackoffConfig, ConfigError, LinkSnapshot,
    LinkStatus, OutageReporter, Target, STOP_LIMIT,
};

/// One line from an adapter.
#[derive(Debug, Clone, PartialEq)]
pub enum ShdrLine<'a> {
    /// Data: the adapter's timestamp (possibly empty) and the items of the line.
    Data {
        /// The first field as sent (ISO 8601 time, possibly with `@duration`, or empty).
        timestamp: &'a str,
        /// `dataItemId|value` pairs in line order.
        items: Vec<ShdrItem<'a>>,
    },
    /// `* PONG <ms>`: the adapter is alive and announces its heartbeat interval in ms.
    Pong {
        /// The announced interval in ms (≥ 1).
        interval_ms: u64,
    },
    /// Any other protocol line, `* name: value` or `* name value` (e.g. `* shdrVersion: 2`).
    Command {
        /// The command's name.
        name: &'a str,
        /// The rest of the line, trimmed (may be empty).
        value: &'a str,
    },
}

/// One `dataItemId|value` pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShdrItem<'a> {
    /// The data item's id (or name) in the adapter's device model.
    pub id: &'a str,
    /// Its value.
    pub value: ShdrValue<'a>,
}

/// The value of a data item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ShdrValue<'a> {
    /// A finite number (a POSITION in mm, ANGLE in degrees, TEMPERATURE in °C).
    Number(f64),
    /// `UNAVAILABLE`: the adapter does not know the value.
    Unavailable,
    /// Anything else (an event's text, or a number that is not finite), trimmed.
    Text(&'a str),
}

/// Why a line cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShdrError {
    /// The line is empty or only white space.
    Empty,
    /// A data line without any `|`.
    NoItems,
    /// A data item id without a value (the line has an even number of fields).
    MissingValue {
        /// The id left without a value.
        id: String,
    },
    /// An empty data item id.
    EmptyId {
        /// 1-based field number in the line (the timestamp is field 1).
        field: usize,
    },
    /// `* PONG` without a positive whole number of ms.
    BadPong {
        /// What followed `PONG`.
        found: String,
    },
    /// A `*` line without a command name.
    EmptyCommand,
}

impl std::fmt::Display for ShdrError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Empty => write!(f, "empty line; expected timestamp|dataItemId|value…"),
            Self::NoItems => {
                write!(
                    f,
                    "expected timestamp|dataItemId|value…, found no `|` in the line"
                )
            }
            Self::MissingValue { id } => write!(
                f,
                "expected dataItemId|value pairs after the timestamp; data item `{id}` has no value"
            ),
            Self::EmptyId { field } => {
                write!(
                    f,
                    "expected a data item id in field {field}, found an empty field"
                )
            }
            Self::BadPong { found } => write!(
                f,
                "expected `* PONG <interval in ms>` with a whole number ≥ 1, found `{found}`"
            ),
            Self::EmptyCommand => write!(f, "expected a command after `*`, found nothing"),
        }
    }
}

impl std::error::Error for ShdrError {}

/// Reads one SHDR line (with or without its line end). Pure; never panics.
///
/// ```
/// use truepos_runtime::shdr::{parse_line, ShdrLine, ShdrValue};
/// let line = parse_line("2024-05-01T10:00:00.000Z|Xact|125.5|Tspindle|UNAVAILABLE\r\n").unwrap();
/// let ShdrLine::Data { items, .. } = line else { panic!() };
/// assert_eq!(items[0].value, ShdrValue::Number(125.5));
/// assert_eq!(items[1].value, ShdrValue::Unavailable);
/// assert_eq!(parse_line("* PONG 10000").unwrap(), ShdrLine::Pong { interval_ms: 10000 });
/// ```
pub fn parse_line(line: &str) -> Result<ShdrLine<'_>, ShdrError> {
    let line = line.trim_end_matches(['\r', '\n']);
    if line.trim().is_empty() {
        return Err(ShdrError::Empty);
    }
    if let Some(command) = line.strip_prefix('*') {
        return parse_command(command.trim());
    }
    let mut fields = line.split('|');
    // `split` always yields a first field.
    let timestamp = fields.next().unwrap_or_default().trim();
    let mut items = Vec::new();
    let mut field = 1;
    while let Some(id) = fields.next() {
        field += 1;
        let id = id.trim();
        let Some(value) = fields.next() else {
            return Err(ShdrError::MissingValue { id: id.to_string() });
        };
        if id.is_empty() {
            return Err(ShdrError::EmptyId { field });
        }
        field += 1;
        items.push(ShdrItem {
            id,
            value: parse_value(value),
        });
    }
    if items.is_empty() {
        return Err(ShdrError::NoItems);
    }
    Ok(ShdrLine::Data { timestamp, items })
}

fn parse_command(command: &str) -> Result<ShdrLine<'_>, ShdrError> {
    let (name, value) = match command.find([':', ' ', '\t']) {
        Some(i) => (&command[..i], command[i + 1..].trim()),
        None => (command, ""),
    };
    let name = name.trim();
    if name.is_empty() {
        return Err(ShdrError::EmptyCommand);
    }
    if name == "PONG" {
        return match value.parse::<u64>() {
            Ok(ms) if ms >= 1 => Ok(ShdrLine::Pong { interval_ms: ms }),
            _ => Err(ShdrError::BadPong {
                found: value.to_string(),
            }),
        };
    }
    Ok(ShdrLine::Command { name, value })
}

/// A value field: `UNAVAILABLE`, a finite number, or text.
pub fn parse_value(field: &str) -> ShdrValue<'_> {
    let text = field.trim();
    if text == "UNAVAILABLE" {
        return ShdrValue::Unavailable;
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => ShdrValue::Number(x),
        _ => ShdrValue::Text(text),
    }
}

/// The longest line the client accepts, in bytes; a longer one is a protocol error and ends the
/// connection.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Splits a byte stream into lines (`\n`, with an optional `\r`), across reads.
#[derive(Debug, Default)]
pub struct LineBuffer {
    pending: Vec<u8>,
}

impl LineBuffer {
    /// Appends received bytes and calls `line` for each complete line (as bytes, without its
    /// end). Fails when a line exceeds [`MAX_LINE_BYTES`]; the buffer is then cleared.
    pub fn push(&mut self, bytes: &[u8], mut line: impl FnMut(&[u8])) -> Result<(), String> {
        self.pending.extend_from_slice(bytes);
        let mut start = 0;
        while let Some(n) = self.pending[start..].iter().position(|&b| b == b'\n') {
            let end = start + n;
            let body = &self.pending[start..end];
            line(body.strip_suffix(b"\r").unwrap_or(body));
            start = end + 1;
        }
        self.pending.drain(..start);
        if self.pending.len() > MAX_LINE_BYTES {
            let n = self.pending.len();
            self.pending.clear();
            return Err(format!(
                "expected lines of at most {MAX_LINE_BYTES} bytes, found {n} bytes without a line end"
            ));
        }
        Ok(())
    }

    /// Bytes of the line under way (received, no line end yet).
    pub fn pending_len(&self) -> usize {
        self.pending.len()
    }

    /// Bytes the buffer holds room for (bounded: about [`MAX_LINE_BYTES`] plus one read).
    pub fn capacity(&self) -> usize {
        self.pending.capacity()
    }
}

/// One SHDR data item feeding one machine channel (configuration, TOML). Give exactly one of
/// `temperature`, `axis` or `operating`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShdrChannelConfig {
    /// The adapter's dataItemId (e.g. `Xact`, `Tspindle`).
    pub data_item: String,
    /// Machine temperature channel id (°C).
    #[serde(default)]
    pub temperature: Option<String>,
    /// Machine axis name (position in mm or degrees).
    #[serde(default)]
    pub axis: Option<String>,
    /// Machine operating channel id.
    #[serde(default)]
    pub operating: Option<String>,
}

/// An MTConnect SHDR source (configuration, TOML).
///
/// ```toml
/// address = "127.0.0.1:7878"
/// [[channel]]
/// data_item = "Xact"
/// axis = "X"
/// [[channel]]
/// data_item = "Tspindle"
/// temperature = "spindle_front_bearing"
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShdrConfig {
    /// The adapter's `host:port`.
    pub address: String,
    /// Longest wait for a TCP connection in ms (default 2000).
    #[serde(default = "default_connect_timeout_ms")]
    pub connect_timeout_ms: u64,
    /// The client sends `* PING` this often in ms (default 1000), or at the adapter's announced
    /// interval if that is shorter; every answer confirms the values of the connection.
    #[serde(default = "default_ping_ms")]
    pub ping_ms: u64,
    /// Longest wait for the first `* PONG` in ms, before the adapter has announced its interval
    /// (default 5000). Afterwards the announced interval is the limit.
    #[serde(default = "default_first_pong_ms")]
    pub first_pong_timeout_ms: u64,
    /// Longest time in ms a line may take from its first byte to its end (default 1000); an
    /// adapter dripping a line more slowly loses the connection.
    #[serde(default = "default_line_timeout_ms")]
    pub line_timeout_ms: u64,
    /// Longest time in ms without a usable data line while the adapter still answers `* PING`
    /// (default 300 000, the validator's default stuck-value limit): after it, the source counts
    /// as failing and PONGs no longer confirm its values.
    #[serde(default = "default_data_timeout_ms")]
    pub data_timeout_ms: u64,
    /// Reconnection waits.
    #[serde(default)]
    pub backoff: BackoffConfig,
    /// Which data item feeds which machine channel.
    #[serde(rename = "channel")]
    pub channels: Vec<ShdrChannelConfig>,
}

fn default_connect_timeout_ms() -> u64 {
    2000
}
fn default_ping_ms() -> u64 {
    1000
}
fn default_first_pong_ms() -> u64 {
    5000
}
fn default_line_timeout_ms() -> u64 {
    1000
}
fn default_data_timeout_ms() -> u64 {
    300_000
}

/// Unusable lines in a row (no usable data line between them) after which the source counts as
/// failing: the adapter sends garbage only.
pub const MAX_BAD_LINES_IN_ROW: u32 = 3;

/// `* PONG`s without a `* PING` after which the connection is dropped as a PONG flood.
pub const MAX_UNSOLICITED_PONGS: u32 = 8;

impl ShdrConfig {
    /// Reads the configuration from TOML text (a table with the fields above).
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::new("shdr", e.to_string()))
    }

    /// Reads the configuration from a TOML file; errors name the file (and, for TOML mistakes,
    /// the line and column).
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            ConfigError::new(
                &file,
                format!("cannot read the SHDR source configuration: {e}"),
            )
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::new(file, e.to_string()))
    }

    /// Checks the bounds and resolves the channels against the machine.
    pub fn resolve(&self, machine: &Machine) -> Result<Vec<Target>, ConfigError> {
        let keys = check_source_config(
            "shdr",
            &self.address,
            &[
                ("connect_timeout_ms", self.connect_timeout_ms),
                ("ping_ms", self.ping_ms),
                ("first_pong_timeout_ms", self.first_pong_timeout_ms),
                ("line_timeout_ms", self.line_timeout_ms),
                ("data_timeout_ms", self.data_timeout_ms),
            ],
            &self.backoff,
            self.channels.len(),
            "a data item",
        )?;
        let mut targets = Vec::with_capacity(self.channels.len());
        for (c, key) in self.channels.iter().zip(&keys) {
            if c.data_item.trim().is_empty() || c.data_item.contains('|') {
                return Err(ConfigError::new(
                    format!("{key}.data_item"),
                    format!("expected a dataItemId without `|`, found `{}`", c.data_item),
                ));
            }
            targets.push(Target::resolve(
                machine,
                key,
                c.temperature.as_deref(),
                c.axis.as_deref(),
                c.operating.as_deref(),
            )?);
        }
        check_unique_targets(&targets, &keys)?;
        Ok(targets)
    }
}

/// What the client thread and the cycle share.
#[derive(Debug)]
struct Shared {
    channels: Arc<SharedChannels>,
    /// Per channel, the connection number its value arrived on.
    value_connection: Vec<AtomicU64>,
    /// Service time of the last line or PONG on the current connection (f64 bits).
    alive_s: AtomicU64,
    status: LinkStatus,
    stop: AtomicBool,
}

/// An MTConnect SHDR source: a client thread connected to an adapter, and the cycle's view of
/// the values it received.
#[derive(Debug)]
pub struct ShdrSource {
    name: String,
    targets: Vec<Target>,
    shared: Arc<Shared>,
    outage: OutageReporter,
    thread: Option<JoinHandle<()>>,
}

impl ShdrSource {
    /// Starts the client thread for a checked configuration. `epoch` is the service clock's
    /// zero: stamps are seconds since it.
    pub fn start(
        config: &ShdrConfig,
        machine: &Machine,
        epoch: Instant,
    ) -> Result<Self, ConfigError> {
        let targets = config.resolve(machine)?;
        let n = targets.len();
        let shared = Arc::new(Shared {
            channels: SharedChannels::new(n),
            value_connection: (0..n).map(|_| AtomicU64::new(0)).collect(),
            alive_s: AtomicU64::new(NEVER.to_bits()),
            status: LinkStatus::default(),
            stop: AtomicBool::new(false),
        });
        let mut by_id: HashMap<String, Vec<usize>> = HashMap::new();
        for (k, c) in config.channels.iter().enumerate() {
            by_id
                .entry(c.data_item.trim().to_string())
                .or_default()
                .push(k);
        }
        let client = Client {
            config: config.clone(),
            by_id,
            shared: Arc::clone(&shared),
            epoch,
        };
        let name = format!("shdr {}", config.address);
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || client.run())
            .map_err(|e| {
                ConfigError::new("shdr", format!("cannot start the client thread: {e}"))
            })?;
        Ok(Self {
            name,
            targets,
            shared,
            outage: OutageReporter::default(),
            thread: Some(thread),
        })
    }

    /// The link's state for the status line.
    pub fn status(&self) -> LinkSnapshot {
        self.shared.status.snapshot()
    }

    /// The link's state, including its events to drain (off the cycle).
    pub fn link(&self) -> &LinkStatus {
        &self.shared.status
    }

    /// The machine channels this source feeds, in configuration order.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }
}

impl Source for ShdrSource {
    fn name(&self) -> &str {
        &self.name
    }

    /// Copies the latest values with their confirmation stamps (atomics only, no allocation; see
    /// [`OutageReporter`] for an outage's first read). A value that arrived after the frame's
    /// clock reading is stamped with the frame's time: stamps never lie after `frame.time_s`.
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let current = self.shared.status.connection_number();
        let alive = f64::from_bits(self.shared.alive_s.load(Ordering::Acquire));
        for (k, target) in self.targets.iter().enumerate() {
            let (value, stamp) = self.shared.channels.get(k);
            let confirmed = if self.shared.value_connection[k].load(Ordering::Acquire) == current {
                stamp.max(alive)
            } else {
                stamp
            };
            target.write(frame, value, confirmed.min(frame.time_s));
        }
        self.outage.check(&self.shared.status)
    }
}

impl Drop for ShdrSource {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            stop_thread(&self.shared.stop, t, STOP_LIMIT);
        }
    }
}

/// The client thread.
struct Client {
    config: ShdrConfig,
    by_id: HashMap<String, Vec<usize>>,
    shared: Arc<Shared>,
    epoch: Instant,
}

/// How a connection ended.
enum End {
    Stopped,
    Lost(String),
}

impl Client {
    fn now_s(&self) -> f64 {
        seconds_since(self.epoch)
    }

    fn run(self) {
        let mut backoff = Backoff::new(self.config.backoff);
        let status = &self.shared.status;
        while !self.shared.stop.load(Ordering::Acquire) {
            match self.connect() {
                Ok(stream) => {
                    backoff.reset();
                    status.set_connected(
                        self.now_s(),
                        format!("connected to {}", self.config.address),
                    );
                    match self.serve(stream) {
                        End::Stopped => return,
                        End::Lost(why) => {
                            self.freeze_confirmations();
                            status.set_lost(self.now_s(), why)
                        }
                    }
                }
                Err(why) => status.set_lost(self.now_s(), why),
            }
            if !sleep_unless_stopped(backoff.next_delay(), &self.shared.stop) {
                return;
            }
        }
    }

    /// At the end of a connection: the values it delivered keep, as their stamps, the last time
    /// it confirmed them (later connections do not confirm them; stamps never go backwards).
    fn freeze_confirmations(&self) {
        let connection = self.shared.status.connection_number();
        let alive = f64::from_bits(self.shared.alive_s.load(Ordering::Acquire));
        for (k, c) in self.shared.value_connection.iter().enumerate() {
            if c.load(Ordering::Acquire) == connection {
                let (value, stamp) = self.shared.channels.get(k);
                self.shared.channels.publish(k, value, stamp.max(alive));
            }
        }
    }

    fn connect(&self) -> Result<TcpStream, String> {
        let address =
            resolve_address(&self.config.address, "shdr.address").map_err(|e| e.message)?;
        let stream = TcpStream::connect_timeout(
            &address,
            Duration::from_millis(self.config.connect_timeout_ms),
        )
        .map_err(|e| format!("cannot connect to adapter {address}: {e}"))?;
        stream
            .set_read_timeout(Some(Duration::from_millis(20)))
            .and_then(|_| stream.set_write_timeout(Some(Duration::from_millis(500))))
            .and_then(|_| stream.set_nodelay(true))
            .map_err(|e| format!("cannot set up the connection to {address}: {e}"))?;
        Ok(stream)
    }

    /// Reads lines and keeps the heartbeat until the connection ends.
    fn serve(&self, mut stream: TcpStream) -> End {
        let connection = self.shared.status.connection_number();
        let address = &self.config.address;
        let mut lines = LineBuffer::default();
        let mut chunk = [0u8; 4096];
        // The limit for the PONG we wait for: the configured one until the adapter announces its
        // interval.
        let mut pong_limit = Duration::from_millis(self.config.first_pong_timeout_ms);
        let mut ping_every = Duration::from_millis(self.config.ping_ms);
        let mut outstanding: Option<Instant> = None;
        let mut last_ping: Option<Instant> = None;
        let mut skip_until: Option<String> = None;
        let mut health = Health::new(Instant::now());
        loop {
            if self.shared.stop.load(Ordering::Acquire) {
                return End::Stopped;
            }
            let now = Instant::now();
            if let Some(sent) = outstanding {
                if now.duration_since(sent) > pong_limit {
                    return End::Lost(format!(
                        "no `* PONG` from {address} within {} ms of `* PING`",
                        pong_limit.as_millis()
                    ));
                }
            } else if last_ping.is_none_or(|t| now.duration_since(t) >= ping_every) {
                if let Err(e) = stream.write_all(b"* PING\n") {
                    return End::Lost(format!("cannot send `* PING` to {address}: {e}"));
                }
                outstanding = Some(now);
                last_ping = Some(now);
                health.unsolicited_pongs = 0;
            }
            if let Some(why) = health.overdue(now, &self.config) {
                return End::Lost(why);
            }
            if health.failing.is_none()
                && now.duration_since(health.last_data).as_millis()
                    > u128::from(self.config.data_timeout_ms)
            {
                health.fail(
                    &self.shared.status,
                    self.now_s(),
                    Failing::Silent,
                    format!(
                        "adapter {address} sent no data for {} ms while answering `* PING`",
                        self.config.data_timeout_ms
                    ),
                );
            }
            let n = match stream.read(&mut chunk) {
                Ok(0) => return End::Lost(format!("adapter {address} closed the connection")),
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    continue
                }
                Err(e) => return End::Lost(format!("cannot read from adapter {address}: {e}")),
            };
            let mut pong: Option<u64> = None;
            let mut complete = false;
            let pushed = lines.push(&chunk[..n], |bytes| {
                complete = true;
                match self.handle_line(bytes, connection, &mut skip_until) {
                    Line::Pong(ms) if outstanding.take().is_some() => pong = Some(ms),
                    Line::Pong(_) => health.unsolicited_pongs += 1,
                    Line::Data => health.data(&self.shared.status, self.now_s(), address),
                    Line::Bad(why) => health.bad(&self.shared.status, self.now_s(), address, why),
                    Line::Other => {}
                }
            });
            if let Err(why) = pushed {
                return End::Lost(format!("adapter {address}: {why}"));
            }
            health.track_partial(Instant::now(), complete, lines.pending_len());
            if health.unsolicited_pongs > MAX_UNSOLICITED_PONGS {
                return End::Lost(format!(
                    "adapter {address} sent {} `* PONG` without a `* PING` (a PONG flood)",
                    health.unsolicited_pongs
                ));
            }
            if let Some(ms) = pong {
                // A PONG confirms the values only while the adapter also delivers data.
                if health.failing.is_none() {
                    self.shared
                        .alive_s
                        .store(self.now_s().to_bits(), Ordering::Release);
                }
                pong_limit = Duration::from_millis(ms);
                ping_every = Duration::from_millis(self.config.ping_ms.min(ms));
            }
        }
    }

    /// Handles one complete line: publishes its values, reports what cannot be used.
    fn handle_line(&self, bytes: &[u8], connection: u64, skip_until: &mut Option<String>) -> Line {
        let now = self.now_s();
        let status = &self.shared.status;
        let address = &self.config.address;
        let Ok(text) = std::str::from_utf8(bytes) else {
            let why = format!("adapter {address}: a line is not UTF-8 text");
            status.bad_data(now, why.clone());
            return Line::Bad(why);
        };
        if let Some(marker) = skip_until.as_deref() {
            if text.trim() == marker {
                *skip_until = None;
            }
            return Line::Other;
        }
        if text.trim().is_empty() {
            return Line::Other;
        }
        match parse_line(text) {
            Ok(ShdrLine::Pong { interval_ms }) => Line::Pong(interval_ms),
            Ok(ShdrLine::Command { .. }) => Line::Other,
            Ok(ShdrLine::Data { items, .. }) => {
                for item in &items {
                    if let ShdrValue::Text(t) = item.value {
                        if t.starts_with("--multiline--") {
                            *skip_until = Some(t.to_string());
                        }
                    }
                    let Some(ks) = self.by_id.get(item.id) else {
                        continue;
                    };
                    let value = match item.value {
                        ShdrValue::Number(x) => x,
                        ShdrValue::Unavailable => f64::NAN,
                        ShdrValue::Text(t) => {
                            status.bad_data(
                                now,
                                format!(
                                    "adapter {address}: data item `{}`: expected a number or UNAVAILABLE, found `{t}`",
                                    item.id
                                ),
                            );
                            f64::NAN
                        }
                    };
                    for &k in ks {
                        self.shared.channels.publish(k, value, now);
                        self.shared.value_connection[k].store(connection, Ordering::Release);
                    }
                }
                self.shared.alive_s.store(now.to_bits(), Ordering::Release);
                Line::Data
            }
            Err(e) => {
                let why = format!("adapter {address}: {e}");
                status.bad_data(now, why.clone());
                Line::Bad(why)
            }
        }
    }
}

/// What a complete line was, for the health of the connection.
enum Line {
    /// `* PONG` with its announced interval in ms.
    Pong(u64),
    /// A data line (its values published).
    Data,
    /// An unusable line, with the reason.
    Bad(String),
    /// A command, an empty line or part of a skipped asset.
    Other,
}

/// Why a connected adapter counts as not delivering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Failing {
    /// Only unusable lines arrive.
    Garbage,
    /// No data line for `data_timeout_ms`, while PONGs still come.
    Silent,
}

/// What the connection delivered lately: whether it counts as failing, and the deadlines of a
/// line under way.
struct Health {
    last_data: Instant,
    bad_in_row: u32,
    unsolicited_pongs: u32,
    /// When the first byte of the line under way arrived.
    partial_since: Option<Instant>,
    partial_bytes: usize,
    failing: Option<Failing>,
}

impl Health {
    fn new(now: Instant) -> Self {
        Self {
            last_data: now,
            bad_in_row: 0,
            unsolicited_pongs: 0,
            partial_since: None,
            partial_bytes: 0,
            failing: None,
        }
    }

    fn fail(&mut self, status: &LinkStatus, now_s: f64, kind: Failing, why: String) {
        if self.failing != Some(kind) {
            self.failing = Some(kind);
            status.set_failing(now_s, why);
        }
    }

    fn data(&mut self, status: &LinkStatus, now_s: f64, address: &str) {
        self.last_data = Instant::now();
        self.bad_in_row = 0;
        if self.failing.take().is_some() {
            status.set_delivering(now_s, format!("adapter {address} sends data again"));
        }
    }

    fn bad(&mut self, status: &LinkStatus, now_s: f64, address: &str, why: String) {
        self.bad_in_row = self.bad_in_row.saturating_add(1);
        if self.bad_in_row >= MAX_BAD_LINES_IN_ROW {
            let last = why
                .strip_prefix(&format!("adapter {address}: "))
                .unwrap_or(&why);
            let message = format!("garbage only ({} lines in a row): {last}", self.bad_in_row);
            self.fail(status, now_s, Failing::Garbage, message);
        }
    }

    /// After a chunk: the line under way started in this chunk if a line ended in it, else
    /// when its first byte came.
    fn track_partial(&mut self, now: Instant, line_ended: bool, pending: usize) {
        self.partial_bytes = pending;
        if pending == 0 {
            self.partial_since = None;
        } else if line_ended || self.partial_since.is_none() {
            self.partial_since = Some(now);
        }
    }

    /// A line under way for longer than `line_timeout_ms` ends the connection.
    fn overdue(&self, now: Instant, config: &ShdrConfig) -> Option<String> {
        let since = self.partial_since?;
        let limit = Duration::from_millis(config.line_timeout_ms);
        (now.duration_since(since) > limit).then(|| {
            format!(
                "adapter {}: a line took longer than {} ms ({} bytes without a line end)",
                config.address, config.line_timeout_ms, self.partial_bytes
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(line: &str) -> Vec<ShdrItem<'_>> {
        match parse_line(line) {
            Ok(ShdrLine::Data { items, .. }) => items,
            other => panic!("expected data from {line:?}, got {other:?}"),
        }
    }

    #[test]
    fn data_lines() {
        let items = data("2024-05-01T10:00:00.123456Z|Xact|125.500|Tspindle|24.1\n");
        assert_eq!(items.len(), 2);
        assert_eq!(
            items[0],
            ShdrItem {
                id: "Xact",
                value: ShdrValue::Number(125.5)
            }
        );
        assert_eq!(
            items[1],
            ShdrItem {
                id: "Tspindle",
                value: ShdrValue::Number(24.1)
            }
        );
        // Empty timestamp, CRLF, spaces around fields, negative and exponent numbers.
        let items = data("| Zact | -3.5e1 |exec|ACTIVE|T1|UNAVAILABLE\r\n");
        assert_eq!(items[0].value, ShdrValue::Number(-35.0));
        assert_eq!(items[1].value, ShdrValue::Text("ACTIVE"));
        assert_eq!(items[2].value, ShdrValue::Unavailable);
        // An empty value is text, not a number; non-finite numbers are text too.
        assert_eq!(data("t|a|")[0].value, ShdrValue::Text(""));
        assert_eq!(data("t|a|NaN|b|inf")[0].value, ShdrValue::Text("NaN"));
        assert_eq!(data("t|a|NaN|b|inf")[1].value, ShdrValue::Text("inf"));
        match parse_line("2024-05-01T10:00:00Z@100.0|x|1").unwrap() {
            ShdrLine::Data { timestamp, .. } => assert_eq!(timestamp, "2024-05-01T10:00:00Z@100.0"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn protocol_lines() {
        assert_eq!(
            parse_line("* PONG 10000\r\n"),
            Ok(ShdrLine::Pong { interval_ms: 10000 })
        );
        assert_eq!(
            parse_line("*PONG 250"),
            Ok(ShdrLine::Pong { interval_ms: 250 })
        );
        assert_eq!(
            parse_line("* shdrVersion: 2"),
            Ok(ShdrLine::Command {
                name: "shdrVersion",
                value: "2"
            })
        );
        assert_eq!(
            parse_line("* PING"),
            Ok(ShdrLine::Command {
                name: "PING",
                value: ""
            })
        );
    }

    #[test]
    fn malformed_lines_are_errors_naming_the_problem() {
        assert_eq!(parse_line(""), Err(ShdrError::Empty));
        assert_eq!(parse_line(" \r\n"), Err(ShdrError::Empty));
        assert_eq!(parse_line("2024-05-01T10:00:00Z"), Err(ShdrError::NoItems));
        assert_eq!(
            parse_line("t|Xact|1|Yact"),
            Err(ShdrError::MissingValue { id: "Yact".into() })
        );
        assert_eq!(parse_line("t||1"), Err(ShdrError::EmptyId { field: 2 }));
        assert_eq!(
            parse_line("t|a|1| |2"),
            Err(ShdrError::EmptyId { field: 4 })
        );
        assert_eq!(
            parse_line("* PONG"),
            Err(ShdrError::BadPong { found: "".into() })
        );
        assert_eq!(
            parse_line("* PONG 0"),
            Err(ShdrError::BadPong { found: "0".into() })
        );
        assert_eq!(
            parse_line("* PONG -5"),
            Err(ShdrError::BadPong { found: "-5".into() })
        );
        assert_eq!(parse_line("*  "), Err(ShdrError::EmptyCommand));
        assert_eq!(
            ShdrError::MissingValue { id: "Yact".into() }.to_string(),
            "expected dataItemId|value pairs after the timestamp; data item `Yact` has no value"
        );
    }

    #[test]
    fn line_buffer_splits_across_reads() {
        let mut b = LineBuffer::default();
        let mut got: Vec<String> = Vec::new();
        b.push(b"t|a|1\r\nt|b", |l| {
            got.push(String::from_utf8_lossy(l).into())
        })
        .unwrap();
        assert_eq!(got, ["t|a|1"]);
        b.push(b"|2\n\n* PONG 5\n", |l| {
            got.push(String::from_utf8_lossy(l).into())
        })
        .unwrap();
        assert_eq!(got, ["t|a|1", "t|b|2", "", "* PONG 5"]);
        let long = vec![b'x'; MAX_LINE_BYTES + 1];
        assert!(b.push(&long, |_| {}).is_err());
        b.push(b"ok\n", |l| assert_eq!(l, b"ok")).unwrap();
    }

    #[test]
    fn config_defaults_and_errors() {
        let c = ShdrConfig::from_toml(
            "address = \"127.0.0.1:7878\"\n[[channel]]\ndata_item = \"Xact\"\naxis = \"X\"\n",
        )
        .unwrap();
        assert_eq!(
            (c.connect_timeout_ms, c.ping_ms, c.first_pong_timeout_ms),
            (2000, 1000, 5000)
        );
        assert_eq!(c.backoff, BackoffConfig::default());
        let e = ShdrConfig::from_toml("address = \"a\"\nchannels = []").unwrap_err();
        assert!(e.message.contains("unknown field `channels`"), "{e}");
    }
}
