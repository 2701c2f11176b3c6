//! A model's coefficients for the report, in the words and units of the shop floor: grouped by
//! the input they act on (a temperature difference; a sensor with its rise, lags and rates; the
//! spindle speed), each with the unit the model file keeps it in and, where that unit is one
//! nobody reads (µm per K/s, µm per 1/min), the same value in one they do (µm per K/h, µm per
//! 1000 rpm).

use truepos_model::dynamic::FeatureKind;
use truepos_model::{
    BoundDynamicModel, LagSource, Machine, MachineInput, Model, OperatingKind, PartForm, Reference,
};
use truepos_report::Coefficient;

/// A time constant for a person: `1 h`, `10 min`, `90 s`, `2.5 h`.
fn duration(tau_s: f64) -> String {
    let trim = |v: f64| {
        let s = format!("{v:.2}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    if tau_s >= 3600.0 {
        format!("{} h", trim(tau_s / 3600.0))
    } else if tau_s >= 60.0 {
        format!("{} min", trim(tau_s / 60.0))
    } else {
        format!("{} s", trim(tau_s))
    }
}

/// What an operating input measures, in words, and its unit as the model reads it with the
/// scale and unit a person reads a coefficient of it in (per 1000 rpm rather than per 1/min).
fn operating_words(kind: OperatingKind) -> (&'static str, &'static str, f64, &'static str) {
    match kind {
        OperatingKind::SpindleSpeed => ("spindle speed", "1/min", 1000.0, "1000 rpm"),
        OperatingKind::AxisSpeed => ("axis speed", "mm/min", 1000.0, "m/min"),
        OperatingKind::Torque => ("torque", "N·m", 1.0, "N·m"),
        OperatingKind::Power => ("power", "W", 1000.0, "kW"),
        OperatingKind::Other => ("operating state", "unit", 1.0, "unit"),
    }
}

/// The sensor (or operating input) a temperature channel comes from — a lagged channel is its
/// source's — as the group its coefficients are shown under, and the channel in words
/// (`spindle_front lagged τ = 2 h`).
fn sensor_of(machine: &Machine, channel: usize) -> (String, String) {
    let t = &machine.temperatures[channel];
    match t.lag {
        None => (format!("{} (temperature)", t.id), t.id.clone()),
        Some(lag) => {
            let lagged = format!("lagged τ = {}", duration(lag.tau_s));
            match lag.source {
                LagSource::Temperature(s) => {
                    let (group, source) = sensor_of(machine, s);
                    (group, format!("{source} {lagged}"))
                }
                LagSource::Operating { channel, .. } => {
                    let o = &machine.operating[channel];
                    let (what, ..) = operating_words(o.kind);
                    (
                        format!("{} ({what})", o.id),
                        format!("heat of {} {lagged}", o.id),
                    )
                }
            }
        }
    }
}

/// A static model's coefficients (position-dependent model or reference-sensor regression):
/// each summand's K₀ and position terms under the sensor its temperature difference reads, the
/// difference spelt out; the constants last.
pub fn of_model(model: &Model, machine: &Machine) -> Vec<Coefficient> {
    let mut out = Vec::new();
    let mut constants = Vec::new();
    // A model whose parts are of both forms says which form each term belongs to.
    let mixed = model
        .parts()
        .iter()
        .any(|p| p.form != model.parts()[0].form);
    for p in model.parts() {
        let part = match (mixed, p.form) {
            (false, _) => "",
            (true, PartForm::Regression) => " (reference-sensor regression)",
            (true, PartForm::PositionDependent) => " (position-dependent)",
        };
        for s in &p.summands {
            let channel = machine.axes[s.axis].name.clone();
            let d = &machine.differences[s.difference];
            let (input, plus) = sensor_of(machine, d.plus);
            let minus = match d.minus {
                Reference::Sensor(r) => sensor_of(machine, r).1,
                Reference::Fixed(c) => format!("{c} °C"),
            };
            let mult = s
                .bed_multiplier
                .map(|b| format!(" · KFA({})", machine.axes[b].name))
                .unwrap_or_default();
            let coefficient = |terms: String, value: f64| Coefficient {
                channel: channel.clone(),
                input: input.clone(),
                feature: format!("{}{terms}{mult}{part}", d.name),
                meaning: format!("{} = {plus} − {minus}", d.name),
                value,
                unit: "µm/K".into(),
                readable: None,
            };
            out.push(coefficient(String::new(), s.k0_um_per_k));
            for t in &s.position_terms {
                let g = format!(" · {}({})", t.factor.name(), machine.axes[t.axis].name);
                out.push(coefficient(g, t.k_um_per_k));
            }
        }
        for &(a, v) in &p.constants_um {
            constants.push(Coefficient {
                channel: machine.axes[a].name.clone(),
                input: String::new(),
                feature: format!("constant{part}"),
                meaning: String::new(),
                value: v,
                unit: "µm".into(),
                readable: None,
            });
        }
    }
    out.extend(constants);
    out
}

/// A fitted dynamic model's coefficients: every non-zero feature under the sensor or operating
/// input it reads, the intercepts last.
pub fn of_dynamic(bound: &BoundDynamicModel, machine: &Machine) -> Vec<Coefficient> {
    let features = bound.model().bank().features();
    let n = features.len();
    let input = |k: usize| match bound.inputs()[k] {
        MachineInput::Temperature(c) => (machine.temperatures[c].id.as_str(), None),
        MachineInput::Operating(c) => (
            machine.operating[c].id.as_str(),
            Some(machine.operating[c].kind),
        ),
    };
    let mut out = Vec::new();
    let mut intercepts = Vec::new();
    for (k, axis) in bound.axes().iter().enumerate() {
        let Some(a) = axis else { continue };
        let channel = machine.axes[*a].name.clone();
        intercepts.push(Coefficient {
            channel: channel.clone(),
            input: String::new(),
            feature: "intercept".into(),
            meaning: String::new(),
            value: bound.model().intercepts()[k],
            unit: "µm".into(),
            readable: None,
        });
        for (j, f) in features.iter().enumerate() {
            let value = bound.model().coefficients()[k * n + j];
            if value == 0.0 {
                continue;
            }
            let (id, operating) = input(f.input);
            let (group, feature, unit, readable) = match (f.kind, operating) {
                (FeatureKind::Operating { tau_s }, Some(kind)) => {
                    let (what, unit, scale, shown) = operating_words(kind);
                    (
                        format!("{id} ({what})"),
                        format!("{what}, lagged τ = {}", duration(tau_s)),
                        format!("µm per {unit}"),
                        (scale != 1.0).then(|| (value * scale, format!("µm per {shown}"))),
                    )
                }
                (FeatureKind::OperatingSquared { tau_s }, Some(kind)) => {
                    let (what, unit, scale, shown) = operating_words(kind);
                    (
                        format!("{id} ({what})"),
                        format!("{what} squared, lagged τ = {}", duration(tau_s)),
                        format!("µm per ({unit})²"),
                        (scale != 1.0)
                            .then(|| (value * scale * scale, format!("µm per ({shown})²"))),
                    )
                }
                (kind, _) => {
                    let (feature, unit, readable) = temperature_term(kind, value, &input);
                    (format!("{id} (temperature)"), feature, unit, readable)
                }
            };
            out.push(Coefficient {
                channel: channel.clone(),
                input: group,
                feature,
                meaning: String::new(),
                value,
                unit,
                readable,
            });
        }
    }
    out.extend(intercepts);
    out
}

/// A term of a temperature input: its words, the unit of its coefficient, and a rate's
/// coefficient per K/h (the model keeps rates in K/s; a shop's sensors drift a few K an hour).
fn temperature_term<'a>(
    kind: FeatureKind,
    value: f64,
    input: &impl Fn(usize) -> (&'a str, Option<OperatingKind>),
) -> (String, String, Option<(f64, String)>) {
    match kind {
        FeatureKind::Rise => ("rise since the start".into(), "µm/K".into(), None),
        FeatureKind::LowPass { tau_s } => (
            format!("rise, lagged τ = {}", duration(tau_s)),
            "µm/K".into(),
            None,
        ),
        FeatureKind::Rate { tau_s } => (
            format!("rate of rise, smoothed τ = {}", duration(tau_s)),
            "µm/(K/s)".into(),
            Some((value / 3600.0, "µm/(K/h)".into())),
        ),
        FeatureKind::RiseWhileRunning { running } => (
            format!("rise while {} is not zero", input(running).0),
            "µm/K".into(),
            None,
        ),
        // Operating kinds on an input the machine calls a temperature: named as the model does.
        FeatureKind::Operating { tau_s } | FeatureKind::OperatingSquared { tau_s } => (
            format!("lagged τ = {}", duration(tau_s)),
            "µm per unit".into(),
            None,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_constants_in_words() {
        assert_eq!(duration(3600.0), "1 h");
        assert_eq!(duration(9000.0), "2.5 h");
        assert_eq!(duration(600.0), "10 min");
        assert_eq!(duration(90.0), "1.5 min");
        assert_eq!(duration(30.0), "30 s");
    }
}
