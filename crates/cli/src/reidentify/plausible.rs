//! What re-identification may take and write, judged against the machine's envelope (each
//! axis' `max_offset_um`, the largest offset the service ever applies): a probe deviation
//! beyond [`ENVELOPE_FACTOR`] times it is no thermal error this compensation could correct (a
//! missed touch, a wrong stylus, a probe that measured the part) and is left out; a
//! re-identified model that predicts beyond that bound where the probes were taken is not
//! written. The factor leaves room for an envelope set tighter than the machine drifts (the
//! service then clamps, and the model is still right inside the envelope): the twin's spindle
//! reaches 1.5 times its 100 µm default.

use truepos_fit::reidentify::ProbeEvent;
use truepos_model::envelope::TrainingEnvelope;
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

/// How far a re-identified model may move the prediction at its parent's training inputs, as
/// a multiple of the parent's largest |prediction| there: the error may double or vanish, not
/// more — re-identification corrects a drift of the machine, it does not make a new model.
pub const MOVE_FRACTION: f64 = 1.0;

/// The training inputs of a model with an envelope: every channel it knows at the middle of its
/// range, then each in turn at both ends, then all at each end; positions at the middle of the
/// travel. Channels it does not know stay at 20 °C.
fn training_points(env: &TrainingEnvelope, machine: &Machine) -> Vec<Vec<f64>> {
    let mid: Vec<f64> = env
        .temperatures
        .iter()
        .map(|r| r.map_or(20.0, |(lo, hi)| 0.5 * (lo + hi)))
        .collect();
    let known: Vec<usize> = (0..mid.len())
        .filter(|&c| env.temperatures[c].is_some())
        .collect();
    let mut points = vec![mid.clone()];
    let end =
        |c: usize, hi: bool| env.temperatures[c].map_or(20.0, |(l, h)| if hi { h } else { l });
    for &c in &known {
        for hi in [false, true] {
            let mut p = mid.clone();
            p[c] = end(c, hi);
            points.push(p);
        }
    }
    for hi in [false, true] {
        let mut p = mid.clone();
        for &c in &known {
            p[c] = end(c, hi);
        }
        points.push(p);
    }
    points.retain(|p| p.len() == machine.temperatures.len());
    points
}

/// Refuses a re-identified model that moves the prediction at its parent's training inputs by
/// more than [`MOVE_FRACTION`] × the parent's largest |prediction| there (per axis, at least
/// 1 µm), and gives the new model the parent's envelope, each axis' largest |prediction| the
/// larger of the parent's and the new model's at those inputs. A parent without an envelope
/// gives nothing to compare with: the new model has none either.
pub fn check_move(old: &Model, new: &mut Model, machine: &Machine) -> Result<(), CliError> {
    let Some(env) = old.envelope().cloned() else {
        return Ok(());
    };
    let positions: Vec<f64> = machine
        .axes
        .iter()
        .map(|a| 0.5 * (a.travel_min + a.travel_max))
        .collect();
    let operating = vec![0.0; machine.operating.len()];
    let mut moved = vec![0.0f64; machine.axes.len()];
    let mut largest = vec![0.0f64; machine.axes.len()];
    for t in training_points(&env, machine) {
        let input = CycleInput {
            temperatures_c: &t,
            positions: &positions,
            operating: &operating,
        };
        let (Ok(a), Ok(b)) = (old.evaluate(&input), new.evaluate(&input)) else {
            continue;
        };
        for (k, (x, y)) in a.error_um().iter().zip(b.error_um()).enumerate() {
            moved[k] = moved[k].max((y - x).abs());
            largest[k] = largest[k].max(y.abs());
        }
    }
    for (k, m) in moved.iter().enumerate() {
        let parent = env.max_abs_um.get(k).copied().flatten().unwrap_or(0.0);
        let limit = MOVE_FRACTION * parent.max(1.0);
        if m.is_nan() || *m > limit {
            return Err(CliError::refused(format!(
                "the re-identified model moves the prediction on {} by {m:.1} µm at its \
                 parent's training inputs, more than {MOVE_FRACTION} × the parent's largest \
                 prediction there ({parent:.1} µm); nothing written",
                machine.axes[k].name
            )));
        }
    }
    let mut kept = env;
    for (slot, l) in kept.max_abs_um.iter_mut().zip(&largest) {
        *slot = slot.map(|m| m.max(*l));
    }
    new.set_envelope(Some(kept));
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

    /// A model part that is a constant error of `k0` µm on the first axis.
    fn part(k0: f64) -> truepos_model::Part {
        truepos_model::Part {
            name: "structure".into(),
            enabled: true,
            form: truepos_model::PartForm::Regression,
            summands: vec![],
            constants_um: vec![(0, k0)],
        }
    }

    #[test]
    fn a_model_that_moves_the_training_prediction_too_far_is_refused() {
        let machine = machine();
        let mut old = Model::new("old", &machine, vec![part(40.0)]).unwrap();
        old.set_envelope(Some(TrainingEnvelope {
            temperatures: vec![],
            operating: vec![],
            max_abs_um: vec![Some(40.0)],
        }));
        let mut far = Model::new("far", &machine, vec![part(200.0)]).unwrap();
        let err = check_move(&old, &mut far, &machine)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("moves the prediction on Z by 160.0 µm"),
            "{err}"
        );
        let mut near = Model::new("near", &machine, vec![part(60.0)]).unwrap();
        check_move(&old, &mut near, &machine).unwrap();
        assert_eq!(near.envelope().unwrap().max_abs_um, vec![Some(60.0)]);
        // A parent without an envelope: nothing to compare with.
        let bare = Model::new("bare", &machine, vec![part(40.0)]).unwrap();
        check_move(&bare, &mut far, &machine).unwrap();
    }

    #[test]
    fn a_model_beyond_the_envelope_where_the_probes_were_is_refused() {
        let machine = machine();
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
