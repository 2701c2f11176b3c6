//! # truepos-runtime — the cyclic compensation service
//!
//! Every cycle: sources → validation → model set → evaluation → safety envelope → sinks, with
//! the log written off the cycle. This crate is being built up; see `ARCHITECTURE.md`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod admission;
pub mod config;
pub mod cycle_budget;
pub mod envelope;
pub mod events;
pub mod frame;
pub mod host;
pub mod io_traits;
pub mod live;
pub mod log;
pub mod model_set;
pub mod output;
pub mod probe;
pub mod replay;
pub mod sensor_validation;
pub mod service;
pub mod sources;

pub use config::{AxisConfig, MachineConfig, SensorChecks};
pub use frame::{Frame, NEVER};
pub use host::{Running, ServiceHost, Stopped};
pub use io_traits::{LinkError, SharedChannels, Sink, Source};
pub use output::{CompensationState, Output};
pub use service::{PathState, Service, ServiceConfig};
