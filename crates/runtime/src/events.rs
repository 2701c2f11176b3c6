//! Events of the service: what happened, when, to which channel. An event is `Copy` and carries
//! indices, so raising one on the cycle path allocates nothing; the log names the channels.

use std::sync::atomic::{AtomicU64, Ordering};

use crossbeam_queue::ArrayQueue;

use crate::sensor_validation::Fault;

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
    /// A path now uses this model (selected by axis combination, or after a fault cleared).
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
    /// No model of the set matches the path's axis combination: the user is notified.
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
    /// The control switched axes between paths (axis switching): models are selected anew.
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
    /// A path's model was evaluated beyond its training envelope: the input farthest beyond
    /// was clamped to its widened training range, and the output capped
    /// (`truepos_model::envelope`). Raised when it starts and when the input farthest beyond
    /// changes.
    Extrapolating {
        /// Path, 1-based.
        path: u32,
        /// The machine channel.
        input: truepos_model::MachineInput,
        /// Its value.
        value: f64,
        /// The edge of its widened training range.
        limit: f64,
    },
    /// Every input of the path's model is back inside its training envelope.
    ExtrapolationEnded {
        /// Path, 1-based.
        path: u32,
    },
    /// The envelope stopped clamping an axis.
    ClampReleased {
        /// Machine axis.
        axis: usize,
    },
    /// A source failed to deliver this cycle (it keeps trying), or the reason of its failure
    /// changed while it stays lost.
    SourceLost {
        /// Index of the source.
        source: usize,
        /// Why, as the source reported it.
        reason: Reason,
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

/// Bytes a [`Reason`] holds; longer text is cut on a character boundary. Small enough that a
/// `Result<(), LinkError>` stays under 128 bytes.
pub const REASON_BYTES: usize = 112;

/// A short text that is `Copy` and fixed in size, so that a reason can travel with an event and
/// through a lock-free queue without allocating: UTF-8, at most [`REASON_BYTES`] bytes (longer
/// text is cut on a character boundary and ends with `…`).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Reason {
    bytes: [u8; REASON_BYTES],
    len: u8,
}

impl Reason {
    /// The empty reason.
    pub const EMPTY: Reason = Reason {
        bytes: [0; REASON_BYTES],
        len: 0,
    };

    /// `text`, cut to [`REASON_BYTES`] bytes on a character boundary if longer.
    pub fn new(text: &str) -> Self {
        let mut r = Self::EMPTY;
        if text.len() <= REASON_BYTES {
            r.bytes[..text.len()].copy_from_slice(text.as_bytes());
            r.len = text.len() as u8;
            return r;
        }
        const ELLIPSIS: &str = "…";
        let mut cut = REASON_BYTES - ELLIPSIS.len();
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        r.bytes[..cut].copy_from_slice(&text.as_bytes()[..cut]);
        r.bytes[cut..cut + ELLIPSIS.len()].copy_from_slice(ELLIPSIS.as_bytes());
        r.len = (cut + ELLIPSIS.len()) as u8;
        r
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        // Only whole characters are ever copied in, so this cannot fail; an empty text is the
        // harmless answer if it ever did.
        std::str::from_utf8(&self.bytes[..usize::from(self.len)]).unwrap_or_default()
    }

    /// Whether the text is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for Reason {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl std::ops::Deref for Reason {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::fmt::Debug for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        std::fmt::Debug::fmt(self.as_str(), f)
    }
}

impl From<&str> for Reason {
    fn from(text: &str) -> Self {
        Self::new(text)
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
    fn reasons_are_cut_on_a_character_boundary() {
        assert_eq!(Reason::new("timed out").as_str(), "timed out");
        assert!(Reason::EMPTY.is_empty());
        let exact = "x".repeat(REASON_BYTES);
        assert_eq!(Reason::new(&exact).as_str(), exact);
        // 'é' takes bytes 108–109, so the cut at byte 109 (112 less the 3 of '…') falls inside it.
        let long = format!("{}é{}", "a".repeat(108), "b".repeat(50));
        let r = Reason::new(&long);
        assert!(r.len() <= REASON_BYTES, "{}", r.len());
        assert!(r.ends_with('…'), "{r}");
        assert!(r.starts_with(&"a".repeat(108)));
        let multi = "°".repeat(200);
        let r = Reason::new(&multi);
        assert!(r.chars().all(|c| c == '°' || c == '…'), "{r}");
        assert!(r.len() <= REASON_BYTES);
    }
}
