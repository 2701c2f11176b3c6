//! # truepos-kinematics — the kinematics table with error tables
//!
//! A machine's geometry as a chain of fixed transformations and
//! machine axes read from the tool centre point (TCP) towards the workpiece, with **error
//! transformations** whose values come from axis-specific compensation tables
//! ([`table::CompTable`]) interpolated at the current axis position; ISO 230-1's errors of a
//! slide (three straightness/position errors and three angular errors per linear axis) are such
//! rows.
//!
//! # Convention
//! Frame 0 has its origin at the TCP and its +Z axis along the tool, pointing from the tip into
//! the spindle (the `I J K` direction of 5-axis programs). Each [`Row`] maps coordinates of the
//! frame on its tool side (i) into the frame on its workpiece side (i + 1):
//!
//! * a translation along X/Y/Z by v: x_{i+1} = x_i + v·e_k;
//! * a rotation about X/Y/Z (A/B/C) by θ (right-hand rule): x_{i+1} = R_k(θ)·x_i.
//!
//! The pose of the tool in workpiece coordinates is P = M_{n−1}⋯M_1·M_0: the TCP is P·0 and the
//! tool direction R_P·e_z. The gauge point of the spindle lies L above the tip, so the tool
//! length row is written `Trans Z -L` (coordinates of the tip frame moved by −L·e_z). A
//! machine axis that moves the workpiece instead of the tool (a table axis) appears with the
//! opposite sign (`MachAxis -X`): moving the table by +q moves the tool by −q relative to it.
//!
//! The example 5-axis head (rows 0–6; docs/glossary.md) reads: `Trans Z -L` · `Trans X F_A_X(A)` ·
//! `Trans B F_A_B(A)` · `MachAxis A` · `Trans X L'` · `Trans Y L''` · `MachAxis C`, followed
//! here by the linear axes that carry the head.
//!
//! Lengths are mm and angles degrees at this interface; inside, rotations are radians.
//! Evaluation ([`Chain::forward`], [`Chain::inverse`]) allocates nothing, does no I/O and
//! returns a [`KinError`] instead of panicking or producing NaN.
//!
//! The thermal core (`truepos-model`) does not depend on this crate: a control that compensates
//! thermal errors only links the core; one that runs the kinematics table too links both and
//! adds the thermal correction to the set-points with [`superimpose`]. Like the core, the crate
//! is `#![no_std]` with `alloc` (building a chain allocates, transforms do not) and does its
//! maths beyond `+ − × ÷` through `libm`.
//!
//! ## Example: a straightness error of X in Y
//! Three linear axes and one error row: moving X from −500 mm to +500 mm moves the tool up to
//! 10 µm along Y. The forward transform shows the error; the inverse transform returns
//! set-points that put the real tool on the target, so Y moves by −10 µm.
//!
//! ```
//! use truepos_kinematics::table::{CompTable, Interpolation, Wrap};
//! use truepos_kinematics::*;
//!
//! let axis = |name: &str| KinAxis {
//!     name: name.into(), kind: AxisKind::Linear, travel_min: -500.0, travel_max: 500.0,
//! };
//! let straightness = CompTable::new(
//!     vec![-500.0, 500.0], vec![0.0, 10.0], Wrap::Hold, Interpolation::Linear,
//! ).unwrap();
//! let tables = vec![ErrorTable {
//!     name: "EYX".into(), axis: 0, unit: ErrorUnit::Micrometre, table: straightness,
//! }];
//! // From the tool tip towards the workpiece: tool length, Z, Y, the error of X in Y, X.
//! let rows = vec![
//!     Row::Tool { dof: Dof::Z, sign: -1.0, offset: 0.0 },
//!     Row::Axis { dof: Dof::Z, axis: 2, sign: 1.0 },
//!     Row::Axis { dof: Dof::Y, axis: 1, sign: 1.0 },
//!     Row::Error { dof: Dof::Y, offset: 0.0, table: 0 },
//!     Row::Axis { dof: Dof::X, axis: 0, sign: 1.0 },
//! ];
//! let chain = Chain::new(vec![axis("X"), axis("Y"), axis("Z")], tables, rows).unwrap();
//! let tool_mm = 100.0;
//!
//! let at = [500.0, 0.0, 0.0];
//! let real = chain.forward(&at, tool_mm, Directions::default(), Geometry::Actual).unwrap();
//! assert!((real.position[1] - 0.010).abs() < 1e-12);
//!
//! let target = Pose { position: [500.0, 0.0, -100.0], direction: [0.0, 0.0, 1.0] };
//! let mut q = [0.0; 3];
//! let report = chain
//!     .inverse(&target, tool_mm, &at, Directions::default(), Geometry::Actual, &mut q)
//!     .unwrap();
//! assert!(report.position_residual_mm <= 5e-7);
//! assert!((q[0] - 500.0).abs() < 1e-9 && (q[1] + 0.010).abs() < 1e-9);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

extern crate alloc;

mod chain;
mod description;
mod error;
mod forward;
mod inverse;
pub mod table;

use core::f64::consts::PI;

pub use chain::{Chain, Directions, Geometry, Pose};
pub use description::{Dof, ErrorTable, ErrorUnit, KinAxis, Row};
pub use error::{ChainError, KinError};
pub use inverse::{InverseReport, DIRECTION_TOLERANCE_RAD, POSITION_TOLERANCE_MM};
// Part of this crate's interface (`KinAxis::kind`, the thermal `Correction` of `superimpose`).
pub use truepos_model::{AxisKind, Correction, MAX_AXES};

const DEG: f64 = PI / 180.0;

/// Superimposes the per-axis compensation of a thermal model (one of the "further parts": a
/// [`Correction`] in machine axis order) on set-points from the kinematics: for each chain axis
/// j, `machine_axis[j]` names its machine axis; linear axes get compensation µm / 1000 mm,
/// rotary axes read the model's value as µrad and get it in degrees.
///
/// The result is the set-point the drive receives: geometric compensation (through the chain)
/// plus thermal compensation (−predicted error).
pub fn superimpose(
    chain: &Chain,
    setpoints: &mut [f64],
    correction: &Correction,
    machine_axis: &[usize],
) {
    for ((q, axis), &m) in setpoints.iter_mut().zip(chain.axes()).zip(machine_axis) {
        let c = correction.compensation_um(m);
        *q += match axis.kind {
            AxisKind::Linear => c * 1e-3,
            AxisKind::Rotary => c * 1e-6 / DEG,
        };
    }
}

/// sin and cos, exact to double precision; the series for tiny error angles is faster than
/// libm and returns (0, 1) exactly at 0, so a zero error rotation is an exact identity.
#[inline]
pub(crate) fn sincos(x: f64) -> (f64, f64) {
    if libm::fabs(x) < 1e-3 {
        // Taylor series; the first terms left out are x⁷/5040 (relative 2e-22 of sin x) and
        // x⁶/720 < 1.4e-21: both below the double epsilon 2.2e-16.
        let x2 = x * x;
        let sin = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0)));
        let cos = 1.0 - x2 * 0.5 * (1.0 - x2 * (1.0 / 12.0));
        (sin, cos)
    } else {
        libm::sincos(x)
    }
}
