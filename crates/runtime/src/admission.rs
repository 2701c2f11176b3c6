//! What a model must pass before it may serve an axis, checked at every load — start and hot
//! reload, in `truepos run` and in the LinuxCNC component: it must be plausible for this
//! machine, and its evaluation must fit the cycle ([`crate::cycle_budget`]).
//!
//! A valid file can still carry coefficients no machine has (k = 10⁶ µm/K, a unit mistaken
//! for mm, 10³⁰⁰): the envelope would then pin the axis at its limit while the state says
//! `active`, and the compensation the user believes in never reaches the machine. Two physical
//! bounds, each against the axis' own safety envelope (`max_offset_um`), catch that without
//! any figure measured on one dataset:
//! - the **cold machine** — every temperature alike, standing, anywhere in the travel — needs no
//!   correction larger than the envelope;
//! - **one kelvin** on one sensor, reached within an hour and then held until every filter of
//!   the model has settled, moves no axis by more than its whole envelope at any time (real
//!   machines drift a few µm per kelvin).
//!
//! The temperatures are one value inside every sensor's valid range (20 °C where it fits); the
//! positions the middle and every corner of the travel (each axis' ends beyond six axes).
//! Operating inputs stand at 0: a machine file states no range for them, so a coefficient on
//! spindle speed is bounded on the machine by the training envelope's cap, not here. The model
//! is judged unguarded — its own coefficients, not what the runtime's envelope guard would let
//! through. A model whose evaluation fails at such a state (a coefficient of 10³⁰⁸ overflows)
//! is refused with the reason.

use std::time::Duration;

use truepos_model::{CompensationModel, CycleInput, MAX_AXES};

use crate::config::MachineConfig;
use crate::cycle_budget;
use crate::model_set::ModelEntry;

/// Time a settled state is held, s: longer than any lag a model carries (hours), so that every
/// filter has reached the held input.
const SETTLE_S: f64 = 1e7;

/// Time within which the one kelvin is reached, s: a sensor warming 1 K in an hour is an
/// ordinary machine, so its rate of change is part of what the bound judges.
const RAMP_S: f64 = 3600.0;

/// The machine's travel is walked through its corners up to this many axes; beyond, each
/// axis' two ends with the others in the middle.
const CORNER_AXES: usize = 6;

/// Checks `entry` for the machine (plausibility, then the cycle budget at `period_s`); returns
/// the evaluation's median time, or what is wrong in words that name the model, the axis, the
/// figure and the limit.
pub fn admit(
    entry: &ModelEntry,
    config: &MachineConfig,
    period_s: f64,
) -> Result<Duration, String> {
    plausible(&entry.model, config)?;
    cycle_budget::check(entry, &config.machine, period_s)
}

/// [`admit`] for every model of a set; the first refusal.
pub fn admit_set(
    entries: &[ModelEntry],
    config: &MachineConfig,
    period_s: f64,
) -> Result<(), String> {
    for entry in entries {
        admit(entry, config, period_s)?;
    }
    Ok(())
}

/// The two bounds of the module's doc, at the middle and the corners of the travel.
pub fn plausible(model: &CompensationModel, config: &MachineConfig) -> Result<(), String> {
    let name = model.name();
    let m = &config.machine;
    let base_t = base_temperatures(config);
    let operating = vec![0.0; m.operating.len()];
    let points = match model {
        CompensationModel::Position(_) => positions(config),
        CompensationModel::Filtered(_) => positions(config).into_iter().take(1).collect(),
    };
    for p in &points {
        let fail = |e: truepos_model::EvalError| {
            format!(
                "model `{name}` cannot be evaluated {}: {e}",
                state(config, p)
            )
        };
        let (cold, _) = largest_move(model, &base_t, &base_t, p, &operating).map_err(fail)?;
        for (axis, (a, c)) in config.axes.iter().zip(cold).enumerate() {
            if c.abs() > a.max_offset_um {
                return Err(format!(
                    "model `{name}` asks a correction of {} µm on axis {} of a cold machine \
                     (every temperature alike, standing, {}), beyond the axis' whole envelope \
                     of {} µm (`max_offset_um`): not a model of this machine's drift",
                    micrometres(c),
                    m.axes[axis].name,
                    state(config, p),
                    a.max_offset_um
                ));
            }
        }
        for (sensor, channel) in m.temperatures.iter().enumerate() {
            let mut warm = base_t.clone();
            warm[sensor] += if base_t[sensor] + 1.0 <= channel.valid_max_c {
                1.0
            } else {
                -1.0
            };
            let (_, moved) = largest_move(model, &base_t, &warm, p, &operating).map_err(fail)?;
            for (axis, a) in config.axes.iter().enumerate() {
                let by = moved[axis];
                if by.abs() > a.max_offset_um {
                    return Err(format!(
                        "model `{name}`: one kelvin on sensor `{}` moves axis {} by {} µm \
                         ({}), more than the axis' whole envelope of {} µm \
                         (`max_offset_um`): no machine drifts so (a unit mistaken, or a model \
                         of another machine)",
                        channel.id,
                        m.axes[axis].name,
                        micrometres(by),
                        state(config, p),
                        a.max_offset_um
                    ));
                }
            }
        }
    }
    Ok(())
}

/// One temperature for every sensor — 20 °C, moved into every sensor's valid range where they
/// share one — so that the model sees a cold machine it can evaluate; a sensor whose range
/// cannot share it is put at the nearest point of its own range.
fn base_temperatures(config: &MachineConfig) -> Vec<f64> {
    let sensors = &config.machine.temperatures;
    let lo = sensors
        .iter()
        .map(|t| t.valid_min_c)
        .fold(f64::MIN, f64::max);
    let hi = sensors
        .iter()
        .map(|t| t.valid_max_c)
        .fold(f64::MAX, f64::min);
    sensors
        .iter()
        .map(|t| {
            if lo <= hi {
                20.0_f64.clamp(lo, hi)
            } else {
                20.0_f64.clamp(t.valid_min_c, t.valid_max_c)
            }
        })
        .collect()
}

/// The model started at `base_c`: its error per axis there, and the largest move from it per
/// axis while the inputs go to `target_c` within an hour (so that a filtered model's rates of
/// change take part) and are then held until every filter has settled. A position model has no
/// filters: its move is the one at the target.
fn largest_move(
    model: &CompensationModel,
    base_c: &[f64],
    target_c: &[f64],
    positions: &[f64],
    operating: &[f64],
) -> Result<([f64; MAX_AXES], [f64; MAX_AXES]), truepos_model::EvalError> {
    const RAMP_STEPS: u32 = 60;
    let mut model = model.clone();
    model.reset();
    let mut now = base_c.to_vec();
    let start = model.step(0.0, &cycle(&now, positions, operating))?;
    let mut largest = [0.0_f64; MAX_AXES];
    let mut keep = |error: [f64; MAX_AXES]| {
        for ((l, e), s) in largest.iter_mut().zip(error).zip(start) {
            if (e - s).abs() > l.abs() {
                *l = e - s;
            }
        }
    };
    for k in 1..=RAMP_STEPS {
        let f = f64::from(k) / f64::from(RAMP_STEPS);
        for ((n, b), t) in now.iter_mut().zip(base_c).zip(target_c) {
            *n = b + f * (t - b);
        }
        keep(model.step(
            RAMP_S / f64::from(RAMP_STEPS),
            &cycle(&now, positions, operating),
        )?);
    }
    let held = cycle(target_c, positions, operating);
    keep(model.step(SETTLE_S, &held)?);
    keep(model.step(SETTLE_S, &held)?);
    Ok((start, largest))
}

fn cycle<'a>(
    temperatures_c: &'a [f64],
    positions: &'a [f64],
    operating: &'a [f64],
) -> CycleInput<'a> {
    CycleInput {
        temperatures_c,
        positions,
        operating,
    }
}

/// The positions a position-dependent model is judged at: every corner of the travel and its
/// middle (the ends of each axis with the others in the middle beyond [`CORNER_AXES`] axes).
fn positions(config: &MachineConfig) -> Vec<Vec<f64>> {
    let axes = &config.machine.axes;
    let middle: Vec<f64> = axes
        .iter()
        .map(|a| 0.5 * (a.travel_min + a.travel_max))
        .collect();
    let mut points = vec![middle.clone()];
    if axes.len() <= CORNER_AXES {
        for corner in 0..1usize << axes.len() {
            let p = axes
                .iter()
                .enumerate()
                .map(|(i, a)| {
                    if corner >> i & 1 == 1 {
                        a.travel_max
                    } else {
                        a.travel_min
                    }
                })
                .collect();
            points.push(p);
        }
    } else {
        for (i, a) in axes.iter().enumerate() {
            for end in [a.travel_min, a.travel_max] {
                let mut p = middle.clone();
                p[i] = end;
                points.push(p);
            }
        }
    }
    points
}

/// A figure a person can read, however absurd: 123.4, or 1.70e308.
fn micrometres(x: f64) -> String {
    if x.abs() < 1e7 {
        format!("{x:.1}")
    } else {
        format!("{x:.2e}")
    }
}

/// "at X 800, Y 0, Z 0" for a message.
fn state(config: &MachineConfig, p: &[f64]) -> String {
    let at: Vec<String> = config
        .machine
        .axes
        .iter()
        .zip(p)
        .map(|(a, v)| format!("{} {v}", a.name))
        .collect();
    format!("at {}", at.join(", "))
}
