//! What re-identification may take and write, judged against the machine's envelope (each
//! axis' `max_offset_um`, the largest offset the service ever applies): a probe deviation
//! beyond [`ENVELOPE_FACTOR`] times it is no thermal error this compensation could correct (a
//! missed touch, a wrong stylus, a probe that measured the part) and is left out; a
//! re-identified model that predicts beyond that bound where the probes were taken is not
//! written. The factor leaves room for an envelope set tighter than the machine drifts (the
//! service then clamps, and the model is still right inside the envelope): the twin's spindle
//! reaches 1.5 times its 100 µm default.

use truepos_fit::reidentify::ProbeEvent;
use truepos_model::{CycleInput, Machine, Model};
use truepos_runtime::config::AxisConfig;

use crate::error::CliError;

/// How far beyond an axis' envelope a probe deviation or a prediction is still plausible.
pub const ENVELOPE_FACTOR: f64 = 2.0;

/// The plausibility bound of axis `a`, µm.
fn bound(axes: &[AxisConfig], a: usize) -> f64 {
    axes.get(a)
        .map_or(f64::INFINITY, |c| ENVELOPE_FACTOR * c.max_offset_um)
}

/// The events with every measured deviation within its axis' bound, and one line per
/// measurement left out (naming where it came from, the value and the limit).
pub fn within_envelope(
    events: Vec<ProbeEvent>,
    machine: &Machine,
    axes: &[AxisConfig],
) -> (Vec<ProbeEvent>, Vec<String>) {
    let mut left_out = Vec::new();
    let kept = events
        .into_iter()
        .filter_map(|mut ev| {
            for (a, m) in ev.measured_um.iter_mut().enumerate() {
                let limit = bound(axes, a);
                if let Some(v) = *m {
                    if v.is_nan() || v.abs() > limit {
                        left_out.push(format!(
                            "{}: {} deviation {v} µm is beyond ±{limit} µm, {ENVELOPE_FACTOR} \
                             times the axis' envelope (max_offset_um in the machine file)",
                            ev.place, machine.axes[a].name
                        ));
                        *m = None;
                    }
                }
            }
            ev.measured_um.iter().any(Option::is_some).then_some(ev)
        })
        .collect();
    (kept, left_out)
}

/// Refuses a re-identified model whose prediction at any probe event's inputs is not finite or
/// beyond the plausibility bound.
pub fn check_model(
    model: &Model,
    events: &[ProbeEvent],
    machine: &Machine,
    axes: &[AxisConfig],
) -> Result<(), CliError> {
    for ev in events {
        let input = CycleInput {
            temperatures_c: &ev.temperatures_c,
            positions: &ev.position_mm,
            operating: &ev.operating,
        };
        let Ok(c) = model.evaluate(&input) else {
            continue;
        };
        for (a, e) in c.error_um().iter().enumerate() {
            let limit = bound(axes, a);
            if e.is_nan() || e.abs() > limit {
                return Err(CliError::refused(format!(
                    "the re-identified model predicts {e:.1} µm on {} at {} (time {} s), beyond \
                     ±{limit} µm, {ENVELOPE_FACTOR} times the axis' envelope (max_offset_um in \
                     the machine file); nothing written",
                    machine.axes[a].name, ev.place, ev.time_s
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event(dz: f64) -> ProbeEvent {
        ProbeEvent {
            time_s: 0.0,
            place: "run.csv:2".into(),
            temperatures_c: vec![],
            operating: vec![],
            position_mm: vec![0.0],
            measured_um: vec![Some(dz)],
        }
    }

    fn axes(limit: f64) -> Vec<AxisConfig> {
        vec![AxisConfig {
            max_offset_um: limit,
            max_rate_um_per_s: 10.0,
            path: 1,
            number: 1,
        }]
    }

    fn machine() -> Machine {
        truepos_model::Machine {
            name: "m".into(),
            axes: vec![truepos_model::Axis {
                name: "Z".into(),
                kind: truepos_model::AxisKind::Linear,
                travel_min: 0.0,
                travel_max: 100.0,
                carried_by: None,
                carriage: truepos_model::Carriage::Bed,
            }],
            temperatures: vec![],
            differences: vec![],
            operating: vec![],
        }
    }

    #[test]
    fn a_deviation_beyond_the_envelope_is_left_out_and_named() {
        let (kept, out) = within_envelope(
            vec![event(12.0), event(999.9), event(f64::NAN)],
            &machine(),
            &axes(100.0),
        );
        assert_eq!(kept.len(), 1);
        assert_eq!(out.len(), 2);
        assert!(
            out[0].contains("999.9 µm") && out[0].contains("±200 µm"),
            "{}",
            out[0]
        );
    }

    #[test]
    fn a_model_beyond_the_envelope_where_the_probes_were_is_refused() {
        let machine = machine();
        let part = |k0: f64| truepos_model::Part {
            name: "structure".into(),
            enabled: true,
            form: truepos_model::PartForm::Regression,
            summands: vec![],
            constants_um: vec![(0, k0)],
        };
        let ok = Model::new("ok", &machine, vec![part(40.0)]).unwrap();
        let wild = Model::new("wild", &machine, vec![part(-500.0)]).unwrap();
        assert!(check_model(&ok, &[event(0.0)], &machine, &axes(100.0)).is_ok());
        let err = check_model(&wild, &[event(0.0)], &machine, &axes(100.0))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("-500.0 µm on Z") && err.contains("±200 µm"),
            "{err}"
        );
    }
}
