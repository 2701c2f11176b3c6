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
    /// A sink failed to take the output.
    SinkFailed {
        /// Index of the sink.
        sink: usize,
    },
    /// A cycle started later than its deadline.
    Overrun {
        /// Lateness in µs.
        late_us: u32,
    },
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
