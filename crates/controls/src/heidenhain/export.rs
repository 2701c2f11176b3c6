//! HEIDENHAIN TNC: the thermal offset of PLC module 9231 and the `TEMPCOMP` column of the
//! kinematics description.
//!
//! - Module 9231 takes a thermal offset per axis in 0.1 µm, at most ±30 000 (±3 mm) (TNC PLC
//!   documentation, module 9231 "compensation of thermal expansion"): a constant per axis, the
//!   [`crate::projection::Form::Constant`] projection.
//! - `TEMPCOMP` holds a formula over PLC words that replaces a transformation's length, e.g.
//!   `300 + 3.45e-3 * (W486 - 20)` (TNC machine documentation, kinematics description): it
//!   carries a static model that is linear in the temperatures and independent of position;
//!   [`tempcomp`] derives that formula from the model itself and states what it cannot carry.

use truepos_model::Machine;

use crate::projection::AxisProjection;
use crate::ControlError;

/// Largest magnitude module 9231 accepts, in its unit of 0.1 µm.
pub const MODULE_9231_LIMIT: i64 = 30_000;

/// The 9231 offset of one axis, in 0.1 µm, from a constant projection; refused beyond the
/// module's range.
pub fn offset_9231(p: &AxisProjection) -> Result<i64, ControlError> {
    let v = (p.form.k0_mm * 1e4).round();
    if !v.is_finite() || v.abs() > MODULE_9231_LIMIT as f64 {
        return Err(ControlError::Range(format!(
            "axis {}: offset {:.1} µm is beyond module 9231's ±3 000 µm",
            p.name,
            p.form.k0_mm * 1e3
        )));
    }
    Ok(v as i64)
}

/// Where a temperature sensor is in the PLC: a word (`W486`) and the °C per count (0.1 for a
/// word in tenths of a degree).
#[derive(Debug, Clone, PartialEq)]
pub struct PlcWord {
    /// Index of the sensor among the machine's temperature channels.
    pub sensor: usize,
    /// The operand as the PLC names it.
    pub word: String,
    /// °C per count.
    pub scale: f64,
}

/// A `TEMPCOMP` formula for one axis and what it leaves out.
#[derive(Debug, Clone, PartialEq)]
pub struct Tempcomp {
    /// Axis index.
    pub axis: usize,
    /// The formula, mm: the nominal length plus the compensation.
    pub formula: String,
    /// Compensation per kelvin of each sensor it reads, mm/K (sensor index, coefficient).
    pub per_kelvin_mm: Vec<(usize, f64)>,
    /// The compensation at 20 °C on every sensor it reads, mm.
    pub at_20c_mm: f64,
    /// Largest change of the model's compensation over the travel's corners at the given
    /// temperatures: the position dependence the formula cannot carry, µm.
    pub position_error_um: f64,
}

impl Tempcomp {
    /// The compensation the formula gives for these temperatures (one per machine channel), mm.
    pub fn compensation_mm(&self, temperatures_c: &[f64]) -> f64 {
        self.at_20c_mm
            + self
                .per_kelvin_mm
                .iter()
                .map(|&(s, c)| c * (temperatures_c[s] - 20.0))
                .sum::<f64>()
    }
}

/// The model at any thermal state and position: error per axis, µm.
pub type ModelAt<'a> = dyn Fn(&[f64], &[f64]) -> Result<Vec<f64>, String> + 'a;

/// Derives each axis' `TEMPCOMP` formula from the model: the model is linear in the temperatures
/// (position-dependent or regression), so one evaluation per sensor, each 1 K warmer, gives its
/// coefficients exactly; `corners` are positions where the position dependence is measured. A
/// sensor the formula needs without a PLC word, or a lagged channel (a PLC word holds a sensor, not
/// truepos's lag), is refused by name.
pub fn tempcomp(
    machine: &Machine,
    f: &ModelAt<'_>,
    temperatures_c: &[f64],
    now: &[f64],
    corners: &[Vec<f64>],
    words: &[PlcWord],
    nominal_mm: &[f64],
) -> Result<Vec<Tempcomp>, ControlError> {
    let eval = |t: &[f64], p: &[f64]| {
        f(t, p).map_err(|why| ControlError::Model(format!("at positions {p:?}: {why}")))
    };
    let base = eval(temperatures_c, now)?;
    let mut gains = vec![vec![0.0; machine.temperatures.len()]; base.len()];
    for s in 0..machine.temperatures.len() {
        let mut t = temperatures_c.to_vec();
        t[s] += 1.0;
        let e = eval(&t, now)?;
        for (a, g) in gains.iter_mut().enumerate() {
            g[s] = e[a] - base[a];
        }
    }
    check_words(machine, &gains, words)?;
    let mut out = Vec::new();
    for (a, g) in gains.iter().enumerate() {
        let used: Vec<usize> = (0..g.len()).filter(|&s| g[s].abs() > 1e-12).collect();
        if used.is_empty() && base[a].abs() < 1e-12 {
            continue;
        }
        let mut per_kelvin_mm = Vec::new();
        for &s in &used {
            per_kelvin_mm.push((s, -g[s] / 1000.0));
        }
        let e20 = base[a]
            + used
                .iter()
                .map(|&s| g[s] * (20.0 - temperatures_c[s]))
                .sum::<f64>();
        let mut position_error_um = 0.0_f64;
        for c in corners {
            let e = eval(temperatures_c, c)?;
            position_error_um = position_error_um.max((e[a] - base[a]).abs());
        }
        let nominal = nominal_mm.get(a).copied().unwrap_or(0.0);
        let at_20c_mm = -e20 / 1000.0;
        let mut formula = format!("{nominal} + {at_20c_mm:.7}");
        for &(s, c) in &per_kelvin_mm {
            let w = words.iter().find(|w| w.sensor == s).expect("checked above");
            formula += &format!(" + {c:.6e} * ({} * {} - 20)", w.word, w.scale);
        }
        out.push(Tempcomp {
            axis: a,
            formula,
            per_kelvin_mm,
            at_20c_mm,
            position_error_um,
        });
    }
    Ok(out)
}

/// Every sensor the formulas need has a PLC word and none is a lagged channel — all of them
/// named in one message, so that one run finds every missing word.
fn check_words(
    machine: &Machine,
    gains: &[Vec<f64>],
    words: &[PlcWord],
) -> Result<(), ControlError> {
    let read: Vec<usize> = (0..machine.temperatures.len())
        .filter(|&s| gains.iter().any(|g| g[s].abs() > 1e-12))
        .collect();
    let lagged: Vec<&str> = read
        .iter()
        .map(|&s| &machine.temperatures[s])
        .filter(|ch| ch.lag.is_some())
        .map(|ch| ch.id.as_str())
        .collect();
    let missing: Vec<&str> = read
        .iter()
        .filter(|&&s| machine.temperatures[s].lag.is_none() && !words.iter().any(|w| w.sensor == s))
        .map(|&s| machine.temperatures[s].id.as_str())
        .collect();
    let mut problems = Vec::new();
    if !lagged.is_empty() {
        problems.push(format!(
            "the model reads {}, lags of other channels: a TEMPCOMP formula reads PLC words, not truepos's lags",
            lagged.iter().map(|id| format!("`{id}`")).collect::<Vec<_>>().join(", ")
        ));
    }
    if !missing.is_empty() {
        problems.push(format!(
            "the model reads {} sensor(s) without a PLC word: {} (give --plc-word {})",
            missing.len(),
            missing.join(", "),
            missing
                .iter()
                .map(|id| format!("{id}=W…"))
                .collect::<Vec<_>>()
                .join(",")
        ));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(ControlError::Form(problems.join("; ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_model::{Axis, AxisKind, Carriage, TemperatureChannel};

    fn machine(lagged: bool) -> Machine {
        let sensor = |id: &str| TemperatureChannel {
            id: id.into(),
            location: String::new(),
            valid_min_c: -20.0,
            valid_max_c: 120.0,
            lag: None,
        };
        let mut m = Machine {
            name: "m".into(),
            axes: vec![Axis {
                name: "X".into(),
                kind: AxisKind::Linear,
                travel_min: 0.0,
                travel_max: 800.0,
                carried_by: None,
                carriage: Carriage::Cantilever,
            }],
            temperatures: vec![sensor("spindle"), sensor("bed")],
            differences: vec![],
            operating: vec![],
        };
        if lagged {
            m.temperatures[1].lag = Some(truepos_model::Lag {
                source: truepos_model::LagSource::Temperature(0),
                tau_s: 600.0,
            });
        }
        m
    }

    /// error = 2·(T0 − T1) + 0.01·x·(T0 − 20) µm: at x = 100 the gains are 3 and −2 µm/K.
    fn model(t: &[f64], p: &[f64]) -> Result<Vec<f64>, String> {
        Ok(vec![2.0 * (t[0] - t[1]) + 0.01 * p[0] * (t[0] - 20.0)])
    }

    fn words() -> Vec<PlcWord> {
        vec![
            PlcWord {
                sensor: 0,
                word: "W486".into(),
                scale: 0.1,
            },
            PlcWord {
                sensor: 1,
                word: "W488".into(),
                scale: 0.1,
            },
        ]
    }

    #[test]
    fn the_formula_is_the_model_at_its_position_for_any_temperature() {
        let corners = vec![vec![0.0], vec![800.0]];
        let tc = tempcomp(
            &machine(false),
            &model,
            &[25.0, 22.0],
            &[100.0],
            &corners,
            &words(),
            &[300.0],
        )
        .unwrap();
        assert_eq!(tc.len(), 1);
        assert_eq!(tc[0].per_kelvin_mm, vec![(0, -0.003), (1, 0.002)]);
        for t in [[20.0, 20.0], [31.5, 18.25], [45.0, 30.0]] {
            let want = -model(&t, &[100.0]).unwrap()[0] / 1000.0;
            assert!((tc[0].compensation_mm(&t) - want).abs() < 1e-12);
        }
        // At 25 °C on the spindle, x from 100 to 800 adds 0.01·700·5 = 35 µm the formula lacks.
        assert!((tc[0].position_error_um - 35.0).abs() < 1e-9);
        assert!(tc[0].formula.starts_with("300 + "), "{}", tc[0].formula);
        assert!(
            tc[0].formula.contains("(W486 * 0.1 - 20)"),
            "{}",
            tc[0].formula
        );
    }

    #[test]
    fn what_the_plc_does_not_have_is_refused_by_name() {
        let e = tempcomp(
            &machine(false),
            &model,
            &[25.0, 22.0],
            &[100.0],
            &[],
            &words()[..1],
            &[],
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("1 sensor(s) without a PLC word: bed (give --plc-word bed=W…)"),
            "{e}"
        );
        // Every missing word in one message, not one per run.
        let e = tempcomp(
            &machine(false),
            &model,
            &[25.0, 22.0],
            &[100.0],
            &[],
            &[],
            &[],
        )
        .unwrap_err();
        assert!(
            e.to_string().contains(
                "2 sensor(s) without a PLC word: spindle, bed (give --plc-word spindle=W…,bed=W…)"
            ),
            "{e}"
        );
        let e = tempcomp(
            &machine(true),
            &model,
            &[25.0, 22.0],
            &[100.0],
            &[],
            &words(),
            &[],
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("`bed`, lags of other channels"),
            "{e}"
        );
    }

    #[test]
    fn module_9231_range() {
        use crate::projection::{AxisProjection, LinearForm};
        let p = |k0_mm: f64| AxisProjection {
            axis: 0,
            name: "Z".into(),
            form: LinearForm {
                k0_mm,
                tan_beta: 0.0,
                p0_mm: 0.0,
            },
            along_error_um: 0.0,
            cross_axis: vec![],
        };
        assert_eq!(offset_9231(&p(-0.01234)).unwrap(), -123);
        assert_eq!(offset_9231(&p(3.0)).unwrap(), 30_000);
        assert!(offset_9231(&p(3.0001))
            .unwrap_err()
            .to_string()
            .contains("beyond module 9231's ±3 000 µm"));
    }
}
