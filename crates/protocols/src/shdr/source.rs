//! The SHDR source: its client thread (connection, heartbeat, line handling, the health of a
//! connection), hosted by a [`PolledSource`] that gives the cycle the values it received.

use std::cell::Cell;
use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use truepos_model::Machine;

use super::config::ShdrConfig;
use super::parse::{parse_line, LineBuffer, ShdrLine, ShdrValue};
use truepos_files::InputError;
use truepos_runtime::sources::{
    resolve_address, seconds_since, sleep_unless_stopped, Backoff, Link, LinkStatus, PolledSource,
    STOP_LIMIT,
};

/// Unusable lines in a row (no usable data line between them) after which the source counts as
/// failing: the adapter sends garbage only.
pub const MAX_BAD_LINES_IN_ROW: u32 = 3;

/// `* PONG`s without a `* PING` after which the connection is dropped as a PONG flood.
pub const MAX_UNSOLICITED_PONGS: u32 = 8;

/// An MTConnect SHDR source: [`ShdrSource::start`] gives its client thread to a
/// [`PolledSource`], the cycle's view of the values it received. The stamp of a value is the
/// last time the adapter confirmed it: the thread re-stamps every value of the live connection
/// whenever a data line arrives on it, or a `PONG` while it is not failing.
#[derive(Debug)]
pub struct ShdrSource;

impl ShdrSource {
    /// Starts the client thread for a checked configuration. `epoch` is the service clock's
    /// zero: stamps are seconds since it.
    pub fn start(
        config: &ShdrConfig,
        machine: &Machine,
        epoch: Instant,
    ) -> Result<PolledSource, InputError> {
        let targets = config.resolve(machine)?;
        let n = targets.len();
        let mut by_id: HashMap<String, Vec<usize>> = HashMap::new();
        for (k, c) in config.channels.iter().enumerate() {
            by_id
                .entry(c.data_item.trim().to_string())
                .or_default()
                .push(k);
        }
        let config = config.clone();
        let name = format!("shdr {}", config.address);
        PolledSource::start(name, targets, STOP_LIMIT, move |link| {
            Client {
                config,
                by_id,
                link,
                value_connection: vec![Cell::new(0); n],
                epoch,
            }
            .run()
        })
    }
}

/// The client thread.
struct Client {
    config: ShdrConfig,
    by_id: HashMap<String, Vec<usize>>,
    link: Link,
    /// Per channel, the connection number its value arrived on.
    value_connection: Vec<Cell<u64>>,
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
        let status = &self.link.status;
        while !self.link.stop.load(Ordering::Acquire) {
            match self.connect() {
                Ok(stream) => {
                    backoff.reset();
                    status.set_connected(
                        self.now_s(),
                        format!("connected to {}", self.config.address),
                    );
                    match self.serve(stream) {
                        End::Stopped => return,
                        End::Lost(why) => status.set_lost(self.now_s(), why),
                    }
                }
                Err(why) => status.set_lost(self.now_s(), why),
            }
            if !sleep_unless_stopped(backoff.next_delay(), &self.link.stop) {
                return;
            }
        }
    }

    /// The adapter confirmed, at `now_s`, every value of `connection`: it only re-sends changed
    /// values, so a live connection vouches for the unchanged ones. Values of an earlier
    /// connection keep the last stamp theirs gave them; stamps never go backwards.
    fn confirm(&self, connection: u64, now_s: f64) {
        for (k, c) in self.value_connection.iter().enumerate() {
            if c.get() == connection {
                let (value, _) = self.link.channels.get(k);
                self.link.channels.publish(k, value, now_s);
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
        let connection = self.link.status.connection_number();
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
            if self.link.stop.load(Ordering::Acquire) {
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
                    &self.link.status,
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
                    Line::Data => health.data(&self.link.status, self.now_s(), address),
                    Line::Bad(why) => health.bad(&self.link.status, self.now_s(), address, why),
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
                    self.confirm(connection, self.now_s());
                }
                pong_limit = Duration::from_millis(ms);
                ping_every = Duration::from_millis(self.config.ping_ms.min(ms));
            }
        }
    }

    /// Handles one complete line: publishes its values, reports what cannot be used.
    fn handle_line(&self, bytes: &[u8], connection: u64, skip_until: &mut Option<String>) -> Line {
        let now = self.now_s();
        let status = &self.link.status;
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
                        self.link.channels.publish(k, value, now);
                        self.value_connection[k].set(connection);
                    }
                }
                self.confirm(connection, now);
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
