//! The machine description file (`machine.toml`), written by hand by a machine builder.
//!
//! The format is documented in `docs/formats.md`. Loading checks every rule of
//! [`truepos_model::Machine::check`] and reports each broken one at the line, column and key
//! where it is written. The result is the core's [`MachineConfig`]: the machine with each
//! axis' envelope and path slot and each sensor's checks.

use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::Spanned;
use truepos_model::config::{
    AxisConfig, MachineConfig, SensorChecks, DEFAULT_MAX_AGE_S, DEFAULT_MAX_OFFSET_UM,
    DEFAULT_MAX_RATE_K_PER_MIN, DEFAULT_MAX_RATE_UM_PER_S, DEFAULT_NOISE_K,
    DEFAULT_RECOVER_AFTER_S, DEFAULT_STUCK_AFTER_S,
};
use truepos_model::{
    Axis, AxisKind, Carriage, Machine, OperatingChannel, OperatingKind, Reference,
    TemperatureChannel, TemperatureDifference, MAX_AXES,
};

use crate::error::{parse_toml, read_text};
use truepos_files::InputError;

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
    /// Safety envelope: largest offset magnitude in µm.
    max_offset_um: Option<Spanned<f64>>,
    /// Safety envelope: largest rate of change of the offset in µm/s.
    max_rate_um_per_s: Option<Spanned<f64>>,
    /// For model selection by axis combination: the control path (channel) the axis belongs to at
    /// power-on, 1-based.
    path: Option<Spanned<u32>>,
    /// For model selection by axis combination: the axis number within that path, 1-based.
    number: Option<Spanned<u32>>,
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
    /// Fastest plausible change in K/min; faster is a fault (a spike, a loose contact).
    max_rate_k_per_min: Option<Spanned<f64>>,
    /// Longest time without an update in s before the reading is stale.
    max_age_s: Option<Spanned<f64>>,
    /// A reading that does not change at all for this long (s) is stuck; 0 switches it off.
    stuck_after_s: Option<Spanned<f64>>,
    /// Changes up to this size (K) between readings are never a rate fault (resolution, noise).
    noise_k: Option<Spanned<f64>>,
    /// A faulted reading is used again after this long (s) of sound readings.
    recover_after_s: Option<Spanned<f64>>,
    /// A lagged channel: the control computes it as the first-order lag of this sensor.
    lag_of: Option<Spanned<String>>,
    /// Time constant of the lag in s.
    lag_s: Option<Spanned<f64>>,
    /// For a lag of an operating channel: K per unit of u^power.
    gain_k_per_unit: Option<Spanned<f64>>,
    /// For a lag of an operating channel: 1 (default) or 2.
    power: Option<Spanned<i64>>,
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

/// Reads and checks a machine description file.
pub fn load(path: &Path) -> Result<MachineConfig, InputError> {
    let text = read_text(path, truepos_files::MACHINE)?;
    parse(path, &text)
}

/// Checks a machine description given as text; `path` only names it in errors.
pub fn parse(path: &Path, text: &str) -> Result<MachineConfig, InputError> {
    let raw: RawFile = parse_toml(path, text)?;
    let src = Source { path, text };

    check_header(src, &raw)?;
    check_names(src, &raw)?;
    let axes = axes(src, &raw)?;
    let axis_configs = axis_configs(src, &raw)?;
    check_axis_codes(src, &raw, &axis_configs)?;
    let sensor_checks = sensor_checks(src, &raw)?;
    let temperatures = temperatures(src, &raw)?;
    let differences = differences(src, &raw)?;
    let (operating, operating_units) = operating(src, &raw)?;

    let machine = Machine {
        name: raw.machine.name.get_ref().clone(),
        axes,
        temperatures,
        differences,
        operating,
    };
    check_machine(src, &raw, &machine)?;
    Ok(MachineConfig {
        machine,
        description: raw.machine.description,
        operating_units,
        axes: axis_configs,
        sensor_checks,
    })
}

/// The file being checked: its path names it in errors, its text turns a byte span into a line
/// and column.
#[derive(Clone, Copy)]
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Source<'_> {
    fn err(&self, span: std::ops::Range<usize>, key: String, message: String) -> InputError {
        InputError::at_span(self.path, self.text, span, key, message)
    }
}

/// The machine has a name and between one and [`MAX_AXES`] axes.
fn check_header(src: Source, raw: &RawFile) -> Result<(), InputError> {
    if raw.machine.name.get_ref().trim().is_empty() {
        return Err(src.err(
            raw.machine.name.span(),
            "machine.name".into(),
            "expected a non-empty machine name".into(),
        ));
    }
    if raw.axis.is_empty() {
        return Err(InputError::at(
            src.path,
            1,
            1,
            "axis",
            "expected at least one [[axis]] table",
        ));
    }
    if raw.axis.len() > MAX_AXES {
        return Err(src.err(
            raw.axis[MAX_AXES].name.span(),
            format!("axis[{MAX_AXES}]"),
            format!("at most {MAX_AXES} axes are supported"),
        ));
    }
    Ok(())
}

/// Names must be unique within each list, so that references by name are unambiguous; the
/// second occurrence is reported.
fn check_names(src: Source, raw: &RawFile) -> Result<(), InputError> {
    check_unique(
        raw.axis.iter().map(|a| &a.name),
        "axis",
        "name",
        "axis",
        src,
    )?;
    check_unique(
        raw.temperature.iter().map(|t| &t.id),
        "temperature",
        "id",
        "temperature channel",
        src,
    )?;
    check_unique(
        raw.difference.iter().map(|d| &d.name),
        "difference",
        "name",
        "difference",
        src,
    )?;
    check_unique(
        raw.operating.iter().map(|o| &o.id),
        "operating",
        "id",
        "operating channel",
        src,
    )
}

/// The index of the axis a reference names; an unknown name lists the axes there are.
fn find_axis(
    src: Source,
    raw: &RawFile,
    name: &Spanned<String>,
    key: String,
) -> Result<usize, InputError> {
    let axis_names: Vec<&str> = raw.axis.iter().map(|a| a.name.get_ref().as_str()).collect();
    axis_names
        .iter()
        .position(|a| *a == name.get_ref())
        .ok_or_else(|| {
            src.err(
                name.span(),
                key,
                format!(
                    "unknown axis `{}`; expected one of: {}",
                    name.get_ref(),
                    axis_names.join(", ")
                ),
            )
        })
}

/// The axes: each travel is a non-empty interval and each axis rests on another known axis.
fn axes(src: Source, raw: &RawFile) -> Result<Vec<Axis>, InputError> {
    let mut axes = Vec::new();
    for (i, a) in raw.axis.iter().enumerate() {
        let [lo, hi] = *a.travel.get_ref();
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(src.err(
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
                    return Err(src.err(
                        c.span(),
                        key,
                        format!("axis `{}` cannot rest on itself", a.name.get_ref()),
                    ));
                }
                Some(find_axis(src, raw, c, key)?)
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
    Ok(axes)
}

/// An optional limit that must be a finite number > 0 (or ≥ 0 with `allow_zero`); absent, the
/// default.
fn positive(
    src: Source,
    v: &Option<Spanned<f64>>,
    key: String,
    default: f64,
    allow_zero: bool,
) -> Result<f64, InputError> {
    match v {
        None => Ok(default),
        Some(x) => {
            let ok = x.get_ref().is_finite()
                && (*x.get_ref() > 0.0 || (allow_zero && *x.get_ref() == 0.0));
            if ok {
                Ok(*x.get_ref())
            } else {
                let what = if allow_zero { "≥ 0" } else { "> 0" };
                Err(src.err(
                    x.span(),
                    key,
                    format!("expected a finite number {what}, got {}", x.get_ref()),
                ))
            }
        }
    }
}

/// An optional path or axis number (of the axis-combination index), 1 to 99; absent, the default.
fn path_or_number(
    src: Source,
    v: &Option<Spanned<u32>>,
    key: String,
    default: u32,
) -> Result<u32, InputError> {
    match v {
        None => Ok(default),
        Some(x) if (1..=99).contains(x.get_ref()) => Ok(*x.get_ref()),
        Some(x) => Err(src.err(
            x.span(),
            key,
            format!("expected a whole number from 1 to 99, got {}", x.get_ref()),
        )),
    }
}

/// The runtime settings of each axis: its safety envelope and its path and number.
fn axis_configs(src: Source, raw: &RawFile) -> Result<Vec<AxisConfig>, InputError> {
    let mut configs = Vec::new();
    for (i, a) in raw.axis.iter().enumerate() {
        configs.push(AxisConfig {
            max_offset_um: positive(
                src,
                &a.max_offset_um,
                format!("axis[{i}].max_offset_um"),
                DEFAULT_MAX_OFFSET_UM,
                false,
            )?,
            max_rate_um_per_s: positive(
                src,
                &a.max_rate_um_per_s,
                format!("axis[{i}].max_rate_um_per_s"),
                DEFAULT_MAX_RATE_UM_PER_S,
                false,
            )?,
            path: path_or_number(src, &a.path, format!("axis[{i}].path"), 1)?,
            number: path_or_number(src, &a.number, format!("axis[{i}].number"), i as u32 + 1)?,
        });
    }
    Ok(configs)
}

/// The axis-combination index identifies an axis by its code (path and number), so no two axes may
/// share one.
fn check_axis_codes(
    src: Source,
    raw: &RawFile,
    axis_configs: &[AxisConfig],
) -> Result<(), InputError> {
    for (i, a) in axis_configs.iter().enumerate() {
        if let Some(first) = axis_configs[..i].iter().position(|b| b.code() == a.code()) {
            let span = raw.axis[i]
                .number
                .as_ref()
                .or(raw.axis[i].path.as_ref())
                .map_or(raw.axis[i].name.span(), |s| s.span());
            return Err(src.err(
                span,
                format!("axis[{i}].number"),
                format!(
                    "axis `{}` has path {} number {}, like axis `{}`; each axis needs its own",
                    raw.axis[i].name.get_ref(),
                    a.path,
                    a.number,
                    raw.axis[first].name.get_ref()
                ),
            ));
        }
    }
    Ok(())
}

/// The validation limits of each temperature channel, defaults where the file is silent.
fn sensor_checks(src: Source, raw: &RawFile) -> Result<Vec<SensorChecks>, InputError> {
    let mut sensor_checks = Vec::new();
    for (i, t) in raw.temperature.iter().enumerate() {
        sensor_checks.push(SensorChecks {
            max_rate_k_per_s: positive(
                src,
                &t.max_rate_k_per_min,
                format!("temperature[{i}].max_rate_k_per_min"),
                DEFAULT_MAX_RATE_K_PER_MIN,
                false,
            )? / 60.0,
            max_age_s: positive(
                src,
                &t.max_age_s,
                format!("temperature[{i}].max_age_s"),
                DEFAULT_MAX_AGE_S,
                false,
            )?,
            stuck_after_s: positive(
                src,
                &t.stuck_after_s,
                format!("temperature[{i}].stuck_after_s"),
                DEFAULT_STUCK_AFTER_S,
                true,
            )?,
            noise_k: positive(
                src,
                &t.noise_k,
                format!("temperature[{i}].noise_k"),
                DEFAULT_NOISE_K,
                true,
            )?,
            recover_after_s: positive(
                src,
                &t.recover_after_s,
                format!("temperature[{i}].recover_after_s"),
                DEFAULT_RECOVER_AFTER_S,
                true,
            )?,
        });
    }
    Ok(sensor_checks)
}

/// The temperature channels: each valid range is a non-empty interval, and a lagged channel
/// names what it lags and its time constant.
fn temperatures(src: Source, raw: &RawFile) -> Result<Vec<TemperatureChannel>, InputError> {
    let mut temperatures = Vec::new();
    for (i, t) in raw.temperature.iter().enumerate() {
        let lag = lag(src, raw, i, t)?;
        let [lo, hi] = *t.valid_range.get_ref();
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(src.err(
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
            lag,
        });
    }
    Ok(temperatures)
}

/// The lag of temperature channel `i`, if any: `lag_of` and `lag_s` come together, and the time
/// constant is positive.
fn lag(
    src: Source,
    raw: &RawFile,
    i: usize,
    t: &RawTemperature,
) -> Result<Option<truepos_model::Lag>, InputError> {
    match (&t.lag_of, &t.lag_s) {
        (None, None) => Ok(None),
        (Some(of), Some(tau)) => {
            let source = lag_source(src, raw, i, t, of)?;
            let tau_s = *tau.get_ref();
            if !(tau_s.is_finite() && tau_s > 0.0) {
                return Err(src.err(
                    tau.span(),
                    format!("temperature[{i}].lag_s"),
                    format!("expected a positive time constant in s, got {tau_s}"),
                ));
            }
            Ok(Some(truepos_model::Lag { source, tau_s }))
        }
        (Some(of), None) => Err(src.err(
            of.span(),
            format!("temperature[{i}].lag_s"),
            "`lag_of` needs `lag_s`, the time constant of the lag in s".to_string(),
        )),
        (None, Some(tau)) => Err(src.err(
            tau.span(),
            format!("temperature[{i}].lag_of"),
            "`lag_s` needs `lag_of`, the measured sensor it lags".to_string(),
        )),
    }
}

/// What temperature channel `i` lags: a measured sensor (a lag of a lag cannot be computed in
/// one cycle), or an operating channel with its gain and power. Gain and power mean nothing for
/// the lag of a sensor, so they are refused there.
fn lag_source(
    src: Source,
    raw: &RawFile,
    i: usize,
    t: &RawTemperature,
    of: &Spanned<String>,
) -> Result<truepos_model::LagSource, InputError> {
    let temperature = raw
        .temperature
        .iter()
        .position(|s| s.id.get_ref() == of.get_ref() && s.lag_of.is_none());
    let operating = raw
        .operating
        .iter()
        .position(|o| o.id.get_ref() == of.get_ref());
    match (temperature, operating) {
        (Some(s), _) => {
            let extra = t
                .gain_k_per_unit
                .as_ref()
                .map(|g| (g.span(), "gain_k_per_unit"))
                .or(t.power.as_ref().map(|p| (p.span(), "power")));
            if let Some((span, key)) = extra {
                return Err(src.err(
                    span,
                    format!("temperature[{i}].{key}"),
                    format!(
                        "`{key}` applies to the lag of an operating channel; `{}` is a temperature sensor",
                        of.get_ref()
                    ),
                ));
            }
            Ok(truepos_model::LagSource::Temperature(s))
        }
        (None, Some(channel)) => operating_lag_source(src, i, t, of, channel),
        (None, None) => {
            let measured_ids: Vec<&str> = raw
                .temperature
                .iter()
                .filter(|t| t.lag_of.is_none())
                .map(|t| t.id.get_ref().as_str())
                .collect();
            let operating_ids: Vec<&str> = raw
                .operating
                .iter()
                .map(|o| o.id.get_ref().as_str())
                .collect();
            Err(src.err(
                of.span(),
                format!("temperature[{i}].lag_of"),
                format!(
                    "`{}` is neither a measured temperature sensor nor an operating channel; expected one of: {}",
                    of.get_ref(),
                    measured_ids.iter().chain(&operating_ids).copied().collect::<Vec<_>>().join(", ")
                ),
            ))
        }
    }
}

/// The lag of operating channel `channel`: a finite, non-zero gain in K per unit is required,
/// the power is 1 (default) or 2.
fn operating_lag_source(
    src: Source,
    i: usize,
    t: &RawTemperature,
    of: &Spanned<String>,
    channel: usize,
) -> Result<truepos_model::LagSource, InputError> {
    let gain = t.gain_k_per_unit.as_ref().ok_or_else(|| {
        src.err(
            of.span(),
            format!("temperature[{i}].gain_k_per_unit"),
            format!(
                "the lag of operating channel `{}` needs `gain_k_per_unit`, the temperature rise in K per unit",
                of.get_ref()
            ),
        )
    })?;
    let g = *gain.get_ref();
    if !(g.is_finite() && g != 0.0) {
        return Err(src.err(
            gain.span(),
            format!("temperature[{i}].gain_k_per_unit"),
            format!("expected a finite, non-zero number, got {g}"),
        ));
    }
    let power = match &t.power {
        None => 1,
        Some(p) if matches!(*p.get_ref(), 1 | 2) => *p.get_ref() as u8,
        Some(p) => {
            return Err(src.err(
                p.span(),
                format!("temperature[{i}].power"),
                format!("expected 1 or 2, got {}", p.get_ref()),
            ))
        }
    };
    Ok(truepos_model::LagSource::Operating {
        channel,
        gain_k_per_unit: g,
        power,
    })
}

/// The index of the temperature sensor a difference names; an unknown id lists the sensors
/// there are.
fn find_sensor(
    src: Source,
    raw: &RawFile,
    id: &Spanned<String>,
    key: String,
) -> Result<usize, InputError> {
    let sensor_ids: Vec<&str> = raw
        .temperature
        .iter()
        .map(|t| t.id.get_ref().as_str())
        .collect();
    sensor_ids
        .iter()
        .position(|s| *s == id.get_ref())
        .ok_or_else(|| {
            let known = if sensor_ids.is_empty() {
                "no [[temperature]] is defined".to_string()
            } else {
                format!("expected one of: {}", sensor_ids.join(", "))
            };
            src.err(
                id.span(),
                key,
                format!("unknown temperature sensor `{}`; {known}", id.get_ref()),
            )
        })
}

/// The temperature differences: a known sensor minus either another sensor or a fixed
/// temperature.
fn differences(src: Source, raw: &RawFile) -> Result<Vec<TemperatureDifference>, InputError> {
    let mut differences = Vec::new();
    for (i, d) in raw.difference.iter().enumerate() {
        let plus = find_sensor(src, raw, &d.plus, format!("difference[{i}].plus"))?;
        let minus = difference_reference(src, raw, i, d)?;
        differences.push(TemperatureDifference {
            name: d.name.get_ref().clone(),
            plus,
            minus,
        });
    }
    Ok(differences)
}

/// What difference `i` subtracts: exactly one of `minus` (a sensor other than `plus`) and
/// `minus_fixed` (a finite temperature).
fn difference_reference(
    src: Source,
    raw: &RawFile,
    i: usize,
    d: &RawDifference,
) -> Result<Reference, InputError> {
    match (&d.minus, &d.minus_fixed) {
        (Some(m), None) => {
            let key = format!("difference[{i}].minus");
            if m.get_ref() == d.plus.get_ref() {
                return Err(src.err(
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
            Ok(Reference::Sensor(find_sensor(src, raw, m, key)?))
        }
        (None, Some(t)) => {
            if !t.get_ref().is_finite() {
                return Err(src.err(
                    t.span(),
                    format!("difference[{i}].minus_fixed"),
                    "expected a finite temperature in °C".into(),
                ));
            }
            Ok(Reference::Fixed(*t.get_ref()))
        }
        (Some(_), Some(t)) => Err(src.err(
            t.span(),
            format!("difference[{i}].minus_fixed"),
            "expected either `minus` (a sensor) or `minus_fixed` (°C), not both".into(),
        )),
        (None, None) => Err(src.err(
            d.name.span(),
            format!("difference[{i}]"),
            "expected `minus` (a sensor) or `minus_fixed` (°C)".into(),
        )),
    }
}

/// The operating channels with their units; a channel tied to an axis names a known one.
fn operating(
    src: Source,
    raw: &RawFile,
) -> Result<(Vec<OperatingChannel>, Vec<String>), InputError> {
    let mut operating = Vec::new();
    let mut operating_units = Vec::new();
    for (i, o) in raw.operating.iter().enumerate() {
        let axis = match &o.axis {
            Some(a) => Some(find_axis(src, raw, a, format!("operating[{i}].axis"))?),
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
    Ok((operating, operating_units))
}

/// The whole-machine rules of [`Machine::check`]: anything the per-item checks let through (a
/// carried_by loop) is caught here, at the `carried_by` that closes the loop where possible.
fn check_machine(src: Source, raw: &RawFile, machine: &Machine) -> Result<(), InputError> {
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
            Some(span) => src.err(span, "carried_by".into(), e.to_string()),
            None => InputError::file(src.path, e.to_string()),
        }
    })
}

/// Each name in a list is non-empty and not seen before in that list.
fn check_unique<'a>(
    names: impl Iterator<Item = &'a Spanned<String>>,
    list: &str,
    field: &str,
    what: &str,
    src: Source,
) -> Result<(), InputError> {
    let names: Vec<&Spanned<String>> = names.collect();
    for (i, n) in names.iter().enumerate() {
        if n.get_ref().trim().is_empty() {
            return Err(src.err(
                n.span(),
                format!("{list}[{i}].{field}"),
                format!("expected a non-empty {what} {field}"),
            ));
        }
        if let Some(first) = names[..i].iter().position(|m| m.get_ref() == n.get_ref()) {
            return Err(src.err(
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
