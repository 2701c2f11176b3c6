//! The kinematics table as a file states it: its rows ([`Row`]), machine axes ([`KinAxis`]) and
//! the error tables its error rows read ([`ErrorTable`]), before [`crate::Chain::new`] checks
//! and compiles them.

use alloc::string::String;
use core::f64::consts::PI;

use truepos_model::AxisKind;

use crate::table::CompTable;
use crate::DEG;

/// A direction of a kinematics row: translation along X, Y, Z or rotation about them (A, B, C).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dof {
    /// Translation along X.
    X,
    /// Translation along Y.
    Y,
    /// Translation along Z.
    Z,
    /// Rotation about X.
    A,
    /// Rotation about Y.
    B,
    /// Rotation about Z.
    C,
}

impl Dof {
    /// The letter used in kinematics files.
    pub fn name(self) -> &'static str {
        ["X", "Y", "Z", "A", "B", "C"][self.index6()]
    }

    /// Parses `X` … `C`.
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "X" => Self::X,
            "Y" => Self::Y,
            "Z" => Self::Z,
            "A" => Self::A,
            "B" => Self::B,
            "C" => Self::C,
            _ => return None,
        })
    }

    /// True for A, B, C.
    pub fn is_rotation(self) -> bool {
        matches!(self, Self::A | Self::B | Self::C)
    }

    /// Coordinate index 0, 1, 2 of the direction (X/A → 0, Y/B → 1, Z/C → 2).
    pub fn coordinate(self) -> usize {
        self.index6() % 3
    }

    fn index6(self) -> usize {
        self as usize
    }
}

/// Unit of the values of an error table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorUnit {
    /// Micrometres (translation rows).
    Micrometre,
    /// Millimetres (translation rows).
    Millimetre,
    /// Microradians (rotation rows).
    Microradian,
    /// Arc seconds (rotation rows).
    ArcSecond,
    /// Degrees (rotation rows).
    Degree,
}

impl ErrorUnit {
    /// Parses `um`, `mm`, `urad`, `arcsec`, `deg`.
    pub fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "um" | "µm" => Self::Micrometre,
            "mm" => Self::Millimetre,
            "urad" | "µrad" => Self::Microradian,
            "arcsec" => Self::ArcSecond,
            "deg" => Self::Degree,
            _ => return None,
        })
    }

    /// The name used in kinematics files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Micrometre => "um",
            Self::Millimetre => "mm",
            Self::Microradian => "urad",
            Self::ArcSecond => "arcsec",
            Self::Degree => "deg",
        }
    }

    /// True for angle units.
    pub fn is_angle(self) -> bool {
        matches!(self, Self::Microradian | Self::ArcSecond | Self::Degree)
    }

    /// Factor to mm (lengths) or radians (angles).
    pub fn scale(self) -> f64 {
        match self {
            Self::Micrometre => 1e-3,
            Self::Millimetre => 1.0,
            Self::Microradian => 1e-6,
            Self::ArcSecond => PI / (180.0 * 3600.0),
            Self::Degree => DEG,
        }
    }
}

/// A machine axis of the chain, in set-point order.
#[derive(Debug, Clone, PartialEq)]
pub struct KinAxis {
    /// Name as the control knows it.
    pub name: String,
    /// Linear (mm) or rotary (degrees).
    pub kind: AxisKind,
    /// Lower end of travel.
    pub travel_min: f64,
    /// Upper end of travel.
    pub travel_max: f64,
}

impl KinAxis {
    /// Where the axis starts when no earlier set-point is known: 0 if that is within its
    /// travel, else mid-travel.
    pub fn start_position(&self) -> f64 {
        if self.travel_min <= 0.0 && self.travel_max >= 0.0 {
            0.0
        } else {
            0.5 * (self.travel_min + self.travel_max)
        }
    }
}

/// An axis-specific compensation table referenced by error rows.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorTable {
    /// Name the rows refer to (`F_A_X`).
    pub name: String,
    /// Index of the axis (in [`crate::Chain::axes`]) whose position reads the table.
    pub axis: usize,
    /// Unit of the table's values.
    pub unit: ErrorUnit,
    /// The table.
    pub table: CompTable,
}

/// One row of the kinematics table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Row {
    /// `Trans`: a fixed transformation (mm or degrees).
    Fixed {
        /// Direction.
        dof: Dof,
        /// Length or angle.
        value: f64,
    },
    /// `Trans` by `sign · tool length + offset` (mm): the active tool's length enters here.
    Tool {
        /// Direction (X, Y or Z).
        dof: Dof,
        /// +1 or −1.
        sign: f64,
        /// Fixed part in mm.
        offset: f64,
    },
    /// `Trans` with a compensation table: the nominal value `offset` (mm or degrees) plus the
    /// error read from table `table` at the position of its axis.
    Error {
        /// Direction.
        dof: Dof,
        /// Nominal part (mm or degrees).
        offset: f64,
        /// Index into the chain's tables.
        table: usize,
    },
    /// `MachAxis`: the set-point of machine axis `axis`, times `sign`.
    Axis {
        /// Direction.
        dof: Dof,
        /// Index into the chain's axes.
        axis: usize,
        /// +1 (the axis moves the tool) or −1 (the axis moves the workpiece).
        sign: f64,
    },
}
