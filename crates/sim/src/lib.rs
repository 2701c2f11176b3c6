//! # truepos-sim — the thermal twin
//!
//! A physical simulator of a CNC machine tool warming up, bending and being measured, good
//! enough that a compensation model fitted on its output means something, and that users can
//! size sensors and try models before drilling a hole in a casting.
//!
//! - [`scenario`]: operating scenarios from TOML (spindle, axis motion, coolant, idle, ambient,
//!   probing, sensor faults) and the built-in ISO 230-3 style tests and shifts.
//! - [`twin`]: the reference 3-axis vertical machining centre — heat sources, the layout of
//!   its thermal nodes, sensor spots, and its serial kinematic chain.
//! - [`params`]: the physical parameters and the twin description file that overrides them.
//! - [`network`]: the lumped thermal network and its exact exponential integrator.
//! - [`beam`]: thermo-elastic deformation of a part: growth `α·L·ΔT` and the bending radius
//!   `R = H·L_bottom/(L_bottom − L_top)` (docs/glossary.md: bending radius).
//! - [`deviation`]: small-angle homogeneous transforms chained through the axes.
//! - [`sensor`]: first-order lag, noise, quantisation, faults.
//! - [`simulation`]: the time loop, the in-memory run, its CSV and summary.
//!
//! Sign: error = actual − nominal tool position relative to the workpiece, in µm.
//!
//! ## Example
//! ```
//! use truepos_sim::{Scenario, Twin};
//!
//! let twin = Twin::reference();
//! let scenario = Scenario::builtin("spindle-warmup").unwrap();
//! let run = twin.run(&scenario, 42).unwrap();
//! let s = run.summary();
//! // A 4 h spindle run pushes the tool tens of µm down towards the table.
//! assert!(s.peak_error[2].0 < -10.0);
//! // The ground truth anywhere in the working volume at any recorded instant:
//! let last = run.rows.len() - 1;
//! let at_corner = twin.error_um(run.state(last), [0.0, 0.0, 500.0]);
//! assert!(at_corner.iter().all(|v| v.is_finite()));
//! let mut csv = Vec::new();
//! run.write_csv(&mut csv, false).unwrap();
//! assert!(String::from_utf8(csv).unwrap().starts_with("time_s,X_mm,Y_mm,Z_mm,"));
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod beam;
pub mod deviation;
pub mod network;
pub mod params;
pub mod scenario;
pub mod sensor;
pub mod simulation;
pub mod twin;

pub use params::TwinParams;
pub use scenario::{Scenario, BUILTIN};
pub use simulation::{ProbeReading, Row, SimError, SimRun, Summary};
pub use twin::{Deformed, Operating, SensorSpec, Twin, AXES};
