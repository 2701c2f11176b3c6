//! # truepos-live — the live view of a running service
//!
//! One job: serve what the running compensation does over HTTP, on threads of its own — one
//! page embedded in the binary (`/`), the state as JSON (`/api/info`, `/api/state`), the
//! history from the SQLite log downsampled with min/max per bucket (`/api/history`), the
//! logged events (`/api/events`), one Server-Sent Events stream (`/events`, a `state`
//! message every [`stream::TICK`] and an `event` message per logged event, numbered so that
//! `Last-Event-ID` resumes) and the service's health in the Prometheus text format
//! (`/metrics`); answers over 1 kB gzipped for clients that take it. docs/live_view.md documents
//! every endpoint.
//!
//! It reads only what the service publishes: the host's loop writes the latest state into a
//! [`truepos_runtime::live::Board`] between cycles (a sequence lock over atomics: the cycle
//! never waits for a reader, and publishing allocates nothing), and the logger thread writes
//! the SQLite log this server reads. Nothing here runs on the cycle's thread, and no request
//! changes the service (read-only).
//!
//! **Why its own HTTP.** A synchronous HTTP/1.1 server on plain threads ([`http`]): the service
//! and the LinuxCNC component stay free of an async runtime, a stream is a thread writing to its
//! socket, and the threads a client can make it hold are bounded ([`http::MAX_CONNECTIONS`],
//! each with a small stack). tiny_http, used first, gives every connection a thread with the
//! default 2 MiB stack and no bound (the LinuxCNC component locks every stack it has); axum on
//! tokio would bring hyper, tower and an executor beside LinuxCNC's real-time threads, for
//! GETs of eight paths and a stream.
//!
//! **Access.** Loopback by default; any other bind address needs a token, checked on every
//! request ([`access`]).
//!
//! ```
//! use std::io::{Read, Write};
//! use std::sync::Arc;
//! use truepos_live::{Info, LiveServer, LiveSetup};
//! use truepos_runtime::live::{Board, Layout};
//!
//! let layout = Layout { axes: 1, temperatures: 1, operating: 0, paths: 1, sources: 1, sinks: 1, models: 1 };
//! let info = Info {
//!     machine: "lathe".into(), axes: vec![], temperatures: vec![], operating: vec![], paths: 1,
//!     models: vec!["built-in".into()], sources: vec!["replay".into()], sinks: vec!["csv".into()],
//!     log: false, version: "0",
//! };
//! let setup = |addr: &str| LiveSetup {
//!     addr: addr.parse().unwrap(), token: None, board: Arc::new(Board::new(layout)),
//!     info: info.clone(), log: None, probes_after: 0, model_files: vec![None],
//! };
//! // Beyond this machine only with a token.
//! assert!(LiveServer::start(setup("0.0.0.0:0")).is_err());
//! // On loopback, any free port: the static part as JSON.
//! let server = LiveServer::start(setup("127.0.0.1:0")).unwrap();
//! let mut tcp = std::net::TcpStream::connect(server.addr()).unwrap();
//! tcp.write_all(b"GET /api/info HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
//! let mut answer = String::new();
//! tcp.read_to_string(&mut answer).unwrap();
//! assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
//! assert!(answer.contains(r#""machine":"lathe""#), "{answer}");
//! server.stop();
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod access;
pub mod api;
pub mod fleet;
pub mod host;
pub mod http;
pub mod info;
pub mod quality;
pub mod stream;
pub mod work;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use http::{Request, Server};
use serde_json::{json, Value};
use truepos_runtime::live::Board;
use truepos_runtime::log::{self, LoggedEvent, Rows};

pub use info::Info;
use stream::Hub;

/// The page, embedded in the binary (HTML, CSS and JavaScript written here; nothing fetched).
pub const PAGE: &str = include_str!("page.html");

/// Stack of each of the server's threads (accepting, one per connection, sampler): small, since
/// the LinuxCNC component locks its memory (`mlockall` with `MCL_FUTURE`), every thread's stack
/// included; with at most [`http::MAX_CONNECTIONS`] connections, 13 MiB at most in all.
pub(crate) const STACK_BYTES: usize = 512 * 1024;
/// Buckets of a history unless asked otherwise, and the most asked.
const BUCKETS: usize = 1500;
const MAX_BUCKETS: usize = 20_000;

/// What the server is started with.
pub struct LiveSetup {
    /// Address to listen on (port 0: any free port; [`LiveServer::addr`] says which).
    pub addr: SocketAddr,
    /// The token every request must carry; required unless `addr` is loopback.
    pub token: Option<String>,
    /// Where the service publishes.
    pub board: Arc<Board>,
    /// The static part.
    pub info: Info,
    /// The service's log, if it writes one, and its last rows before this run.
    pub log: Option<(PathBuf, Rows)>,
    /// The last row of the log's `probes` table before this run.
    pub probes_after: i64,
    /// Per model of the set, in its order, the file it was read from (`None`: built in).
    pub model_files: Vec<Option<PathBuf>>,
}

/// The running server; stopped by [`LiveServer::stop`] or when dropped.
pub struct LiveServer {
    server: Server,
    hub: Arc<Hub>,
    threads: Vec<JoinHandle<()>>,
}

/// What the request threads share.
struct Shared {
    token: Option<String>,
    board: Arc<Board>,
    info: Info,
    log: Option<(PathBuf, Rows)>,
    probes_after: i64,
    model_files: Vec<Option<PathBuf>>,
    /// Per model, the generation its figures were read at and the figures: read again only when
    /// a reload was applied, so a file refused at reload (unsigned, implausible) never shows
    /// its figures beside the model that still runs.
    figures: Mutex<Vec<(u64, Value)>>,
    hub: Arc<Hub>,
}

/// Seconds since the Unix epoch now.
pub fn wall_unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(f64::NAN, |d| d.as_secs_f64())
}

/// A logged event as the API gives it.
pub fn event_json(row: i64, e: &LoggedEvent) -> Value {
    let time_s = if e.time_s.is_finite() {
        json!(e.time_s)
    } else {
        Value::Null
    };
    json!({"row": row, "time_s": time_s, "kind": e.kind, "subject": e.subject, "detail": e.detail})
}

impl LiveServer {
    /// Checks the access rule, binds and starts the threads. Fails (nothing started) when a
    /// non-loopback address has no token or the address cannot be bound.
    pub fn start(setup: LiveSetup) -> Result<Self, String> {
        access::check_bind(setup.addr, setup.token.as_deref())?;
        let hub = Hub::new();
        let shared = Arc::new(Shared {
            token: setup.token,
            board: setup.board,
            info: setup.info,
            log: setup.log,
            probes_after: setup.probes_after,
            figures: Mutex::new(
                setup
                    .model_files
                    .iter()
                    .map(|f| (1, quality::figures_of(f.as_deref())))
                    .collect(),
            ),
            model_files: setup.model_files,
            hub: Arc::clone(&hub),
        });
        let mut threads = Vec::new();
        let spawn = |name: String, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name)
                .stack_size(STACK_BYTES)
                .spawn(f)
                .map_err(|e| format!("cannot start the live view's thread: {e}"))
        };
        {
            let s = Arc::clone(&shared);
            threads.push(spawn(
                "truepos-live-sampler".into(),
                Box::new(move || {
                    let (file, after) = match &s.log {
                        Some((f, rows)) => (Some(f.clone()), rows.events),
                        None => (None, 0),
                    };
                    stream::sample(&s.hub, &s.board, &s.info, file, after);
                }),
            )?);
        }
        let s = Arc::clone(&shared);
        let server = Server::start(setup.addr, STACK_BYTES, Arc::new(move |rq| handle(rq, &s)));
        let server = match server {
            Ok(srv) => srv,
            Err(e) => {
                hub.stop.store(true, Ordering::Relaxed);
                for t in threads {
                    let _ = t.join();
                }
                return Err(format!("--http {}: cannot listen: {e}", setup.addr));
            }
        };
        Ok(Self {
            server,
            hub,
            threads,
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.server.addr()
    }

    /// Connections open now (streams included).
    pub fn connections(&self) -> usize {
        self.server.connections()
    }

    /// Streams open now.
    pub fn streams(&self) -> usize {
        self.hub.streams.load(Ordering::Relaxed)
    }

    /// Stops the threads and closes the listening socket (streams end within a second).
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.hub.stop.store(true, Ordering::Relaxed);
        self.server.stop(Duration::from_secs(2));
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Smallest body worth compressing.
const GZIP_FROM: usize = 1024;

/// Whether the client takes gzip (`Accept-Encoding: gzip`, without `q=0`).
fn takes_gzip(rq: &Request) -> bool {
    rq.header("Accept-Encoding").is_some_and(|v| {
        v.split(',').any(|e| {
            let mut parts = e.split(';').map(str::trim);
            parts.next() == Some("gzip") && !parts.any(|p| p.replace(' ', "") == "q=0")
        })
    })
}

fn gzip(body: &[u8]) -> Option<Vec<u8>> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(body).ok()?;
    e.finish().ok()
}

pub(crate) fn respond(rq: Request, status: u16, content_type: &str, body: String) {
    let zipped = (body.len() >= GZIP_FROM && takes_gzip(&rq))
        .then(|| gzip(body.as_bytes()))
        .flatten();
    let mut headers = vec![
        ("Content-Type", content_type),
        ("Vary", "Accept-Encoding"),
        ("Cache-Control", "no-store"),
        ("X-Content-Type-Options", "nosniff"),
    ];
    match zipped {
        Some(z) => {
            headers.push(("Content-Encoding", "gzip"));
            rq.respond(status, &headers, &z);
        }
        None => rq.respond(status, &headers, body.as_bytes()),
    }
}

pub(crate) fn respond_json(rq: Request, status: u16, v: &Value) {
    respond(rq, status, "application/json; charset=utf-8", v.to_string());
}

/// The request if it may be answered: it carries the token (when one is set) and reads
/// (`GET`, `HEAD`); else it is answered 401 or 405 here and `None` comes back.
pub(crate) fn gate(rq: Request, token: Option<&str>) -> Option<Request> {
    let query_token = access::query_param(rq.url(), "token");
    if !access::allowed(token, rq.header("Authorization"), query_token.as_deref()) {
        rq.respond(
            401,
            &[
                ("WWW-Authenticate", "Bearer realm=\"truepos\""),
                ("Content-Type", "text/plain; charset=utf-8"),
            ],
            b"a token is required: header `Authorization: Bearer TOKEN` or `?token=TOKEN`\n",
        );
        return None;
    }
    if rq.method() != "GET" && rq.method() != "HEAD" {
        respond(
            rq,
            405,
            "text/plain; charset=utf-8",
            "read-only: GET only\n".into(),
        );
        return None;
    }
    Some(rq)
}

fn handle(rq: Request, s: &Shared) {
    let url = rq.url().to_string();
    let path = url.split('?').next().unwrap_or("");
    let Some(rq) = gate(rq, s.token.as_deref()) else {
        return;
    };
    match path {
        "/" | "/index.html" => respond(rq, 200, "text/html; charset=utf-8", PAGE.to_string()),
        "/api/info" => respond_json(rq, 200, &json!(s.info)),
        "/api/state" => match s.board.read() {
            Some(snap) => respond_json(
                rq,
                200,
                &api::state_json(&snap, &s.info, &s.hub.work(), wall_unix_s()),
            ),
            None => respond_json(
                rq,
                503,
                &json!({"error": "the service has not run a cycle yet"}),
            ),
        },
        "/api/history" => history(rq, &url, s),
        "/api/events" => events(rq, &url, s),
        "/api/quality" => quality(rq, s),
        "/metrics" => match s.board.read() {
            Some(snap) => respond(
                rq,
                200,
                "text/plain; version=0.0.4; charset=utf-8",
                api::metrics(&snap, &s.info, &s.hub.work()),
            ),
            None => respond(
                rq,
                503,
                "text/plain; charset=utf-8",
                "no cycle yet\n".into(),
            ),
        },
        "/events" => open_stream(rq, &url, s),
        _ => respond(
            rq,
            404,
            "text/plain; charset=utf-8",
            format!("no such page: {path}\n"),
        ),
    }
}

fn no_log(rq: Request) {
    respond_json(
        rq,
        404,
        &json!({"error": "this service writes no log: history and events need `truepos run --log FILE`"}),
    );
}

fn history(rq: Request, url: &str, s: &Shared) {
    let Some((file, rows)) = &s.log else {
        return no_log(rq);
    };
    let window_s = access::query_param(url, "window_s").and_then(|w| w.parse::<f64>().ok());
    let buckets = access::query_param(url, "buckets")
        .and_then(|b| b.parse::<usize>().ok())
        .unwrap_or(BUCKETS)
        .clamp(1, MAX_BUCKETS);
    match log::read_history(file, rows.cycles, window_s, buckets) {
        Ok(h) => respond_json(rq, 200, &json!(h)),
        Err(e) => respond_json(rq, 500, &json!({"error": e.to_string()})),
    }
}

fn quality(rq: Request, s: &Shared) {
    let models: Vec<(String, Option<PathBuf>)> = s
        .info
        .models
        .iter()
        .enumerate()
        .map(|(i, n)| (n.clone(), s.model_files.get(i).cloned().flatten()))
        .collect();
    let generations = s.board.read().map(|b| b.generations).unwrap_or_default();
    let figures: Vec<Value> = {
        let mut cache = s.figures.lock().unwrap_or_else(|p| p.into_inner());
        for (i, (generation, figures)) in cache.iter_mut().enumerate() {
            let now = generations.get(i).copied().unwrap_or(*generation);
            if now != *generation {
                *generation = now;
                *figures = quality::figures_of(models.get(i).and_then(|m| m.1.as_deref()));
            }
        }
        cache.iter().map(|(_, f)| f.clone()).collect()
    };
    let axes: Vec<String> = s.info.axes.iter().map(|a| a.name.clone()).collect();
    let probes = s.log.as_ref().map(|(f, _)| (f.as_path(), s.probes_after));
    respond_json(
        rq,
        200,
        &quality::quality_json(&models, &generations, &figures, probes, &axes),
    );
}

fn events(rq: Request, url: &str, s: &Shared) {
    let Some((file, rows)) = &s.log else {
        return no_log(rq);
    };
    let after = access::query_param(url, "after")
        .and_then(|a| a.parse::<i64>().ok())
        .unwrap_or(0)
        .max(rows.events);
    let limit = access::query_param(url, "limit")
        .and_then(|l| l.parse::<usize>().ok())
        .unwrap_or(5000)
        .clamp(1, 100_000);
    match log::read_events_after(file, after, limit) {
        Ok(list) => {
            let last = list.last().map_or(after, |(r, _)| *r);
            let events: Vec<Value> = list.iter().map(|(r, e)| event_json(*r, e)).collect();
            respond_json(rq, 200, &json!({"events": events, "last_row": last}))
        }
        Err(e) => respond_json(rq, 500, &json!({"error": e.to_string()})),
    }
}

/// Serves a stream on this connection's thread until the page goes away or the server stops.
fn open_stream(rq: Request, url: &str, s: &Shared) {
    let last = rq
        .header("Last-Event-ID")
        .map(str::to_string)
        .or_else(|| access::query_param(url, "last_event_id"))
        .and_then(|v| v.trim().parse::<u64>().ok());
    let hub = &s.hub;
    if hub.streams.fetch_add(1, Ordering::AcqRel) >= stream::MAX_STREAMS {
        hub.streams.fetch_sub(1, Ordering::AcqRel);
        respond(
            rq,
            503,
            "text/plain; charset=utf-8",
            "too many live streams open\n".into(),
        );
        return;
    }
    stream::serve(hub, Box::new(rq.into_stream()), last);
    hub.streams.fetch_sub(1, Ordering::AcqRel);
}
