//! Sources and sinks: where a cycle's inputs come from and where its offsets go. Each kind
//! (replay, twin, LinuxCNC HAL, MTConnect SHDR, Modbus TCP) implements one of these traits, so a
//! new one is small.
//!
//! Both are called on the cycle path: `read` and `write` must not block, allocate or do network
//! I/O. A network source runs its own thread and publishes into [`SharedChannels`]; its `read`
//! only copies the latest values.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crate::events::Reason;
use crate::frame::{Frame, NEVER};
use crate::output::Output;

/// Why a source or sink could not do its part this cycle.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkError {
    /// The source does not deliver: its connection is down (it reconnects by itself) or the peer
    /// answers with nothing usable; the channels it feeds go stale. The reason is fixed-size
    /// text, so a source reports it on every cycle of the outage without allocating.
    Disconnected(Reason),
    /// The source has nothing more to give (a replayed run has ended).
    Finished,
    /// Anything else, with a reason.
    Failed(String),
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Disconnected(why) => write!(f, "disconnected: {why}"),
            Self::Finished => write!(f, "finished"),
            Self::Failed(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for LinkError {}

/// Delivers some channels of the frame every cycle.
pub trait Source: Send {
    /// Name for events and status (`modbus 127.0.0.1:5020`).
    fn name(&self) -> &str;
    /// Writes the latest values this source has into `frame` (with [`Frame::set_temperature`]
    /// and friends, which stamp them). Must not block.
    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError>;
}

/// Takes the offsets of every cycle.
pub trait Sink: Send {
    /// Name for events and status.
    fn name(&self) -> &str;
    /// Applies or records one cycle's output. Must not block.
    fn write(&mut self, output: &Output) -> Result<(), LinkError>;
    /// What the service calls every cycle: the output and the cycle's inputs (lagged channels
    /// computed), for a sink that needs more than the offsets — the OPC UA sink projects the
    /// model at these temperatures onto the control's per-axis form. Must not block or allocate.
    /// By default the inputs are not looked at.
    fn write_cycle(&mut self, output: &Output, _frame: &Frame) -> Result<(), LinkError> {
        self.write(output)
    }
    /// Whether the offsets reach the axes through this sink (LinuxCNC's external offsets)
    /// rather than being recorded (a CSV file). When such a sink fails, nothing the service
    /// computes reaches the axes and it cannot resume bumplessly: the run stops with an alarm
    /// (see `Service::axes_unreachable` and ARCHITECTURE.md).
    fn drives_axes(&self) -> bool {
        false
    }
}

/// Latest values published by a source thread and read by the cycle without locks: one atomic
/// f64 (as bits) and one atomic update time per channel.
#[derive(Debug)]
pub struct SharedChannels {
    values: Vec<AtomicU64>,
    stamps: Vec<AtomicU64>,
}

impl SharedChannels {
    /// `n` channels, all NaN and never updated.
    pub fn new(n: usize) -> Arc<Self> {
        Arc::new(Self {
            values: (0..n).map(|_| AtomicU64::new(f64::NAN.to_bits())).collect(),
            stamps: (0..n).map(|_| AtomicU64::new(NEVER.to_bits())).collect(),
        })
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether there are no channels.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Publishes a value received at `stamp_s` (service clock). Out-of-range channels are ignored.
    pub fn publish(&self, channel: usize, value: f64, stamp_s: f64) {
        if let (Some(v), Some(s)) = (self.values.get(channel), self.stamps.get(channel)) {
            v.store(value.to_bits(), Ordering::Release);
            s.store(stamp_s.to_bits(), Ordering::Release);
        }
    }

    /// The latest value and its update time. The stamp is read first: [`Self::publish`] stores
    /// the value before the stamp, so a value read after a stamp is at least as new as it. A
    /// read that overlaps a publish may pair a newer value with the older stamp — the value
    /// looks older than it is, never fresher.
    pub fn get(&self, channel: usize) -> (f64, f64) {
        match (self.values.get(channel), self.stamps.get(channel)) {
            (Some(v), Some(s)) => {
                let stamp = f64::from_bits(s.load(Ordering::Acquire));
                (f64::from_bits(v.load(Ordering::Acquire)), stamp)
            }
            _ => (f64::NAN, NEVER),
        }
    }
}
