//! # truepos-runtime — the cyclic compensation service
//!
//! Every cycle: sources → validation → model set → evaluation → safety envelope → sinks, with
//! the log written off the cycle. [`ServiceHost`] is the one way to start it (machine, models,
//! sources, sinks, log, hot reload); [`Service::cycle`] runs one cycle at the time its caller
//! gives; [`admission`] decides whether a model may serve an axis. The runtime reads no file
//! format: io parses machine and model files into [`MachineConfig`] and
//! [`model_set::ModelEntry`]. The map and the invariants: `ARCHITECTURE.md`.
//!
//! A recorded run replayed through the example machine's model into a CSV sink:
//!
//! ```
//! use std::path::Path;
//! use truepos_runtime::replay::{CsvSink, ReplaySource};
//! use truepos_runtime::ServiceHost;
//!
//! let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vmc3");
//! let machine = truepos_io::machine_file::load(&root.join("machine.toml"))?;
//! let models = truepos_io::model_file::load_set(&[root.join("model.toml")], &machine)?;
//! let run = truepos_io::cycles::load(&root.join("run.csv"), &machine.machine, &[])?;
//! let out = std::env::temp_dir().join(format!("truepos-doc-{}.csv", std::process::id()));
//! let axes: Vec<String> = machine.machine.axes.iter().map(|a| a.name.clone()).collect();
//! let sink = CsvSink::create(&out, &axes, 1.0, &[])?;
//! let mut running = ServiceHost::new(machine, models)
//!     .source(Box::new(ReplaySource::new("replay", run.run)))
//!     .sink(Box::new(sink))
//!     .start()?;
//! for k in 0..2_000 {
//!     running.service.cycle(f64::from(k) * 1e-3); // 2 s of service time at 1 kHz
//! }
//! running.stop();
//! let csv = std::fs::read_to_string(&out)?;
//! assert!(csv.starts_with("time_s,X_offset_um,Y_offset_um,Z_offset_um,state,clamped"));
//! assert_eq!(csv.lines().count(), 1 + 2); // the header and a row a second
//! # std::fs::remove_file(&out)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
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
pub use host::{Running, ServiceHost, StartError, Stopped, DEFAULT_PERIOD_S};
pub use io_traits::{LinkError, SharedChannels, Sink, Source};
pub use output::{CompensationState, Output};
pub use service::{PathState, Service, ServiceConfig};
