//! The machine description file (`machine.toml`), written by hand by a machine builder.
//!
//! The format is documented in `docs/formats.md`. Loading checks every rule of
//! [`truepos_model::Machine::check`] and reports each broken one at the line, column and key
//! where it is written.

use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::Spanned;
use truepos_model::{
    Axis, AxisKind, Carriage, Machine, OperatingChannel, OperatingKind, Reference,
    TemperatureChannel, TemperatureDifference, MAX_AXES,
};

use crate::error::{parse_toml, read_text, InputError};

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    machine: RawHeader,
    #[serde(default)]
    axis: Vec<RawAxis>,
    #[serde(default)]
    temperature: Vec<RawTemperature>,
    #[serde(default)]
    difference: Vec<RawDifference>,
    #[serde(default)]
    operating: Vec<RawOperating>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawHeader {
    name: Spanned<String>,
    #[serde(default)]
    description: String,
}

#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
enum RawAxisKind {
    Linear,
    Rotary,
}

#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
enum RawCarriage {
    Cantilever,
    Bed,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    name: Spanned<String>,
    kind: RawAxisKind,
    travel: Spanned<[f64; 2]>,
    carried_by: Option<Spanned<String>>,
    #[serde(default = "default_carriage")]
    carriage: RawCarriage,
}

fn default_carriage() -> RawCarriage {
    RawCarriage::Cantilever
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawTemperature {
    id: Spanned<String>,
    #[serde(default)]
    location: String,
    valid_range: Spanned<[f64; 2]>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawDifference {
    name: Spanned<String>,
    plus: Spanned<String>,
    minus: Option<Spanned<String>>,
    minus_fixed: Option<Spanned<f64>>,
}

#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
enum RawOperatingKind {
    SpindleSpeed,
    AxisSpeed,
    Torque,
    Power,
    Other,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawOperating {
    id: Spanned<String>,
    kind: RawOperatingKind,
    #[serde(default)]
    unit: String,
    axis: Option<Spanned<String>>,
}

/// A checked machine description with what the file says beyond the real-time core's needs.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineFile {
    /// The machine, checked.
    pub machine: Machine,
    /// Free text from `[machine] description`.
    pub description: String,
    /// Unit of each operating channel, in machine order.
    pub operating_units: Vec<String>,
}

/// Reads and checks a machine description file.
pub fn load(path: &Path) -> Result<MachineFile, InputError> {
    let text = read_text(path)?;
    parse(path, &text)
}

/// Checks a machine description given as text; `path` only names it in errors.
pub fn parse(path: &Path, text: &str) -> Result<MachineFile, InputError> {
    let raw: RawFile = parse_toml(path, text)?;
    let err = |span: std::ops::Range<usize>, key: String, message: String| {
        InputError::at_span(path, text, span, key, message)
    };

    if raw.machine.name.get_ref().trim().is_empty() {
        return Err(err(
            raw.machine.name.span(),
            "machine.name".into(),
            "expected a non-empty machine name".into(),
        ));
    }
    if raw.axis.is_empty() {
        return Err(InputError::at(
            path,
            1,
            1,
            "axis",
            "expected at least one [[axis]] table",
        ));
    }
    if raw.axis.len() > MAX_AXES {
        return Err(err(
            raw.axis[MAX_AXES].name.span(),
            format!("axis[{MAX_AXES}]"),
            format!("at most {MAX_AXES} axes are supported"),
        ));
    }

    // Names must be unique within each list; report the second occurrence.
    check_unique(
        raw.axis.iter().map(|a| &a.name),
        "axis",
        "name",
        "axis",
        &err,
    )?;
    check_unique(
        raw.temperature.iter().map(|t| &t.id),
        "temperature",
        "id",
        "temperature channel",
        &err,
    )?;
    check_unique(
        raw.difference.iter().map(|d| &d.name),
        "difference",
        "name",
        "difference",
        &err,
    )?;
    check_unique(
        raw.operating.iter().map(|o| &o.id),
        "operating",
        "id",
        "operating channel",
        &err,
    )?;

    let axis_names: Vec<&str> = raw.axis.iter().map(|a| a.name.get_ref().as_str()).collect();
    let find_axis = |name: &Spanned<String>, key: String| -> Result<usize, InputError> {
        axis_names
            .iter()
            .position(|a| *a == name.get_ref())
            .ok_or_else(|| {
                err(
                    name.span(),
                    key,
                    format!(
                        "unknown axis `{}`; expected one of: {}",
                        name.get_ref(),
                        axis_names.join(", ")
                    ),
                )
            })
    };

    let mut axes = Vec::new();
    for (i, a) in raw.axis.iter().enumerate() {
        let [lo, hi] = *a.travel.get_ref();
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(err(
                a.travel.span(),
                format!("axis[{i}].travel"),
                format!("expected [min, max] with max > min (travel > 0), got [{lo}, {hi}]"),
            ));
        }
        let carried_by = match &a.carried_by {
            None => None,
            Some(c) => {
                let key = format!("axis[{i}].carried_by");
                if c.get_ref() == a.name.get_ref() {
                    return Err(err(
                        c.span(),
                        key,
                        format!("axis `{}` cannot rest on itself", a.name.get_ref()),
                    ));
                }
                Some(find_axis(c, key)?)
            }
        };
        axes.push(Axis {
            name: a.name.get_ref().clone(),
            kind: match a.kind {
                RawAxisKind::Linear => AxisKind::Linear,
                RawAxisKind::Rotary => AxisKind::Rotary,
            },
            travel_min: lo,
            travel_max: hi,
            carried_by,
            carriage: match a.carriage {
                RawCarriage::Cantilever => Carriage::Cantilever,
                RawCarriage::Bed => Carriage::Bed,
            },
        });
    }

    let mut temperatures = Vec::new();
    for (i, t) in raw.temperature.iter().enumerate() {
        let [lo, hi] = *t.valid_range.get_ref();
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(err(
                t.valid_range.span(),
                format!("temperature[{i}].valid_range"),
                format!("expected [min, max] in °C with max > min, got [{lo}, {hi}]"),
            ));
        }
        temperatures.push(TemperatureChannel {
            id: t.id.get_ref().clone(),
            location: t.location.clone(),
            valid_min_c: lo,
            valid_max_c: hi,
        });
    }

    let sensor_ids: Vec<&str> = raw
        .temperature
        .iter()
        .map(|t| t.id.get_ref().as_str())
        .collect();
    let find_sensor = |id: &Spanned<String>, key: String| -> Result<usize, InputError> {
        sensor_ids
            .iter()
            .position(|s| *s == id.get_ref())
            .ok_or_else(|| {
                let known = if sensor_ids.is_empty() {
                    "no [[temperature]] is defined".to_string()
                } else {
                    format!("expected one of: {}", sensor_ids.join(", "))
                };
                err(
                    id.span(),
                    key,
                    format!("unknown temperature sensor `{}`; {known}", id.get_ref()),
                )
            })
    };

    let mut differences = Vec::new();
    for (i, d) in raw.difference.iter().enumerate() {
        let plus = find_sensor(&d.plus, format!("difference[{i}].plus"))?;
        let minus = match (&d.minus, &d.minus_fixed) {
            (Some(m), None) => {
                let key = format!("difference[{i}].minus");
                if m.get_ref() == d.plus.get_ref() {
                    return Err(err(
                        m.span(),
                        key,
                        format!(
                            "difference `{}` references itself (`{}` minus `{}`); expected another sensor or minus_fixed",
                            d.name.get_ref(),
                            d.plus.get_ref(),
                            m.get_ref()
                        ),
                    ));
                }
                Reference::Sensor(find_sensor(m, key)?)
            }
            (None, Some(t)) => {
                if !t.get_ref().is_finite() {
                    return Err(err(
                        t.span(),
                        format!("difference[{i}].minus_fixed"),
                        "expected a finite temperature in °C".into(),
                    ));
                }
                Reference::Fixed(*t.get_ref())
            }
            (Some(_), Some(t)) => {
                return Err(err(
                    t.span(),
                    format!("difference[{i}].minus_fixed"),
                    "expected either `minus` (a sensor) or `minus_fixed` (°C), not both".into(),
                ))
            }
            (None, None) => {
                return Err(err(
                    d.name.span(),
                    format!("difference[{i}]"),
                    "expected `minus` (a sensor) or `minus_fixed` (°C)".into(),
                ))
            }
        };
        differences.push(TemperatureDifference {
            name: d.name.get_ref().clone(),
            plus,
            minus,
        });
    }

    let mut operating = Vec::new();
    let mut operating_units = Vec::new();
    for (i, o) in raw.operating.iter().enumerate() {
        let axis = match &o.axis {
            Some(a) => Some(find_axis(a, format!("operating[{i}].axis"))?),
            None => None,
        };
        operating.push(OperatingChannel {
            id: o.id.get_ref().clone(),
            kind: match o.kind {
                RawOperatingKind::SpindleSpeed => OperatingKind::SpindleSpeed,
                RawOperatingKind::AxisSpeed => OperatingKind::AxisSpeed,
                RawOperatingKind::Torque => OperatingKind::Torque,
                RawOperatingKind::Power => OperatingKind::Power,
                RawOperatingKind::Other => OperatingKind::Other,
            },
            axis,
        });
        operating_units.push(o.unit.clone());
    }

    let machine = Machine {
        name: raw.machine.name.get_ref().clone(),
        axes,
        temperatures,
        differences,
        operating,
    };
    // Anything the per-item checks above let through (a carried_by loop) is caught here.
    machine.check().map_err(|e| {
        let span = match &e {
            truepos_model::MachineError::CarriageLoop { axis } => raw
                .axis
                .iter()
                .find(|a| a.name.get_ref() == axis)
                .and_then(|a| a.carried_by.as_ref())
                .map(|c| c.span()),
            _ => None,
        };
        match span {
            Some(span) => err(span, "carried_by".into(), e.to_string()),
            None => InputError::file(path, e.to_string()),
        }
    })?;
    Ok(MachineFile {
        machine,
        description: raw.machine.description,
        operating_units,
    })
}

fn check_unique<'a>(
    names: impl Iterator<Item = &'a Spanned<String>>,
    list: &str,
    field: &str,
    what: &str,
    err: &impl Fn(std::ops::Range<usize>, String, String) -> InputError,
) -> Result<(), InputError> {
    let names: Vec<&Spanned<String>> = names.collect();
    for (i, n) in names.iter().enumerate() {
        if n.get_ref().trim().is_empty() {
            return Err(err(
                n.span(),
                format!("{list}[{i}].{field}"),
                format!("expected a non-empty {what} {field}"),
            ));
        }
        if let Some(first) = names[..i].iter().position(|m| m.get_ref() == n.get_ref()) {
            return Err(err(
                n.span(),
                format!("{list}[{i}].{field}"),
                format!(
                    "duplicate {what} `{}` (first defined as {list}[{first}]); names must be unique",
                    n.get_ref()
                ),
            ));
        }
    }
    Ok(())
}
