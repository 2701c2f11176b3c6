//! The kinematics table of seed B: a machine's geometry as a chain of fixed transformations and
//! machine axes read from the tool centre point (TCP) towards the workpiece, with **error
//! transformations** whose values come from axis-specific compensation tables
//! ([`crate::table::CompTable`]) interpolated at the current axis position.
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
//! Seed B's head (rows 0–6, Fig. 2c) reads: `Trans Z -L` · `Trans X F_A_X(A)` ·
//! `Trans B F_A_B(A)` · `MachAxis A` · `Trans X L'` · `Trans Y L''` · `MachAxis C`, followed
//! here by the linear axes that carry the head.
//!
//! Lengths are mm and angles degrees at this interface; inside, rotations are radians.
//! Evaluation ([`Chain::forward`], [`Chain::inverse`]) allocates nothing, does no I/O and
//! returns a [`KinError`] instead of panicking or producing NaN.

use alloc::string::String;
use alloc::vec::Vec;
use core::f64::consts::PI;
use core::fmt;

use crate::evaluate::Correction;
use crate::machine::{AxisKind, MAX_AXES};
use crate::table::{CompTable, Direction};

mod forward;
mod inverse;

pub use inverse::InverseReport;

const DEG: f64 = PI / 180.0;

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

/// An axis-specific compensation table referenced by error rows.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorTable {
    /// Name the rows refer to (`F_A_X`).
    pub name: String,
    /// Index of the axis (in [`Chain::axes`]) whose position reads the table.
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

/// Tool position and direction in workpiece coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// TCP in mm.
    pub position: [f64; 3],
    /// Unit tool direction (from the tip into the spindle).
    pub direction: [f64; 3],
}

/// Travel direction of each axis, for directional (forward/reverse) tables: bit j set means
/// axis j last moved towards smaller positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Directions(pub u16);

impl Directions {
    /// The direction of axis `j`.
    pub fn of(self, j: usize) -> Direction {
        if self.0 >> j & 1 == 1 {
            Direction::Reverse
        } else {
            Direction::Forward
        }
    }
}

/// Whether the error tables take part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Geometry {
    /// The nominal chain: error rows contribute their nominal part only.
    Nominal,
    /// The real chain: error rows add their tables' values.
    Actual,
}

/// What an error row reads: its cubics in the chain's flat array (scaled to mm or radians,
/// with the row's nominal part in the constant term) and where to find the segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ErrRef {
    /// Nominal part (mm or rad): the value of the nominal chain.
    pub offset: f64,
    /// d(axis position in mm or degrees) / d(internal unknown in mm or rad), for the Jacobian.
    pub per_unit: f64,
    /// First cubic of the forward and of the reverse column in `Chain::cubics` (the same for
    /// a table without a reverse column, so the direction costs a select, not a branch).
    pub forward: u32,
    pub reverse: u32,
    /// The table whose support points locate the axis position.
    pub table: u16,
    /// The axis whose position reads the table.
    pub axis: u8,
    /// False if the error row before this one reads a table of the same axis with the same
    /// support points: the axis position's segment found there serves this row too.
    pub relocate: bool,
}

// One compiled row. Angles in radians, lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Step {
    Translate {
        k: usize,
        v: f64,
    },
    Tool {
        k: usize,
        sign: f64,
        offset: f64,
    },
    Rotate {
        k: usize,
        c: f64,
        s: f64,
    },
    ErrTranslate {
        k: usize,
        e: ErrRef,
    },
    ErrRotate {
        k: usize,
        e: ErrRef,
    },
    // Error rows whose table has one value everywhere (squareness errors): the real and the
    // nominal value are fixed, so no lookup and, for rotations, no sine per transform.
    ConstErrTranslate {
        k: usize,
        v: f64,
        nominal: f64,
    },
    ConstErrRotate {
        k: usize,
        c: f64,
        s: f64,
        nominal_c: f64,
        nominal_s: f64,
    },
    AxisTranslate {
        k: usize,
        axis: usize,
        sign: f64,
    },
    AxisRotate {
        k: usize,
        axis: usize,
        sign: f64,
    },
    // Consecutive error rows of one slide (see [`Slide`]), index into `Chain::slides`.
    Slide {
        index: usize,
    },
}

/// Consecutive error rows that read tables of one linear axis on the same support points,
/// in the order translations (X, Y, Z, at most one each) then rotations about X, Y, Z (at
/// most one each, in this order): the six errors of a slide in ISO 230-1. One step evaluates
/// them with one table search, one direction select and one bounds check, with the
/// coordinate of every translation and rotation known in the code (no select, no dispatch
/// per row). The operations and their order are those of the separate rows, so the results
/// are the same to the last bit. Formed only in chains without rotary axes (whose 5-axis
/// analysis reads the rotation rows one by one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Slide {
    /// First block of six cubics (slots X, Y, Z, A, B, C; zero where the slot is empty;
    /// coefficients by power, see `Location::cubics`) of the forward and the reverse column in
    /// `Chain::slide_cubics`, one block per segment.
    pub forward: u32,
    pub reverse: u32,
    /// The table whose support points locate the axis position.
    pub table: u16,
    /// The axis whose position reads the tables.
    pub axis: u8,
    /// Bit s: slot s holds a row.
    pub present: u8,
    /// d(axis position in mm) / d(internal unknown in mm).
    pub per_unit: f64,
    /// Nominal parts of the slots (mm, rad; zero where empty).
    pub nominal: [f64; 6],
}

/// What the inverse transform knows about the chain's structure, found once at build time.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // built once per chain
pub(crate) enum Layout {
    /// Three linear axes and no rotary axis; `affine` is the nominal chain as an affine map
    /// (found once the chain is built; `None` if the axes cannot move the TCP everywhere).
    ThreeAxis {
        linear: [usize; 3],
        affine: Option<inverse::Affine>,
    },
    /// Three linear and two rotary axes: Paden–Kahan subproblem 2 for the rotations, a 3×3
    /// linear system for the translations.
    FiveAxis(inverse::FiveAxis),
    /// Anything else: damped least squares from the previous set-point.
    General,
}

/// A checked kinematics table, ready for per-point transforms.
#[derive(Debug, Clone)]
pub struct Chain {
    axes: Vec<KinAxis>,
    tables: Vec<ErrorTable>,
    rows: Vec<Row>,
    steps: Vec<Step>,
    // The cubics of every error row's table, one block per row and column, scaled to mm or
    // radians with the row's nominal part added to the constant term: a lookup is one index
    // into this array (no table, unit or offset indirection per row).
    cubics: Vec<[f64; 4]>,
    // Slides of a chain without rotary axes (see [`Slide`]) and their cubics.
    slides: Vec<Slide>,
    slide_cubics: Vec<[[f64; 6]; 4]>,
    layout: Layout,
    // Bit j: axis j is rotary and every table it reads repeats every 360°, so whole turns of
    // it change nothing (found once here rather than per inverse transform).
    periodic: u16,
}

impl Chain {
    /// Builds and checks a chain: every axis driven by exactly one row of a fitting direction,
    /// every table of a fitting unit, all values finite.
    pub fn new(
        axes: Vec<KinAxis>,
        tables: Vec<ErrorTable>,
        rows: Vec<Row>,
    ) -> Result<Self, ChainError> {
        if axes.is_empty() || axes.len() > MAX_AXES {
            return Err(ChainError::AxisCount(axes.len()));
        }
        for a in &axes {
            if !(a.travel_min.is_finite()
                && a.travel_max.is_finite()
                && a.travel_max > a.travel_min)
            {
                return Err(ChainError::BadValue {
                    what: alloc::format!("travel of axis `{}`", a.name),
                });
            }
        }
        for t in &tables {
            if t.axis >= axes.len() {
                return Err(ChainError::BadTableAxis {
                    table: t.name.clone(),
                });
            }
        }
        let mut uses = alloc::vec![0usize; axes.len()];
        let mut steps = Vec::with_capacity(rows.len());
        let mut cubics: Vec<[f64; 4]> = Vec::new();
        // The table of the previous error row (see `Step::ErrRotate::relocate`).
        let mut last_table: Option<&ErrorTable> = None;
        for (i, row) in rows.iter().enumerate() {
            let bad = |what: &str| ChainError::BadValue {
                what: alloc::format!("row {i}: {what}"),
            };
            let step = match *row {
                Row::Fixed { dof, value } => {
                    if !value.is_finite() {
                        return Err(bad("value"));
                    }
                    if dof.is_rotation() {
                        let (s, c) = sincos(value * DEG);
                        Step::Rotate {
                            k: dof.coordinate(),
                            c,
                            s,
                        }
                    } else {
                        Step::Translate {
                            k: dof.coordinate(),
                            v: value,
                        }
                    }
                }
                Row::Tool { dof, sign, offset } => {
                    if dof.is_rotation() {
                        return Err(ChainError::ToolNotTranslation { row: i });
                    }
                    if !(offset.is_finite() && (sign == 1.0 || sign == -1.0)) {
                        return Err(bad("tool offset or sign"));
                    }
                    Step::Tool {
                        k: dof.coordinate(),
                        sign,
                        offset,
                    }
                }
                Row::Error { dof, offset, table } => {
                    let t = tables
                        .get(table)
                        .ok_or(ChainError::BadReference { row: i })?;
                    if t.unit.is_angle() != dof.is_rotation() {
                        return Err(ChainError::UnitMismatch { row: i });
                    }
                    if !offset.is_finite() {
                        return Err(bad("value"));
                    }
                    let (k, scale) = (dof.coordinate(), t.unit.scale());
                    let offset = if dof.is_rotation() {
                        offset * DEG
                    } else {
                        offset
                    };
                    if let Some(v) = constant_value(&t.table) {
                        // Leaves `last_table` alone: the next row may share the location
                        // found before this one, which this row does not touch.
                        let value = offset + scale * v;
                        steps.push(if dof.is_rotation() {
                            let (s, c) = sincos(value);
                            let (nominal_s, nominal_c) = sincos(offset);
                            Step::ConstErrRotate {
                                k,
                                c,
                                s,
                                nominal_c,
                                nominal_s,
                            }
                        } else {
                            Step::ConstErrTranslate {
                                k,
                                v: value,
                                nominal: offset,
                            }
                        });
                        continue;
                    }
                    let relocate = last_table.is_none_or(|o: &ErrorTable| {
                        o.axis != t.axis || !o.table.same_support(&t.table)
                    });
                    last_table = Some(t);
                    // This row's value is offset + scale · table: fold both into the cubics.
                    let mut block = |direction: Direction| -> Result<u32, ChainError> {
                        let start = u32::try_from(cubics.len()).map_err(|_| bad("tables"))?;
                        cubics.extend(t.table.cubics(direction).iter().map(|c| {
                            [
                                offset + scale * c[0],
                                scale * c[1],
                                scale * c[2],
                                scale * c[3],
                            ]
                        }));
                        Ok(start)
                    };
                    let forward = block(Direction::Forward)?;
                    let reverse = if t.table.reverse().is_some() {
                        block(Direction::Reverse)?
                    } else {
                        forward
                    };
                    let e = ErrRef {
                        offset,
                        per_unit: match axes[t.axis].kind {
                            AxisKind::Linear => 1.0,
                            AxisKind::Rotary => 1.0 / DEG,
                        },
                        forward,
                        reverse,
                        // MAX_AXES (9) axes and far fewer than 65536 tables in any file.
                        table: u16::try_from(table).map_err(|_| bad("table index"))?,
                        axis: u8::try_from(t.axis).map_err(|_| bad("axis index"))?,
                        relocate,
                    };
                    if dof.is_rotation() {
                        Step::ErrRotate { k, e }
                    } else {
                        Step::ErrTranslate { k, e }
                    }
                }
                Row::Axis { dof, axis, sign } => {
                    let a = axes.get(axis).ok_or(ChainError::BadReference { row: i })?;
                    if (a.kind == AxisKind::Rotary) != dof.is_rotation() {
                        return Err(ChainError::KindMismatch { row: i });
                    }
                    if !(sign == 1.0 || sign == -1.0) {
                        return Err(bad("sign"));
                    }
                    uses[axis] += 1;
                    if dof.is_rotation() {
                        Step::AxisRotate {
                            k: dof.coordinate(),
                            axis,
                            sign,
                        }
                    } else {
                        Step::AxisTranslate {
                            k: dof.coordinate(),
                            axis,
                            sign,
                        }
                    }
                }
            };
            steps.push(step);
        }
        for (a, &n) in axes.iter().zip(&uses) {
            if n != 1 {
                return Err(ChainError::AxisUse {
                    axis: a.name.clone(),
                    rows: n,
                });
            }
        }
        let layout = inverse::analyse(&axes, &steps);
        let (steps, slides, slide_cubics) = if axes.iter().all(|a| a.kind == AxisKind::Linear) {
            slides(steps, &cubics, &tables).map_err(|_| ChainError::BadValue {
                what: "tables".into(),
            })?
        } else {
            (steps, Vec::new(), Vec::new())
        };
        let mut periodic = 0u16;
        for (j, a) in axes.iter().enumerate() {
            let wraps = tables
                .iter()
                .filter(|t| t.axis == j)
                .all(|t| t.table.wrap() == crate::table::Wrap::Rotary);
            if a.kind == AxisKind::Rotary && wraps {
                periodic |= 1 << j;
            }
        }
        let mut chain = Self {
            axes,
            tables,
            rows,
            steps,
            cubics,
            slides,
            slide_cubics,
            layout,
            periodic,
        };
        if let Layout::ThreeAxis { linear, .. } = chain.layout {
            let affine = inverse::affine(&chain, &linear);
            chain.layout = Layout::ThreeAxis { linear, affine };
        }
        Ok(chain)
    }

    /// The axes in set-point order.
    pub fn axes(&self) -> &[KinAxis] {
        &self.axes
    }

    /// The error tables.
    pub fn tables(&self) -> &[ErrorTable] {
        &self.tables
    }

    /// The rows, from the TCP towards the workpiece.
    pub fn rows(&self) -> &[Row] {
        &self.rows
    }

    /// A copy of this chain with every table value set to zero (for tests and comparisons).
    pub fn with_zero_tables(&self) -> Self {
        let mut c = self.clone();
        for t in &mut c.tables {
            let zeros = alloc::vec![0.0; t.table.positions().len()];
            let rebuilt = match t.table.reverse() {
                Some(_) => CompTable::directional(
                    t.table.positions().to_vec(),
                    zeros.clone(),
                    zeros,
                    t.table.wrap(),
                    t.table.interpolation(),
                ),
                None => CompTable::new(
                    t.table.positions().to_vec(),
                    zeros,
                    t.table.wrap(),
                    t.table.interpolation(),
                ),
            };
            // Same positions as a valid table: rebuilding cannot fail.
            if let Ok(z) = rebuilt {
                t.table = z;
            }
        }
        // The flat cubics are copies of the tables: build them again (from a valid chain's
        // parts this cannot fail; the clone would keep the old values, so prefer the rebuild).
        Self::new(c.axes.clone(), c.tables.clone(), c.rows.clone()).unwrap_or(c)
    }

    /// Name of the closed form the inverse transform uses: `3-axis`, `5-axis` or
    /// `damped least squares`.
    pub fn layout_name(&self) -> &'static str {
        match self.layout {
            Layout::ThreeAxis { .. } => "3-axis",
            Layout::FiveAxis(_) => "5-axis",
            Layout::General => "damped least squares",
        }
    }

    fn rotary_count(&self) -> usize {
        self.axes
            .iter()
            .filter(|a| a.kind == AxisKind::Rotary)
            .count()
    }
}

/// Slot of an error row in a [`Slide`] (0–2 translations, 3–5 rotations) and its [`ErrRef`].
fn slot(step: &Step) -> Option<(usize, ErrRef)> {
    match *step {
        Step::ErrTranslate { k, e } => Some((k, e)),
        Step::ErrRotate { k, e } => Some((3 + k, e)),
        _ => None,
    }
}

type Slides = (Vec<Step>, Vec<Slide>, Vec<[[f64; 6]; 4]>);

/// Replaces every run of error rows that fits a [`Slide`] by one slide step (the first row
/// of a run that does not fit starts the next run).
fn slides(steps: Vec<Step>, cubics: &[[f64; 4]], tables: &[ErrorTable]) -> Result<Slides, ()> {
    let mut out = Vec::with_capacity(steps.len());
    let mut slides = Vec::new();
    let mut slide_cubics: Vec<[[f64; 6]; 4]> = Vec::new();
    let mut i = 0;
    while i < steps.len() {
        let Some((first_slot, first)) = slot(&steps[i]) else {
            out.push(steps[i]);
            i += 1;
            continue;
        };
        // rows[s]: the ErrRef of slot s; a run takes slots in increasing order, so the
        // translations come first and each rotation follows the previous one in X, Y, Z order
        // (translations along different coordinates commute exactly; rotations do not).
        let mut rows: [Option<ErrRef>; 6] = [None; 6];
        rows[first_slot] = Some(first);
        let (mut last, mut j) = (first_slot, i + 1);
        while let Some((s, e)) = steps.get(j).and_then(slot) {
            let next_translation = s < 3 && last < 3 && rows[s].is_none();
            let next_rotation = s >= 3 && s > last;
            if e.relocate || e.axis != first.axis || !(next_translation || next_rotation) {
                break;
            }
            rows[s] = Some(e);
            last = last.max(s);
            j += 1;
        }
        let segments = tables[usize::from(first.table)]
            .table
            .cubics(Direction::Forward)
            .len();
        let mut block = |reverse: bool| -> Result<u32, ()> {
            let start = u32::try_from(slide_cubics.len()).map_err(|_| ())?;
            for seg in 0..segments {
                let mut b = [[0.0; 6]; 4];
                for (s, row) in rows.iter().enumerate() {
                    if let Some(e) = row {
                        let base = if reverse { e.reverse } else { e.forward };
                        let c = cubics.get(base as usize + seg).ok_or(())?;
                        for (power, &v) in c.iter().enumerate() {
                            b[power][s] = v;
                        }
                    }
                }
                slide_cubics.push(b);
            }
            Ok(start)
        };
        let forward = block(false)?;
        let reverse = block(true)?;
        let mut slide = Slide {
            forward,
            reverse,
            table: first.table,
            axis: first.axis,
            present: 0,
            per_unit: first.per_unit,
            nominal: [0.0; 6],
        };
        for (s, row) in rows.iter().enumerate() {
            if let Some(e) = row {
                slide.present |= 1 << s;
                slide.nominal[s] = e.offset;
            }
        }
        out.push(Step::Slide {
            index: slides.len(),
        });
        slides.push(slide);
        i = j;
    }
    Ok((out, slides, slide_cubics))
}

/// The value of a table that has the same value at every position and in both directions of
/// travel (every segment's cubic is that constant), else `None`.
fn constant_value(table: &CompTable) -> Option<f64> {
    let v = table.cubics(Direction::Forward).first()?[0];
    let constant = [Direction::Forward, Direction::Reverse]
        .iter()
        .flat_map(|&d| table.cubics(d))
        .all(|c| *c == [v, 0.0, 0.0, 0.0]);
    constant.then_some(v)
}

/// Superimposes the per-axis compensation of a thermal model (seed A's "other parts": a
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
