//! Events of the service: what happened, when, to which channel. An event is `Copy` and carries
//! indices, so raising one on the cycle path allocates nothing; the log names the channels.

use std::sync::atomic::{AtomicU64, Ordering};

use crossbeam_queue::ArrayQueue;

use crate::validate::Fault;

/// What happened.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EventKind {
    /// A temperature channel failed validation.
    SensorFault {
        /// Machine temperature channel.
        channel: usize,
        /// Why.
        fault: Fault,
    },
    /// A temperature channel is valid again.
    SensorRecovered {
        /// Machine temperature channel.
        channel: usize,
    },
    /// An axis position is unusable (NaN, stale): compensation holds.
    PositionFault {
        /// Machine axis.
        axis: usize,
    },
    /// The axis positions are usable again.
    PositionRecovered,
    /// A path now uses this model (seed D selection, or after a fault cleared).
    ModelSelected {
        /// Path, 1-based.
        path: u32,
        /// Model index in the model set.
        model: usize,
    },
    /// A sensor fault made a path fall back from its preferred model to another.
    ModelSubstituted {
        /// Path, 1-based.
        path: u32,
        /// Preferred model.
        from: usize,
        /// Model used instead.
        to: usize,
    },
    /// No model of the set matches the path's axis combination (seed D: notify the user).
    NoModel {
        /// Path, 1-based.
        path: u32,
        /// The target index D of the path.
        target: [u32; 3],
    },
    /// Every matching model reads a bad sensor: the last good compensation is held and ramped
    /// to zero.
    Holding {
        /// Path, 1-based.
        path: u32,
    },
    /// The control switched axes between paths (seed D, Figs. 10–11): models are selected anew.
    AxisSwitch,
    /// Compensation was switched on (true) or off (false).
    Enabled(bool),
    /// The envelope clamped an axis' offset.
    Clamped {
        /// Machine axis.
        axis: usize,
        /// True for the rate limit, false for the magnitude limit.
        rate: bool,
    },
    /// The envelope stopped clamping an axis.
    ClampReleased {
        /// Machine axis.
        axis: usize,
    },
    /// A source failed to deliver this cycle (it keeps trying).
    SourceLost {
        /// Index of the source.
        source: usize,
    },
    /// A source delivers again.
    SourceBack {
        /// Index of the source.
        source: usize,
    },
    /// A sink failed to take the output (raised on the change, not every cycle).
    SinkFailed {
        /// Index of the sink.
        sink: usize,
        /// Why, as the sink said it.
        reason: Reason,
    },
    /// A sink that failed takes the output again.
    SinkBack {
        /// Index of the sink.
        sink: usize,
    },
    /// A cycle started later than its deadline.
    Overrun {
        /// Lateness in µs.
        late_us: u32,
    },
}

/// Bytes a [`Reason`] holds; a longer text is cut at a character boundary.
pub const REASON_BYTES: usize = 96;

/// A short text (why a sink or source failed) that an event can carry: fixed capacity and
/// `Copy`, so raising the event on the cycle path allocates nothing.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Reason {
    len: u8,
    bytes: [u8; REASON_BYTES],
}

impl Reason {
    /// The text, cut to [`REASON_BYTES`] at a character boundary.
    pub fn new(text: &str) -> Self {
        let mut r = Self::default();
        r.push_str(text);
        r
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        // Only whole characters are ever copied in, so this never fails.
        std::str::from_utf8(&self.bytes[..usize::from(self.len)]).unwrap_or("")
    }

    fn push_str(&mut self, text: &str) {
        let start = usize::from(self.len);
        let mut end = text.len().min(REASON_BYTES - start);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[start..start + end].copy_from_slice(&text.as_bytes()[..end]);
        self.len = (start + end) as u8;
    }
}

impl Default for Reason {
    fn default() -> Self {
        Self {
            len: 0,
            bytes: [0; REASON_BYTES],
        }
    }
}

/// `write!` into a reason formats without allocating; what does not fit is cut off.
impl std::fmt::Write for Reason {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.push_str(s);
        Ok(())
    }
}

impl std::fmt::Debug for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An event with its service time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Service time in s.
    pub time_s: f64,
    /// What happened.
    pub kind: EventKind,
}

/// A bounded, lock-free queue of events from the cycle to the logger. If the logger falls so
/// far behind that the queue is full, the event is counted as dropped (and the count logged)
/// rather than blocking the cycle.
#[derive(Debug)]
pub struct EventQueue {
    queue: ArrayQueue<Event>,
    dropped: AtomicU64,
}

impl EventQueue {
    /// A queue for `capacity` events.
    pub fn new(capacity: usize) -> Self {
        Self {
            queue: ArrayQueue::new(capacity.max(1)),
            dropped: AtomicU64::new(0),
        }
    }

    /// Queues an event without blocking or allocating.
    pub fn push(&self, event: Event) {
        if self.queue.push(event).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Takes the oldest event.
    pub fn pop(&self) -> Option<Event> {
        self.queue.pop()
    }

    /// Events dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reason_keeps_short_text_and_cuts_long_text_at_a_character() {
        assert_eq!(Reason::new("disk full").as_str(), "disk full");
        let long = "é".repeat(REASON_BYTES);
        let r = Reason::new(&long);
        assert_eq!(r.as_str().len(), REASON_BYTES);
        assert!(long.starts_with(r.as_str()));
        let mut w = Reason::new("a");
        std::fmt::Write::write_fmt(&mut w, format_args!("{}", "ü".repeat(200))).unwrap();
        assert!(w.as_str().starts_with("aü") && w.as_str().len() <= REASON_BYTES);
    }
}
