//! The one multiplexed stream (`/events`, Server-Sent Events): a sampler thread reads the
//! board every [`TICK`] and the log's new events, and numbers each message; every connected
//! page has a thread of its own that writes the messages after the one it last saw
//! (`Last-Event-ID`), so a page that reconnects misses nothing still in the ring.

use std::collections::VecDeque;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use truepos_runtime::live::Board;
use truepos_runtime::log;

use crate::api;
use crate::info::Info;
use crate::work::{WorkFigures, WorkWindow};

/// How often the sampler reads the board: the stream's rate, at most 250 ms.
pub const TICK: Duration = Duration::from_millis(200);
/// Messages kept for pages that reconnect (at [`TICK`], over three minutes of state).
pub const RING: usize = 1024;
/// Most streams open at once; more are answered 503.
pub const MAX_STREAMS: usize = 16;
/// A comment line this often keeps idle proxies from closing a stream.
const KEEP_ALIVE: Duration = Duration::from_secs(15);

/// One numbered message of the stream.
#[derive(Debug, Clone)]
struct Message {
    id: u64,
    text: Arc<str>,
}

#[derive(Debug, Default)]
struct Ring {
    messages: VecDeque<Message>,
    next_id: u64,
}

/// What the sampler and the stream threads share.
#[derive(Debug)]
pub struct Hub {
    ring: Mutex<Ring>,
    grew: Condvar,
    /// Streams open now.
    pub streams: AtomicUsize,
    /// Set when the server stops.
    pub stop: AtomicBool,
    /// The cycle's work over the last minute, as the sampler made it last.
    pub work: Mutex<WorkFigures>,
}

impl Hub {
    /// An empty hub.
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            ring: Mutex::new(Ring {
                messages: VecDeque::with_capacity(RING),
                next_id: 1,
            }),
            grew: Condvar::new(),
            streams: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            work: Mutex::new(WorkFigures::default()),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Ring> {
        self.ring.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Adds a message of `event` type with `data` (one line of JSON).
    fn push(&self, event: &str, data: &str) {
        let mut r = self.lock();
        let id = r.next_id;
        r.next_id += 1;
        let text: Arc<str> = format!("id: {id}\nevent: {event}\ndata: {data}\n\n").into();
        if r.messages.len() == RING {
            r.messages.pop_front();
        }
        r.messages.push_back(Message { id, text });
        drop(r);
        self.grew.notify_all();
    }

    /// The messages after `after` (all kept, if `after` is older than the ring), or, for a
    /// new page (`None`), the latest `state` message only.
    fn after(&self, after: Option<u64>, wait: Duration) -> Vec<Message> {
        let mut r = self.lock();
        let pick = |r: &Ring| -> Vec<Message> {
            match after {
                Some(a) => r.messages.iter().filter(|m| m.id > a).cloned().collect(),
                None => r
                    .messages
                    .iter()
                    .rev()
                    .find(|m| m.text.contains("\nevent: state\n"))
                    .cloned()
                    .into_iter()
                    .collect(),
            }
        };
        let now = pick(&r);
        if !now.is_empty() || self.stop.load(Ordering::Relaxed) {
            return now;
        }
        r = self
            .grew
            .wait_timeout(r, wait)
            .map(|(g, _)| g)
            .unwrap_or_else(|p| p.into_inner().0);
        pick(&r)
    }

    /// The cycle's work figures the sampler made last.
    pub fn work(&self) -> WorkFigures {
        *self.work.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The latest message id (0: none yet).
    fn last_id(&self) -> u64 {
        self.lock().next_id - 1
    }
}

/// Runs the sampler until the hub stops: the cycle's work over the last minute, the board's
/// state when it changed, and the log's new events (after row `after`), each a message.
pub fn sample(hub: &Hub, board: &Board, info: &Info, log_file: Option<PathBuf>, mut after: i64) {
    let mut last_seq = 0;
    let mut window = WorkWindow::new(Instant::now(), truepos_runtime::live::WORK_BUCKETS);
    while !hub.stop.load(Ordering::Relaxed) {
        let started = Instant::now();
        let work = window.update(board.work(), started);
        *hub.work.lock().unwrap_or_else(|p| p.into_inner()) = work;
        if let Some(s) = board.read() {
            if s.seq != last_seq {
                last_seq = s.seq;
                let v = api::state_json(&s, info, &work, crate::wall_unix_s());
                hub.push("state", &v.to_string());
            }
        }
        if let Some(file) = &log_file {
            if let Ok(events) = log::read_events_after(file, after, 500) {
                for (row, e) in events {
                    after = row;
                    let v = crate::event_json(row, &e);
                    hub.push("event", &v.to_string());
                }
            }
        }
        std::thread::sleep(TICK.saturating_sub(started.elapsed()));
    }
}

/// Writes the stream to one page until it goes away or the hub stops. `last_event_id`: the
/// `Last-Event-ID` header or `?last_event_id=` query of a page that reconnects.
pub fn serve(hub: &Hub, mut w: Box<dyn Write + Send>, last_event_id: Option<u64>) {
    let head = "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream; charset=utf-8\r\n\
                Cache-Control: no-store\r\nX-Accel-Buffering: no\r\nConnection: close\r\n\r\n\
                retry: 1000\n\n";
    if w.write_all(head.as_bytes())
        .and_then(|()| w.flush())
        .is_err()
    {
        return;
    }
    // An id from before this server's start (a restarted service) is treated as none.
    let mut after = last_event_id.filter(|&id| id <= hub.last_id());
    let mut quiet_since = Instant::now();
    while !hub.stop.load(Ordering::Relaxed) {
        let messages = hub.after(after, Duration::from_secs(1));
        let mut out = Vec::new();
        for m in &messages {
            out.extend_from_slice(m.text.as_bytes());
            after = Some(m.id);
        }
        if out.is_empty() && quiet_since.elapsed() >= KEEP_ALIVE {
            out.extend_from_slice(b": keep-alive\n\n");
        }
        if out.is_empty() {
            if after.is_none() {
                after = Some(hub.last_id());
            }
            continue;
        }
        quiet_since = Instant::now();
        if w.write_all(&out).and_then(|()| w.flush()).is_err() {
            return;
        }
    }
}
