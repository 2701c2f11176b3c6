//! # truepos-runtime — the cyclic compensation service
//!
//! Every cycle: sources → validation → model set → evaluation → safety envelope → sinks, with
//! the log written off the cycle. This crate is being built up; see `ARCHITECTURE.md`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod frame;
pub mod io_traits;
pub mod modbus;
pub mod output;
pub mod reconnect;
pub mod shdr;

pub use frame::{Frame, NEVER};
pub use io_traits::{LinkError, SharedChannels, Sink, Source};
pub use output::{CompensationState, Output};
