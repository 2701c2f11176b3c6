//! # truepos-model — the real-time core of truepos
//!
//! Everything that runs inside a control cycle: the checked machine description
//! ([`Machine`]), thermal compensation models ([`Model`]) made of switchable, superimposing
//! [`Part`]s, and their evaluation for one cycle ([`Model::evaluate`]), which neither allocates,
//! nor does I/O, nor panics, and turns NaN/∞ inputs into an [`EvalError`] instead of a NaN offset.
//!
//! The crate is `#![no_std]` (with `alloc` for building a model once at load time) so that the
//! same core can run inside drive or controller firmware. Maths that needs more than `+ − × ÷`
//! goes through `libm`.
//!
//! ## Sign convention
//! **error = actual − nominal**; a model predicts the error of each axis in µm, and the
//! **compensation added to the set-point is −error** ([`Correction::compensation_um`]).
//!
//! ## Example: a slide that bends (the glossary's worked example)
//! A slide (axis X, 500 mm) heated underneath bends; the error across it, along Y, is
//! ΔT·[K_21 + K_22·r_X]. With K_21 = 2 µm/K, K_22 = 4 µm/K and ΔT = 5 K the error is 10 µm at
//! r = 0 and 30 µm at r = 1.
//!
//! ```
//! use truepos_model::*;
//!
//! let axis = |name: &str| Axis {
//!     name: name.into(), kind: AxisKind::Linear, travel_min: 0.0, travel_max: 500.0,
//!     carried_by: None, carriage: Carriage::Cantilever,
//! };
//! let sensor = |id: &str| TemperatureChannel {
//!     id: id.into(), location: String::new(), valid_min_c: 0.0, valid_max_c: 80.0, lag: None,
//! };
//! let machine = Machine {
//!     name: "example-1".into(),
//!     axes: vec![axis("X"), axis("Y")],
//!     temperatures: vec![sensor("x_bottom"), sensor("x_top")],
//!     differences: vec![TemperatureDifference {
//!         name: "dT_x".into(), plus: 0, minus: Reference::Sensor(1),
//!     }],
//!     operating: vec![],
//! };
//! machine.check().unwrap();
//! let bend = Summand {
//!     axis: 1, difference: 0, k0_um_per_k: 2.0, bed_multiplier: None,
//!     position_terms: vec![PositionTerm { axis: 0, factor: PositionFactor::Ratio, k_um_per_k: 4.0 }],
//! };
//! let part = Part {
//!     name: "structure".into(), enabled: true, form: PartForm::PositionDependent,
//!     summands: vec![bend], constants_um: vec![],
//! };
//! let model = Model::new("example", &machine, vec![part]).unwrap();
//! let at = |x: f64| model.evaluate(&CycleInput {
//!     temperatures_c: &[25.0, 20.0], positions: &[x, 0.0], operating: &[],
//! }).unwrap();
//! assert!((at(0.0).error_um()[1] - 10.0).abs() < 1e-12);
//! assert!((at(500.0).error_um()[1] - 30.0).abs() < 1e-12);
//! assert!((at(500.0).compensation_um(1) + 30.0).abs() < 1e-12);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

pub mod compensation;
pub mod config;
pub mod dynamic;
pub mod envelope;
pub mod evaluate;
pub mod lag;
pub mod machine;
pub mod model;
pub mod parameters;
pub mod recorded;
pub mod rls;
pub mod update_period;

pub use compensation::{BindError, BoundDynamicModel, Channels, CompensationModel, MachineInput};
pub use dynamic::{
    lag_gain, DynamicError, DynamicModel, Feature, FeatureBank, FeatureKind, FeatureSpec,
};
pub use evaluate::{Correction, CycleInput, EvalError, TRAVEL_TOLERANCE};
pub use lag::{Lag, LagFilters, LagSource};
pub use machine::{
    Axis, AxisKind, Carriage, Machine, MachineError, OperatingChannel, OperatingKind, Reference,
    TemperatureChannel, TemperatureDifference, MAX_AXES,
};
pub use model::{
    Model, ModelError, Part, PartForm, PositionFactor, PositionTerm, Summand, MAX_MODEL_DIFFERENCES,
};
pub use recorded::RecordedRun;
pub use rls::{Rls, SwitchRule};
pub use update_period::{travel_per_update_mm, update_error_fraction};

// Re-exported so that doc examples and hosted users can name `String`/`vec!` without `std`.
#[doc(hidden)]
pub use alloc::{string::String, vec};
