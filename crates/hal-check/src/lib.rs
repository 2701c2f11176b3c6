//! # truepos-hal-check — the HAL component's development tools, not shipped
//!
//! What checks the `truepos` HAL component (`truepos-hal`) rather than what runs beside
//! LinuxCNC: the binary `truepos-hal-check` judges the LinuxCNC end-to-end test
//! (`scripts/linuxcnc_e2e.sh`, [`check`]) and benchmarks the component's cycle without
//! LinuxCNC (`scripts/cycle_timing.sh`, [`timing`]). It reads the component's pin names,
//! status codes, pacing and offset resolution from `truepos-hal` itself, so the judge and the
//! component cannot disagree about them.
//!
//! - [`check`]: what LinuxCNC applied against the models selected by axis combination and the
//!   output invariant, from the samplers' recording.
//! - [`Error`]: what stops either before a verdict or a figure.
//! - [`timing`]: the service on the component's pacing, replaying a run, with the host's steal
//!   time sampled beside it.
//!
//! What LinuxCNC's `sampler` must record for a one-axis machine and the component `truepos`:
//! the columns' pins come from the component's own pin names, so the judge reads what it wrote.
//!
//! ```
//! use truepos_hal_check::check::record::{motion_columns, sampler_cfg};
//! use truepos_model::{Axis, AxisKind, Carriage, Machine};
//! let x = Axis {
//!     name: "X".into(), kind: AxisKind::Linear, travel_min: 0.0, travel_max: 500.0,
//!     carried_by: None, carriage: Carriage::Cantilever,
//! };
//! let machine = Machine {
//!     name: "m".into(), axes: vec![x], temperatures: vec![], differences: vec![], operating: vec![],
//! };
//! let columns = motion_columns(&machine, "truepos");
//! assert_eq!(sampler_cfg(&columns).len(), columns.len());
//! assert!(columns.iter().any(|c| c.pin.starts_with("truepos.")), "{columns:?}");
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod check;
pub mod error;
pub mod timing;

pub use error::Error;
