//! Why a chain cannot be built ([`ChainError`], at load time) and why a transform produced no
//! result ([`KinError`], per point, `Copy`).

use alloc::string::String;
use core::fmt;

use truepos_model::MAX_AXES;

/// Why a chain cannot be built.
#[derive(Debug, Clone, PartialEq)]
pub enum ChainError {
    /// The chain has no axes, or more than [`MAX_AXES`].
    AxisCount(usize),
    /// Row `row` refers to a table or axis that does not exist.
    BadReference {
        /// Row number.
        row: usize,
    },
    /// Row `row` drives an axis whose kind does not fit the row direction (a rotary axis in a
    /// translation row or the other way round).
    KindMismatch {
        /// Row number.
        row: usize,
    },
    /// Row `row` uses a table whose unit does not fit its direction (µm in a rotation row).
    UnitMismatch {
        /// Row number.
        row: usize,
    },
    /// Axis `axis` appears in no row or in more than one.
    AxisUse {
        /// Axis name.
        axis: String,
        /// Number of rows that drive it.
        rows: usize,
    },
    /// A value or travel is not finite, a travel is empty, or a sign is not ±1.
    BadValue {
        /// Where.
        what: String,
    },
    /// A table reads the position of an axis that does not exist.
    BadTableAxis {
        /// Table name.
        table: String,
    },
    /// A tool row is not a translation.
    ToolNotTranslation {
        /// Row number.
        row: usize,
    },
}

impl fmt::Display for ChainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::AxisCount(n) => write!(f, "{n} axes; expected 1 to {MAX_AXES}"),
            Self::BadReference { row } => write!(f, "row {row} refers to an unknown table or axis"),
            Self::KindMismatch { row } => write!(
                f,
                "row {row}: a linear axis must be X, Y or Z and a rotary axis A, B or C"
            ),
            Self::UnitMismatch { row } => write!(
                f,
                "row {row}: the table's unit does not fit the direction (lengths for X/Y/Z, angles for A/B/C)"
            ),
            Self::AxisUse { axis, rows } => write!(
                f,
                "axis `{axis}` is driven by {rows} MachAxis rows; expected exactly one"
            ),
            Self::BadValue { what } => write!(f, "{what}: not a usable value"),
            Self::BadTableAxis { table } => {
                write!(f, "table `{table}` reads an axis that is not in the chain")
            }
            Self::ToolNotTranslation { row } => {
                write!(f, "row {row}: the tool length can only enter a translation (X, Y, Z)")
            }
        }
    }
}

impl core::error::Error for ChainError {}

/// Why a transform produced no result. `Copy`, so reporting it needs no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KinError {
    /// The slice of axis positions does not have one value per axis.
    AxisCount {
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// An input (position, direction, tool length, set-point) is NaN or infinite.
    NonFinite,
    /// The tool direction has zero length.
    ZeroDirection,
    /// No axis positions give this tool direction (outside the reach of the rotary axes).
    UnreachableDirection,
    /// Every solution puts this axis outside its travel.
    OutsideTravel {
        /// Axis index.
        axis: usize,
        /// The nearest set-point found.
        value: f64,
    },
    /// The linear axes cannot move the TCP in every direction at this pose.
    Singular,
    /// Newton did not meet the tolerances.
    NotConverged {
        /// Remaining TCP deviation in mm.
        position_mm: f64,
        /// Remaining tool direction deviation in rad.
        direction_rad: f64,
    },
}

impl fmt::Display for KinError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::AxisCount { expected, got } => {
                write!(f, "expected {expected} axis positions, got {got}")
            }
            Self::NonFinite => write!(f, "an input is not a finite number"),
            Self::ZeroDirection => write!(f, "the tool direction has zero length"),
            Self::UnreachableDirection => {
                write!(
                    f,
                    "no position of the rotary axes gives this tool direction"
                )
            }
            Self::OutsideTravel { axis, value } => {
                write!(
                    f,
                    "axis #{axis} would have to move to {value}, outside its travel"
                )
            }
            Self::Singular => write!(f, "the axes cannot move the tool in every direction here"),
            Self::NotConverged {
                position_mm,
                direction_rad,
            } => write!(
                f,
                "did not converge: {position_mm:e} mm and {direction_rad:e} rad left"
            ),
        }
    }
}

impl core::error::Error for KinError {}
