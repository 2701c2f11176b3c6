//! The state of a link as the cycle and the status line see it: connected, failing, counters, the
//! events to drain, and the outage reason reported by `Source::read`.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

use crossbeam_queue::ArrayQueue;

use crate::events::Reason;
use crate::io_traits::LinkError;

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
