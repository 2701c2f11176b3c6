//! OPC UA: truepos beside a control that takes values over OPC UA.
//!
//! SINUMERIK and TwinCAT accept writes over their OPC UA servers, and both carry a linear
//! temperature compensation per axis, ΔK = K0 + tanβ·(P − P0) (SINUMERIK SD43900/43910/43920;
//! see `truepos_controls::projection`). This module is truepos's OPC UA client (the pure-Rust
//! `async-opcua` stack, client only):
//!
//! - [`sink::OpcUaSink`] (`truepos run --sink opcua:MAPPING.toml`): every period (default
//!   100 ms) the running model projected onto each axis' line at the cycle's temperatures,
//!   moved to the service's output at the axis' position, kept within the envelope and the
//!   control's own rate limit, written to the mapped nodes; each node's status checked (a
//!   refused value is not taken as applied); lost sessions reopened with backoff;
//! - [`source::OpcUaSource`] (`truepos run --source opcua:CONFIG.toml`): temperatures and axis
//!   positions read from nodes; a Bad or Uncertain status, or a value that is not a finite
//!   number, leaves the channel un-updated, so the service's validation sees it go stale;
//! - [`config`]: the TOML of both, with the security a machine network needs (user/password,
//!   `Basic256Sha256` Sign or SignAndEncrypt, a trust list of server certificates; anonymous
//!   sessions only when the mapping says so).
//!
//! Neither touches the network on the cycle: each runs a thread of its own with a
//! current-thread tokio runtime; the cycle hands over and takes values through atomics.

pub mod client;
pub mod config;
pub mod form;
pub mod latest;
pub mod sink;
pub mod source;

pub use config::{Identity, SinkConfig, SourceConfig};
pub use sink::{OpcUaSink, WriteStats};
pub use source::OpcUaSource;
