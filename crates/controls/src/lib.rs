//! # truepos-controls — a truepos model in the form each control accepts
//!
//! The big controls identify no thermal model; they accept values someone else computes. This crate
//! projects a model — any function giving the error of every axis at given positions, so
//! position-dependent models and fitted dynamic models alike — onto a control's per-axis form,
//! states the projection error, and writes the file that sets the values:
//!
//! - [`projection`]: K0/tanβ/P0 per axis (Siemens SD43900/43910/43920, Beckhoff/ISG's linear
//!   temperature compensation) or a constant per axis, fitted along each axis' travel with the
//!   other axes where they are, with the error along the travel and per other axis;
//! - one module per control, its one home: what sets its values from a projection, and its
//!   compensation-table files read and written —
//!   [`siemens`] (the part program setting the three setting data; `$AA_ENC_COMP`/`$AN_CEC`
//!   tables), [`heidenhain`] (PLC module 9231 offsets, `TEMPCOMP` formulas; `.COM`/`.CMA`
//!   tables), [`isg`] (axis parameters P-AXIS-00271…00274; `kw.ssfk.*` lists), [`fanuc`] (the
//!   line as custom macro variables; pitch error compensation tapes) and [`linuxcnc`] (its
//!   `COMP_FILE`s; the rest of LinuxCNC is the `truepos-hal` component);
//! - [`table`]: what the tables share, and truepos' own CSV form of a table.
//!
//! Sign: a model predicts the error (actual − nominal); every value here is the compensation,
//! its negative, which the control adds to the set-point.
//!
//! ```
//! use truepos_controls::projection::{project, Form};
//! use truepos_model::{Axis, AxisKind, Carriage, Machine};
//! let axis = |name: &str, max: f64| Axis {
//!     name: name.into(), kind: AxisKind::Linear, travel_min: 0.0, travel_max: max,
//!     carried_by: None, carriage: Carriage::Cantilever,
//! };
//! let machine = Machine {
//!     name: "m".into(), axes: vec![axis("X", 800.0), axis("Y", 500.0)],
//!     temperatures: vec![], differences: vec![], operating: vec![],
//! };
//! // X grows 10 µm plus 0.02 µm per mm of X; Y's error follows X a little (cross-axis).
//! let error = |p: &[f64]| Ok(vec![10.0 + 0.02 * p[0], 0.001 * p[0]]);
//! let proj = project(&machine, &error, &[400.0, 250.0], Form::Linear, &[0.0, 0.0]).unwrap();
//! let x = &proj[0];
//! assert!((x.form.k0_mm - -0.010).abs() < 1e-12); // compensation = −error, mm, at P0 = 0
//! assert!((x.form.tan_beta - -0.02e-3).abs() < 1e-15);
//! assert!(x.along_error_um < 1e-9);
//! // Y's compensation moves up to 0.4 µm from its value at X = 400 as X travels 0…800 mm:
//! // the per-axis form cannot carry it.
//! assert!((proj[1].cross_axis[0].change_um - 0.4).abs() < 1e-9);
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod fanuc;
pub mod heidenhain;
pub mod isg;
pub mod linuxcnc;
pub mod projection;
pub mod siemens;
pub mod table;

/// Why a projection or a control file failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControlError {
    /// The model gave no finite error.
    #[error("the model: {0}")]
    Model(String),
    /// The axis positions given are not usable.
    #[error("axis positions: {0}")]
    Positions(String),
    /// A value beyond what the control accepts.
    #[error("{0}")]
    Range(String),
    /// The model has something the control's form cannot carry.
    #[error("{0}")]
    Form(String),
    /// A control file that does not read, named at file:line:column like every file truepos
    /// reads.
    #[error("{0}")]
    Syntax(#[from] truepos_files::InputError),
}
