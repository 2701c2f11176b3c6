//! What every network source shares, whatever its protocol (the protocols themselves — Modbus
//! TCP, MTConnect SHDR, OPC UA — are the crate `truepos-protocols`): the host of a source fed by
//! a thread of its own ([`PolledSource`]), reconnection with exponential backoff, the state of a
//! link as the cycle and the status line see it, the mapping of a received value onto a machine
//! channel of the frame, and the checks of their configurations.
//!
//! A network source runs its own thread. When its connection is lost the thread stops publishing,
//! so the stamps of the channels it feeds stop advancing: the service's validation then sees
//! them as missing updates, i.e. bad sensors, and applies its policy. The thread meanwhile tries
//! to reconnect, waiting `initial_ms`, then twice as long after every failed attempt, up to
//! `max_ms`; a successful connection resets the wait.

mod backoff;
mod config;
mod link;
mod polled;
mod target;
mod thread;

pub use backoff::{Backoff, BackoffConfig};
pub use config::{check_source_config, from_toml_text, load_toml_file, resolve_address};
pub use link::{
    LinkEvent, LinkEventKind, LinkSnapshot, LinkStatus, OutageReporter, MAX_EVENT_MESSAGE_BYTES,
    MAX_PENDING_EVENTS,
};
pub use polled::{Link, PolledSource};
pub use target::{check_unique_targets, Target};
pub use thread::{read_exact_until, seconds_since, sleep_unless_stopped, stop_thread, STOP_LIMIT};
