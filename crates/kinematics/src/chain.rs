//! The checked, compiled chain ([`Chain`]): every row turned into a step that a transform
//! evaluates without lookups by name or unit, error rows' tables folded into one flat array of
//! cubics, the error rows of a slide merged, and the structure the inverse transform uses
//! found once.

use alloc::vec::Vec;

use truepos_model::{AxisKind, MAX_AXES};

use crate::description::{Dof, ErrorTable, KinAxis, Row};
use crate::error::ChainError;
use crate::inverse;
use crate::table::{CompTable, Direction, Wrap};
use crate::{sincos, DEG};

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
    pub(crate) axes: Vec<KinAxis>,
    pub(crate) tables: Vec<ErrorTable>,
    pub(crate) rows: Vec<Row>,
    pub(crate) steps: Vec<Step>,
    // The cubics of every error row's table, one block per row and column, scaled to mm or
    // radians with the row's nominal part added to the constant term: a lookup is one index
    // into this array (no table, unit or offset indirection per row).
    pub(crate) cubics: Vec<[f64; 4]>,
    // Slides of a chain without rotary axes (see [`Slide`]) and their cubics.
    pub(crate) slides: Vec<Slide>,
    pub(crate) slide_cubics: Vec<[[f64; 6]; 4]>,
    pub(crate) layout: Layout,
    // Bit j: axis j is rotary and every table it reads repeats every 360°, so whole turns of
    // it change nothing (found once here rather than per inverse transform).
    pub(crate) periodic: u16,
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
        // The table of the previous error row (see `ErrRef::relocate`).
        let mut last: Option<&ErrorTable> = None;
        for (i, row) in rows.iter().enumerate() {
            let step = match *row {
                Row::Fixed { dof, value } => fixed_step(i, dof, value)?,
                Row::Tool { dof, sign, offset } => tool_step(i, dof, sign, offset)?,
                Row::Error { dof, offset, table } => error_step(
                    i,
                    dof,
                    offset,
                    table,
                    (&axes, &tables),
                    &mut last,
                    &mut cubics,
                )?,
                Row::Axis { dof, axis, sign } => {
                    let step = axis_step(i, dof, axis, sign, &axes)?;
                    uses[axis] += 1;
                    step
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
        let periodic = periodic_axes(&axes, &tables);
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

    pub(crate) fn rotary_count(&self) -> usize {
        self.axes
            .iter()
            .filter(|a| a.kind == AxisKind::Rotary)
            .count()
    }
}

/// The step of a fixed row: a constant rotation (its sine and cosine found once here) or
/// translation.
fn fixed_step(i: usize, dof: Dof, value: f64) -> Result<Step, ChainError> {
    if !value.is_finite() {
        return Err(ChainError::BadValue {
            what: alloc::format!("row {i}: value"),
        });
    }
    Ok(if dof.is_rotation() {
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
    })
}

/// The step of the tool row: a translation by sign · tool length + offset, so that the
/// active tool's length enters the chain at this row.
fn tool_step(i: usize, dof: Dof, sign: f64, offset: f64) -> Result<Step, ChainError> {
    if dof.is_rotation() {
        return Err(ChainError::ToolNotTranslation { row: i });
    }
    if !(offset.is_finite() && (sign == 1.0 || sign == -1.0)) {
        return Err(ChainError::BadValue {
            what: alloc::format!("row {i}: tool offset or sign"),
        });
    }
    Ok(Step::Tool {
        k: dof.coordinate(),
        sign,
        offset,
    })
}

/// The step of an axis row: the axis' set-point as a rotation or translation, which must
/// match the axis' kind.
fn axis_step(
    i: usize,
    dof: Dof,
    axis: usize,
    sign: f64,
    axes: &[KinAxis],
) -> Result<Step, ChainError> {
    let a = axes.get(axis).ok_or(ChainError::BadReference { row: i })?;
    if (a.kind == AxisKind::Rotary) != dof.is_rotation() {
        return Err(ChainError::KindMismatch { row: i });
    }
    if !(sign == 1.0 || sign == -1.0) {
        return Err(ChainError::BadValue {
            what: alloc::format!("row {i}: sign"),
        });
    }
    Ok(if dof.is_rotation() {
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
    })
}

/// The rotary axes (bit j for axis j) whose every table repeats every 360°, so whole turns
/// of them change nothing; found once here rather than per inverse transform.
fn periodic_axes(axes: &[KinAxis], tables: &[ErrorTable]) -> u16 {
    let mut periodic = 0u16;
    for (j, a) in axes.iter().enumerate() {
        let wraps = tables
            .iter()
            .filter(|t| t.axis == j)
            .all(|t| t.table.wrap() == Wrap::Rotary);
        if a.kind == AxisKind::Rotary && wraps {
            periodic |= 1 << j;
        }
    }
    periodic
}

/// The step of error row `i` (see [`Row::Error`]): a fixed step for a constant table, else a
/// reference to the table's cubics, appended to `cubics` with the row's unit and nominal part
/// folded in. `last` is the table of the previous error row that located its position.
fn error_step<'a>(
    i: usize,
    dof: Dof,
    offset: f64,
    table: usize,
    (axes, tables): (&[KinAxis], &'a [ErrorTable]),
    last: &mut Option<&'a ErrorTable>,
    cubics: &mut Vec<[f64; 4]>,
) -> Result<Step, ChainError> {
    let bad = |what: &str| ChainError::BadValue {
        what: alloc::format!("row {i}: {what}"),
    };
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
        // Leaves `last` alone: the next row may share the location found before this one,
        // which this row does not touch.
        let value = offset + scale * v;
        return Ok(if dof.is_rotation() {
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
    }
    let relocate =
        last.is_none_or(|o: &ErrorTable| o.axis != t.axis || !o.table.same_support(&t.table));
    *last = Some(t);
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
    Ok(if dof.is_rotation() {
        Step::ErrRotate { k, e }
    } else {
        Step::ErrTranslate { k, e }
    })
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
