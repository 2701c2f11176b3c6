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
//! **Why tiny_http.** A small, synchronous HTTP/1.1 server (MIT/Apache-2.0, four small
//! dependencies, no TLS compiled in) on plain threads: the service and the LinuxCNC component
//! stay free of an async runtime, a stream is a thread writing to its socket, and the build
//! stays small on two cores. axum on tokio (already linked by the OPC UA client) was the
//! other candidate: its routing, extractors and SSE helpers are not needed for seven GET
//! endpoints, and it would pull hyper, tower and an executor into the component that runs
//! beside LinuxCNC's real-time threads.
//!
//! **Access.** Loopback by default; any other bind address needs a token, checked on every
//! request ([`access`]).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod access;
pub mod api;
pub mod host;
pub mod info;
pub mod quality;
pub mod stream;
pub mod work;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use serde_json::{json, Value};
use tiny_http::{Header, Request, Response, Server};
use truepos_runtime::live::Board;
use truepos_runtime::log::{self, LoggedEvent, Rows};

pub use info::Info;
use stream::Hub;

/// The page, embedded in the binary (HTML, CSS and JavaScript written here; nothing fetched).
pub const PAGE: &str = include_str!("page.html");

/// Threads answering requests (a stream has a thread of its own besides).
const WORKERS: usize = 4;
/// Stack of each of the server's own threads (workers, streams, sampler): small, since the
/// LinuxCNC component locks its memory (`mlockall` with `MCL_FUTURE`), every thread's stack
/// included. tiny_http's own accept and connection threads keep the default stack; that they
/// are not bounded is said in docs/live_view.md ("Not yet").
const STACK_BYTES: usize = 512 * 1024;
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
    addr: SocketAddr,
    server: Arc<Server>,
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
        let server = Server::http(setup.addr)
            .map_err(|e| format!("--http {}: cannot listen: {e}", setup.addr))?;
        let addr = server
            .server_addr()
            .to_ip()
            .ok_or_else(|| format!("--http {}: not an IP address", setup.addr))?;
        let server = Arc::new(server);
        let hub = Hub::new();
        let shared = Arc::new(Shared {
            token: setup.token,
            board: setup.board,
            info: setup.info,
            log: setup.log,
            probes_after: setup.probes_after,
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
        for i in 0..WORKERS {
            let (s, srv) = (Arc::clone(&shared), Arc::clone(&server));
            threads.push(spawn(
                format!("truepos-live-{i}"),
                Box::new(move || worker(&srv, &s)),
            )?);
        }
        Ok(Self {
            addr,
            server,
            hub,
            threads,
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
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
        for _ in 0..WORKERS {
            self.server.unblock();
        }
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

fn worker(server: &Server, s: &Arc<Shared>) {
    while !s.hub.stop.load(Ordering::Relaxed) {
        match server.recv_timeout(Duration::from_millis(250)) {
            Ok(Some(rq)) => handle(rq, s),
            Ok(None) => {}
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("a valid header")
}

fn request_header<'a>(rq: &'a Request, name: &'static str) -> Option<&'a str> {
    rq.headers()
        .iter()
        .find(|h| h.field.equiv(name))
        .map(|h| h.value.as_str())
}

/// Smallest body worth compressing.
const GZIP_FROM: usize = 1024;

/// Whether the client takes gzip (`Accept-Encoding: gzip`, without `q=0`).
fn takes_gzip(rq: &Request) -> bool {
    request_header(rq, "Accept-Encoding").is_some_and(|v| {
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

fn respond(rq: Request, status: u16, content_type: &str, body: String) {
    let zipped = (body.len() >= GZIP_FROM && takes_gzip(&rq))
        .then(|| gzip(body.as_bytes()))
        .flatten();
    let r = match zipped {
        Some(z) => Response::from_data(z).with_header(header("Content-Encoding", "gzip")),
        None => Response::from_data(body.into_bytes()),
    };
    let r = r
        .with_status_code(status)
        .with_header(header("Content-Type", content_type))
        .with_header(header("Vary", "Accept-Encoding"))
        .with_header(header("Cache-Control", "no-store"))
        .with_header(header("X-Content-Type-Options", "nosniff"));
    let _ = rq.respond(r);
}

fn respond_json(rq: Request, status: u16, v: &Value) {
    respond(rq, status, "application/json; charset=utf-8", v.to_string());
}

fn handle(rq: Request, s: &Arc<Shared>) {
    let url = rq.url().to_string();
    let path = url.split('?').next().unwrap_or("");
    let query_token = access::query_param(&url, "token");
    if !access::allowed(
        s.token.as_deref(),
        request_header(&rq, "Authorization"),
        query_token.as_deref(),
    ) {
        let r = Response::from_string(
            "a token is required: header `Authorization: Bearer TOKEN` or `?token=TOKEN`\n",
        )
        .with_status_code(401)
        .with_header(header("WWW-Authenticate", "Bearer realm=\"truepos\""))
        .with_header(header("Content-Type", "text/plain; charset=utf-8"));
        let _ = rq.respond(r);
        return;
    }
    if *rq.method() != tiny_http::Method::Get && *rq.method() != tiny_http::Method::Head {
        respond(
            rq,
            405,
            "text/plain; charset=utf-8",
            "read-only: GET only\n".into(),
        );
        return;
    }
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
    let axes: Vec<String> = s.info.axes.iter().map(|a| a.name.clone()).collect();
    let probes = s.log.as_ref().map(|(f, _)| (f.as_path(), s.probes_after));
    respond_json(
        rq,
        200,
        &quality::quality_json(&models, &generations, probes, &axes),
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

fn open_stream(rq: Request, url: &str, s: &Arc<Shared>) {
    let last = request_header(&rq, "Last-Event-ID")
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
    let s = Arc::clone(s);
    let spawned = std::thread::Builder::new()
        .name("truepos-live-stream".into())
        .stack_size(STACK_BYTES)
        .spawn(move || {
            let w = rq.into_writer();
            stream::serve(&s.hub, w, last);
            s.hub.streams.fetch_sub(1, Ordering::AcqRel);
        });
    if spawned.is_err() {
        hub.streams.fetch_sub(1, Ordering::AcqRel);
    }
}
