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
//! - **one kelvin** on one sensor, held until every filter of the model has settled, moves no
//!   axis by more than its whole envelope (real machines drift a few µm per kelvin).
//!
//! A model whose evaluation fails at such a state (a coefficient of 10³⁰⁸ overflows) is refused
//! with the reason.

use std::time::Duration;

use truepos_model::{CompensationModel, CycleInput, MAX_AXES};

use crate::config::MachineConfig;
use crate::cycle_budget;
use crate::model_set::ModelEntry;

/// Time a settled state is held, s: longer than any lag a model carries (hours), so that every
/// filter has reached the held input.
const SETTLE_S: f64 = 1e7;

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

/// The two bounds of the module's doc, at the middle and every corner of the travel.
pub fn plausible(model: &CompensationModel, config: &MachineConfig) -> Result<(), String> {
    let name = model.name();
    let m = &config.machine;
    let base_t = vec![20.0; m.temperatures.len()];
    let operating = vec![0.0; m.operating.len()];
    let points = match model {
        CompensationModel::Position(_) => positions(config),
        CompensationModel::Filtered(_) => positions(config).into_iter().take(1).collect(),
    };
    for p in &points {
        let at = |t: &[f64]| {
            settled(model, &base_t, t, p, &operating).map_err(|e| {
                format!(
                    "model `{}` cannot be evaluated at {}: {e}",
                    name,
                    state(config, p)
                )
            })
        };
        let cold = at(&base_t)?;
        for (axis, (a, c)) in config.axes.iter().zip(cold).enumerate() {
            if c.abs() > a.max_offset_um {
                return Err(format!(
                    "model `{}` asks a correction of {} µm on axis {} of a cold machine \
                     (every temperature alike, standing, {}), beyond the axis' whole envelope \
                     of {} µm (`max_offset_um`): not a model of this machine's drift",
                    name,
                    micrometres(c),
                    m.axes[axis].name,
                    state(config, p),
                    a.max_offset_um
                ));
            }
        }
        for (sensor, channel) in m.temperatures.iter().enumerate() {
            let mut warm = base_t.clone();
            warm[sensor] += 1.0;
            let moved = at(&warm)?;
            for (axis, a) in config.axes.iter().enumerate() {
                let by = moved[axis] - cold[axis];
                if by.abs() > a.max_offset_um {
                    return Err(format!(
                        "model `{}`: one kelvin on sensor `{}` moves axis {} by {} µm \
                         ({}), more than the axis' whole envelope of {} µm \
                         (`max_offset_um`): no machine drifts so (a unit mistaken, or a model \
                         of another machine)",
                        name,
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

/// The error per axis once the model, started at `base_c`, has held `temperatures_c` long
/// enough for every filter to settle (a position model has none: its first step says it).
fn settled(
    model: &CompensationModel,
    base_c: &[f64],
    temperatures_c: &[f64],
    positions: &[f64],
    operating: &[f64],
) -> Result<[f64; MAX_AXES], truepos_model::EvalError> {
    let mut model = model.clone();
    model.reset();
    let input = |t| CycleInput {
        temperatures_c: t,
        positions,
        operating,
    };
    model.step(0.0, &input(base_c))?;
    model.step(SETTLE_S, &input(temperatures_c))?;
    model.step(SETTLE_S, &input(temperatures_c))
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
