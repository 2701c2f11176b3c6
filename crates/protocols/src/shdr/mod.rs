//! MTConnect SHDR input: a TCP client to an MTConnect adapter, reading axis positions
//! (`POSITION`, `ANGLE`) and temperatures (`TEMPERATURE`) from its SHDR lines.
//!
//! SHDR ("simple hierarchical data representation") is the line protocol between an MTConnect
//! adapter and an agent, as described by the MTConnect Institute's reference agent
//! documentation (cppagent, "Adapter Agent Protocol"): the adapter listens on TCP, and each line
//! it sends is `timestamp|dataItemId|value|dataItemId|value…`, with the value `UNAVAILABLE` when
//! it does not know it. An adapter sends a value when it changes (and all values when a client
//! connects). The client sends `* PING`; the adapter answers `* PONG <ms>`, announcing the
//! longest time the client should wait for the next answer. Lines starting with `*` are protocol
//! commands (`* shdrVersion: 2`).
//!
//! [`parse_line`] is a pure function: every malformed line gives an [`ShdrError`], never a
//! panic (property-tested with a million inputs, `tests/fuzz_network.rs`).
//!
//! [`ShdrSource::start`] runs the client on its own thread, hosted by a
//! [`PolledSource`](truepos_runtime::sources::PolledSource), the [`Source`] the cycle reads. The stamp of a
//! value is the last time the adapter confirmed it: when it arrived, or later when a data line or
//! a `PONG` arrived on the same connection — a `PONG` only while the adapter also delivers data
//! (an adapter only re-sends changed values, so a live connection confirms the unchanged ones).
//! When the connection is lost — the socket closes, or no `PONG` comes within the announced
//! interval after a `PING` — the stamps stop advancing and the client reconnects with backoff
//! ([`truepos_runtime::sources`]).
//!
//! Limits: data items are read as `id|value` pairs, so CONDITION (six fields), MESSAGE and
//! time-series items must be on lines of their own (as adapters usually send them); a line whose
//! pairing fails is reported as bad data and skipped. Multi-line assets (`--multiline--`) are
//! skipped. The adapter's timestamp is not used: values are stamped on the service clock when
//! they arrive.
//!
//! [`Source`]: truepos_runtime::Source

mod config;
mod parse;
mod source;

pub use config::{ShdrChannelConfig, ShdrConfig};
pub use parse::{
    parse_line, parse_value, LineBuffer, ShdrError, ShdrItem, ShdrLine, ShdrValue, MAX_LINE_BYTES,
};
pub use source::{ShdrSource, MAX_BAD_LINES_IN_ROW, MAX_UNSOLICITED_PONGS};
