//! The example machines of `examples/kinematics/`, built in code with synthetic, smooth error
//! tables of realistic size (tens of µm, tens of µrad).
#![allow(dead_code)]

use truepos_kinematics::table::{CompTable, Interpolation, Wrap};
use truepos_kinematics::{Chain, Dof, ErrorTable, ErrorUnit, KinAxis, Row};
use truepos_model::AxisKind;

pub fn lin(name: &str, min: f64, max: f64) -> KinAxis {
    KinAxis {
        name: name.into(),
        kind: AxisKind::Linear,
        travel_min: min,
        travel_max: max,
    }
}

pub fn rot(name: &str, min: f64, max: f64) -> KinAxis {
    KinAxis {
        name: name.into(),
        kind: AxisKind::Rotary,
        travel_min: min,
        travel_max: max,
    }
}

/// A table sampled from `f` at `n` support points over [lo, hi] (rotary: [0, 360) every
/// 360/n degrees).
#[allow(clippy::too_many_arguments)]
pub fn table(
    name: &str,
    axis: usize,
    unit: ErrorUnit,
    rotary: bool,
    lo: f64,
    hi: f64,
    n: usize,
    f: impl Fn(f64) -> f64,
) -> ErrorTable {
    let (pos, wrap): (Vec<f64>, Wrap) = if rotary {
        (
            (0..n).map(|i| 360.0 * i as f64 / n as f64).collect(),
            Wrap::Rotary,
        )
    } else {
        (
            (0..n)
                .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
                .collect(),
            Wrap::Hold,
        )
    };
    let values = pos.iter().map(|&p| f(p)).collect();
    ErrorTable {
        name: name.into(),
        axis,
        unit,
        table: CompTable::new(pos, values, wrap, Interpolation::MonotoneCubic).unwrap(),
    }
}

fn s(deg: f64) -> f64 {
    deg.to_radians().sin()
}

fn tool(offset: f64) -> Row {
    Row::Tool {
        dof: Dof::Z,
        sign: -1.0,
        offset,
    }
}
fn fixed(dof: Dof, value: f64) -> Row {
    Row::Fixed { dof, value }
}
fn err(dof: Dof, table: usize) -> Row {
    Row::Error {
        dof,
        offset: 0.0,
        table,
    }
}
fn axis(dof: Dof, axis: usize, sign: f64) -> Row {
    Row::Axis { dof, axis, sign }
}

/// Document B's head: A swivels in a fork that rotates about C; the head rides on Z, Y, X.
/// Axes: X Y Z A C. Pole: A = 0.
pub fn head_ac() -> Chain {
    let axes = vec![
        lin("X", -1000.0, 1000.0),
        lin("Y", -800.0, 800.0),
        lin("Z", -600.0, 600.0),
        rot("A", -110.0, 110.0),
        rot("C", -720.0, 720.0),
    ];
    let tables = vec![
        table("F_A_X", 3, ErrorUnit::Micrometre, true, 0.0, 0.0, 36, |a| {
            12.0 * s(a) + 3.0 * s(2.0 * a + 20.0)
        }),
        table(
            "F_A_B",
            3,
            ErrorUnit::Microradian,
            true,
            0.0,
            0.0,
            36,
            |a| 40.0 * s(a + 15.0),
        ),
        table("F_C_Y", 4, ErrorUnit::Micrometre, true, 0.0, 0.0, 72, |c| {
            6.0 * s(c) - 2.0 * s(3.0 * c)
        }),
        table(
            "F_C_A",
            4,
            ErrorUnit::Microradian,
            true,
            0.0,
            0.0,
            72,
            |c| 25.0 * s(c + 40.0),
        ),
    ];
    let rows = vec![
        tool(-150.0),
        err(Dof::X, 0),
        err(Dof::B, 1),
        axis(Dof::A, 3, 1.0),
        fixed(Dof::X, 0.02),
        fixed(Dof::Y, -0.015),
        err(Dof::Y, 2),
        err(Dof::A, 3),
        axis(Dof::C, 4, 1.0),
        fixed(Dof::Z, 400.0),
        axis(Dof::Z, 2, 1.0),
        axis(Dof::Y, 1, 1.0),
        axis(Dof::X, 0, 1.0),
    ];
    Chain::new(axes, tables, rows).unwrap()
}

/// Table-table trunnion: A cradle carries the C table; the spindle moves X Y Z.
/// Axes: X Y Z A C. Pole: A = 0 (C axis along the tool).
pub fn table_ac() -> Chain {
    let axes = vec![
        lin("X", -600.0, 600.0),
        lin("Y", -600.0, 600.0),
        lin("Z", -300.0, 800.0),
        rot("A", -120.0, 30.0),
        rot("C", -720.0, 720.0),
    ];
    let tables = vec![
        table(
            "F_A_Z",
            3,
            ErrorUnit::Micrometre,
            false,
            -120.0,
            30.0,
            16,
            |a| 8.0 * s(a) + 0.02 * a,
        ),
        table(
            "F_A_B",
            3,
            ErrorUnit::Microradian,
            false,
            -120.0,
            30.0,
            16,
            |a| 30.0 * s(2.0 * a),
        ),
        table("F_C_X", 4, ErrorUnit::Micrometre, true, 0.0, 0.0, 36, |c| {
            5.0 * s(c)
        }),
        table(
            "F_C_A",
            4,
            ErrorUnit::Microradian,
            true,
            0.0,
            0.0,
            36,
            |c| 15.0 * s(c + 30.0),
        ),
    ];
    let rows = vec![
        tool(0.0),
        axis(Dof::Z, 2, 1.0),
        axis(Dof::Y, 1, 1.0),
        axis(Dof::X, 0, 1.0),
        fixed(Dof::Z, -250.0),
        fixed(Dof::Y, 0.03),
        axis(Dof::A, 3, -1.0),
        err(Dof::Z, 0),
        err(Dof::B, 1),
        fixed(Dof::Z, 80.0),
        axis(Dof::C, 4, -1.0),
        err(Dof::X, 2),
        err(Dof::A, 3),
        fixed(Dof::Z, -20.0),
    ];
    Chain::new(axes, tables, rows).unwrap()
}

/// Head-head: B swivel on a C fork; the head rides on Z, Y, X. Axes: X Y Z B C. Pole: B = 0.
pub fn head_bc() -> Chain {
    let axes = vec![
        lin("X", -1000.0, 1000.0),
        lin("Y", -800.0, 800.0),
        lin("Z", -600.0, 600.0),
        rot("B", -100.0, 100.0),
        rot("C", -720.0, 720.0),
    ];
    let tables = vec![
        table("F_B_Z", 3, ErrorUnit::Micrometre, true, 0.0, 0.0, 36, |b| {
            10.0 * s(b) * s(b)
        }),
        table(
            "F_B_A",
            3,
            ErrorUnit::Microradian,
            true,
            0.0,
            0.0,
            36,
            |b| 20.0 * s(b - 10.0),
        ),
        table("F_C_X", 4, ErrorUnit::Micrometre, true, 0.0, 0.0, 36, |c| {
            4.0 * s(2.0 * c)
        }),
    ];
    let rows = vec![
        tool(-120.0),
        err(Dof::Z, 0),
        err(Dof::A, 1),
        axis(Dof::B, 3, 1.0),
        fixed(Dof::Y, 0.01),
        err(Dof::X, 2),
        axis(Dof::C, 4, 1.0),
        fixed(Dof::Z, 350.0),
        axis(Dof::Z, 2, 1.0),
        axis(Dof::Y, 1, 1.0),
        axis(Dof::X, 0, 1.0),
    ];
    Chain::new(axes, tables, rows).unwrap()
}

/// 3-axis machine with the 21 errors of ISO 230-1: per axis positioning, two straightness,
/// roll, pitch, yaw (18 tables), and the squareness errors A0Z, B0Z, C0Y (constant tables).
/// Axes: X Y Z, all moving the tool.
pub fn three_axis_21() -> Chain {
    let axes = vec![
        lin("X", 0.0, 800.0),
        lin("Y", 0.0, 600.0),
        lin("Z", 0.0, 500.0),
    ];
    let travel = [800.0, 600.0, 500.0];
    let mut tables = Vec::new();
    let mut rows = vec![tool(-100.0)];
    // Z errors, then Z; squareness; Y errors, then Y; squareness; X errors, then X.
    let dofs = [Dof::X, Dof::Y, Dof::Z, Dof::A, Dof::B, Dof::C];
    let names = ["X", "Y", "Z"];
    for (step, &ax) in [2usize, 1, 0].iter().enumerate() {
        let l = travel[ax];
        for (e, &dof) in dofs.iter().enumerate() {
            let unit = if dof.is_rotation() {
                ErrorUnit::Microradian
            } else {
                ErrorUnit::Micrometre
            };
            let amp = if dof.is_rotation() { 15.0 } else { 6.0 };
            let phase = 37.0 * (e + 6 * ax) as f64;
            tables.push(table(
                &format!("E{}{}", dof.name(), names[ax]),
                ax,
                unit,
                false,
                0.0,
                l,
                11,
                move |p| amp * s(360.0 * p / l + phase) + amp * 0.3 * p / l,
            ));
            rows.push(err(dof, tables.len() - 1));
        }
        rows.push(axis(Dof::Z.with_coordinate(ax), ax, 1.0));
        let squareness: &[(Dof, &str, f64)] = match step {
            0 => &[(Dof::A, "EA0Z", 12.0), (Dof::B, "EB0Z", -8.0)],
            1 => &[(Dof::C, "EC0Y", 20.0)],
            _ => &[],
        };
        for &(dof, name, v) in squareness {
            tables.push(table(
                name,
                ax,
                ErrorUnit::Microradian,
                false,
                0.0,
                l,
                2,
                move |_| v,
            ));
            rows.push(err(dof, tables.len() - 1));
        }
    }
    Chain::new(axes, tables, rows).unwrap()
}

trait WithCoordinate {
    fn with_coordinate(self, k: usize) -> Dof;
}
impl WithCoordinate for Dof {
    fn with_coordinate(self, k: usize) -> Dof {
        [Dof::X, Dof::Y, Dof::Z][k]
    }
}

/// All example chains with the index of the rotary axis whose zero is the pole (if any).
pub fn all() -> Vec<(&'static str, Chain, Option<usize>)> {
    vec![
        ("head-ac", head_ac(), Some(3)),
        ("table-ac", table_ac(), Some(3)),
        ("head-bc", head_bc(), Some(3)),
        ("3-axis-21", three_axis_21(), None),
    ]
}
