//! The worked example of docs/how-to-add-a-control.md, kept compiling and passing: a control
//! whose thermal compensation takes, per axis, an offset in whole 0.1 µm and a slope in whole
//! µm/m as `AXIS OFFSET SLOPE` lines (a made-up control, so that nothing here claims a real
//! one's format). The values come from the one projection every control shares; the control's
//! own code is its units, its range and its file — written and read back.

use std::path::Path;
use truepos_controls::projection::{project, AxisProjection, Form};
use truepos_controls::ControlError;
use truepos_files::InputError;
use truepos_model::{Axis, AxisKind, Carriage, Machine};

/// What the made-up control accepts per value: ±99 999 in its unit.
const LIMIT: i64 = 99_999;

/// The control's values of one axis, in its units.
#[derive(Debug, PartialEq)]
struct Line {
    axis: String,
    offset_0_1um: i64,
    slope_um_per_m: i64,
}

/// The projection in the control's units, refused beyond its range (never clipped: a clipped
/// value would compensate something else than the model).
fn line(p: &AxisProjection) -> Result<Line, ControlError> {
    let whole = |v: f64, what: &str| {
        let r = v.round();
        if r.is_finite() && r.abs() <= LIMIT as f64 {
            Ok(r as i64)
        } else {
            Err(ControlError::Range(format!(
                "axis {}: {what} {v} is beyond the control's ±{LIMIT}",
                p.name
            )))
        }
    };
    Ok(Line {
        axis: p.name.clone(),
        // The compensation at P0 = 0 in mm → 0.1 µm; tanβ (mm per mm) → µm/m.
        offset_0_1um: whole(p.form.k0_mm * 1e4, "offset")?,
        slope_um_per_m: whole(p.form.tan_beta * 1e6, "slope")?,
    })
}

fn write(lines: &[Line]) -> String {
    lines
        .iter()
        .map(|l| format!("{} {} {}\n", l.axis, l.offset_0_1um, l.slope_um_per_m))
        .collect()
}

/// The file read back, every mistake named at file:line:column.
fn read(file: &str, text: &str) -> Result<Vec<Line>, ControlError> {
    let syntax = |line: usize, column: usize, message: &str| {
        ControlError::Syntax(InputError::at(Path::new(file), line, column, "", message))
    };
    let mut out = Vec::new();
    for (i, row) in text.lines().enumerate() {
        let words: Vec<&str> = row.split_whitespace().collect();
        let [axis, offset, slope] = words[..] else {
            return Err(syntax(i + 1, 1, "expected `AXIS OFFSET SLOPE`"));
        };
        let number = |w: &str| {
            let column = row.find(w).map_or(1, |c| c + 1);
            w.parse::<i64>()
                .map_err(|_| syntax(i + 1, column, "expected a whole number"))
        };
        out.push(Line {
            axis: axis.into(),
            offset_0_1um: number(offset)?,
            slope_um_per_m: number(slope)?,
        });
    }
    Ok(out)
}

fn machine() -> Machine {
    let axis = |name: &str, max: f64| Axis {
        name: name.into(),
        kind: AxisKind::Linear,
        travel_min: 0.0,
        travel_max: max,
        carried_by: None,
        carriage: Carriage::Cantilever,
    };
    Machine {
        name: "m".into(),
        axes: vec![axis("X", 800.0), axis("Z", 500.0)],
        temperatures: vec![],
        differences: vec![],
        operating: vec![],
    }
}

#[test]
fn a_new_control_takes_the_projection_in_its_units_and_reads_back() {
    // X grows 12 µm plus 15 µm/m along X; Z 30 µm, wherever it is.
    let error = |p: &[f64]| Ok(vec![12.0 + 0.015 * p[0], 30.0]);
    let proj = project(
        &machine(),
        &error,
        &[400.0, 250.0],
        Form::Linear,
        &[0.0, 0.0],
    )
    .unwrap();
    let lines: Vec<Line> = proj.iter().map(line).collect::<Result<_, _>>().unwrap();
    let text = write(&lines);
    assert_eq!(text, "X -120 -15\nZ -300 0\n");
    assert_eq!(read("comp.txt", &text).unwrap(), lines);
    let err = read("comp.txt", "X -120 15x\n").unwrap_err().to_string();
    assert_eq!(err, "comp.txt:1:8: expected a whole number");
}

#[test]
fn a_value_beyond_the_controls_range_is_refused_naming_the_axis() {
    let error = |_: &[f64]| Ok(vec![1e4, 0.0]); // 10 mm: 100 000 × 0.1 µm
    let proj = project(&machine(), &error, &[0.0, 0.0], Form::Linear, &[0.0, 0.0]).unwrap();
    let err = line(&proj[0]).unwrap_err().to_string();
    assert!(err.starts_with("axis X: offset -100000 is beyond"), "{err}");
}
