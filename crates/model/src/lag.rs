//! Lagged temperature channels: the structure lags its sensors.
//!
//! A sensor on the surface of a casting answers to a heat source within minutes; the casting's mean
//! temperature, which sets its growth and bending, follows over an hour or more. A temperature
//! channel with a [`Lag`] is not read from hardware: the control computes it every cycle as the
//! first-order lag of another sensor, τ·dy/dt = x − y, discretised exactly for an input held over
//! the step (zero-order hold): y_k = y_{k−1} + a·(x_k − y_{k−1}), a = 1 − exp(−Δt/τ). Every model
//! term — the position-dependent summands as much as the prior art's ΔT·K — can then read a lagged
//! channel through an ordinary temperature difference, so dynamics and position dependence live in
//! one model form that [`crate::Model::evaluate`] evaluates unchanged.
//!
//! [`LagFilters`] holds the filter states (allocated once, when built from the machine) and
//! fills the lagged channels of a cycle's temperature slice in place.
//!
//! ```
//! use truepos_model::*;
//! let sensor = |id: &str, lag: Option<Lag>| TemperatureChannel {
//!     id: id.into(), location: String::new(), valid_min_c: 0.0, valid_max_c: 80.0, lag,
//! };
//! let machine = Machine {
//!     name: "m".into(),
//!     axes: vec![Axis { name: "Z".into(), kind: AxisKind::Linear, travel_min: 0.0,
//!         travel_max: 500.0, carried_by: None, carriage: Carriage::Cantilever }],
//!     temperatures: vec![
//!         sensor("spindle", None),
//!         sensor("spindle_lag1h", Some(Lag { source: LagSource::Temperature(0), tau_s: 3600.0 })),
//!     ],
//!     differences: vec![],
//!     operating: vec![],
//! };
//! machine.check().unwrap();
//! let mut lags = LagFilters::new(&machine);
//! let mut t = [20.0, f64::NAN];
//! lags.apply(0.0, &mut t, &[]); // first cycle: the lag starts in steady state
//! assert_eq!(t[1], 20.0);
//! t[0] = 30.0;
//! lags.apply(3600.0, &mut t, &[]); // one time constant later: 1 − 1/e of the 10 K step
//! assert!((t[1] - (20.0 + 10.0 * (1.0 - (-1.0f64).exp()))).abs() < 1e-9);
//! ```

use alloc::vec::Vec;

use crate::machine::Machine;

/// What a lagged channel follows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LagSource {
    /// A measured temperature channel (its index); the lag reads in °C like its source.
    Temperature(usize),
    /// An operating-state channel (spindle speed, axis speed, …): a heat source the control
    /// knows before any sensor sees it. The lag follows `gain_k_per_unit · u^power` and reads as
    /// a temperature rise in K of a virtual node heated by that load (0 at rest).
    Operating {
        /// Index of the operating channel.
        channel: usize,
        /// K per unit of u^power (e.g. 0.001 K per 1/min).
        gain_k_per_unit: f64,
        /// 1 or 2: bearing friction heat grows with speed faster than linearly.
        power: u8,
    },
}

/// How a lagged channel is computed: the first-order lag of a measured channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lag {
    /// What it follows.
    pub source: LagSource,
    /// Time constant τ in s.
    pub tau_s: f64,
}

#[derive(Debug, Clone, Copy)]
struct Filter {
    channel: usize,
    source: LagSource,
    tau_s: f64,
    state: f64,
    started: bool,
}

/// The states of every lagged channel of a machine.
#[derive(Debug, Clone)]
pub struct LagFilters {
    filters: Vec<Filter>,
}

impl LagFilters {
    /// One filter per lagged channel of a checked machine ([`Machine::check`] guarantees that
    /// sources are measured channels and time constants are positive and finite).
    pub fn new(machine: &Machine) -> Self {
        let filters = machine
            .temperatures
            .iter()
            .enumerate()
            .filter_map(|(channel, t)| {
                t.lag.map(|lag| Filter {
                    channel,
                    source: lag.source,
                    tau_s: lag.tau_s,
                    state: 0.0,
                    started: false,
                })
            })
            .collect();
        Self { filters }
    }

    /// Whether the machine has no lagged channel.
    pub fn is_empty(&self) -> bool {
        self.filters.is_empty()
    }

    /// Forgets every state: the next [`LagFilters::apply`] starts each filter in steady state
    /// at its source's value.
    pub fn reset(&mut self) {
        for f in &mut self.filters {
            f.started = false;
        }
    }

    /// Advances every filter by `dt_s` with the source values of this cycle and writes the
    /// lagged channels into `temperatures_c`. No allocation, no panic: a slice too short for a
    /// channel skips it; a non-finite or negative step counts as zero; a source that is NaN or
    /// ∞ leaves its filter untouched and writes NaN into the lagged channel, so no compensation
    /// is computed from it (the model reports the channel as non-finite).
    pub fn apply(&mut self, dt_s: f64, temperatures_c: &mut [f64], operating: &[f64]) {
        self.apply_checked(dt_s, temperatures_c, operating, |_| true);
    }

    /// As [`LagFilters::apply`], but a temperature source for which `good` says `false` (a
    /// sensor the runtime's validation judged faulty) counts as NaN: its lag holds its state and
    /// reads NaN until the sensor is good again.
    pub fn apply_checked(
        &mut self,
        dt_s: f64,
        temperatures_c: &mut [f64],
        operating: &[f64],
        good: impl Fn(usize) -> bool,
    ) {
        let dt = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s
        } else {
            0.0
        };
        for f in &mut self.filters {
            let x = match f.source {
                LagSource::Temperature(s) => match temperatures_c.get(s) {
                    Some(&x) if good(s) => x,
                    Some(_) => f64::NAN,
                    None => continue,
                },
                LagSource::Operating {
                    channel,
                    gain_k_per_unit,
                    power,
                } => match operating.get(channel) {
                    Some(&u) if power == 2 => gain_k_per_unit * u * u,
                    Some(&u) => gain_k_per_unit * u,
                    None => continue,
                },
            };
            let out = if !x.is_finite() {
                f64::NAN
            } else if !f.started {
                f.state = x;
                f.started = true;
                x
            } else {
                let a = 1.0 - libm::exp(-dt / f.tau_s);
                f.state += a * (x - f.state);
                f.state
            };
            if let Some(slot) = temperatures_c.get_mut(f.channel) {
                *slot = out;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::{Axis, AxisKind, Carriage, TemperatureChannel};
    use alloc::string::String;
    use alloc::vec;

    fn machine(lags: &[(usize, f64)]) -> Machine {
        let mut temperatures = vec![TemperatureChannel {
            id: "s".into(),
            location: String::new(),
            valid_min_c: 0.0,
            valid_max_c: 80.0,
            lag: None,
        }];
        for (i, &(source, tau_s)) in lags.iter().enumerate() {
            temperatures.push(TemperatureChannel {
                id: alloc::format!("lag{i}"),
                location: String::new(),
                valid_min_c: 0.0,
                valid_max_c: 80.0,
                lag: Some(Lag {
                    source: LagSource::Temperature(source),
                    tau_s,
                }),
            });
        }
        Machine {
            name: "m".into(),
            axes: vec![Axis {
                name: "X".into(),
                kind: AxisKind::Linear,
                travel_min: 0.0,
                travel_max: 1.0,
                carried_by: None,
                carriage: Carriage::Cantilever,
            }],
            temperatures,
            differences: vec![],
            operating: vec![],
        }
    }

    #[test]
    fn step_response_is_exact_for_any_step_size() {
        // A 10 K step at t = 0 through τ = 100 s: y(t) = 10·(1 − e^(−t/100)).
        // After 50 s in one step or in 50 steps of 1 s: 10·(1 − e^−0.5) = 3.934693403 K.
        let m = machine(&[(0, 100.0)]);
        m.check().unwrap();
        for steps in [1usize, 50] {
            let mut lags = LagFilters::new(&m);
            let mut t = [0.0, 0.0];
            lags.apply(0.0, &mut t, &[]);
            t[0] = 10.0;
            for _ in 0..steps {
                lags.apply(50.0 / steps as f64, &mut t, &[]);
            }
            assert!((t[1] - 3.934_693_403).abs() < 1e-8, "{steps}: {}", t[1]);
        }
    }

    #[test]
    fn a_bad_source_gives_nan_and_keeps_the_state() {
        let m = machine(&[(0, 10.0)]);
        let mut lags = LagFilters::new(&m);
        let mut t = [20.0, 0.0];
        lags.apply(0.0, &mut t, &[]);
        t[0] = f64::NAN;
        lags.apply(1.0, &mut t, &[]);
        assert!(t[1].is_nan());
        // Recovery continues from the state before the fault: 20 → 20 with no jump.
        t[0] = 20.0;
        lags.apply(f64::INFINITY, &mut t, &[]);
        assert_eq!(t[1], 20.0);
        // A slice too short is skipped, not a panic.
        lags.apply(1.0, &mut [20.0], &[]);
    }

    #[test]
    fn an_operating_load_heats_a_virtual_node() {
        // Spindle 0 → 6000 1/min at t = 0, 0.001 K per 1/min, τ = 300 s: after 300 s the node
        // reads 6 K·(1 − e^−1) = 3.792723 K. The squared load with 1e-7 K/(1/min)² settles at
        // 6000²·1e-7 = 3.6 K.
        let mut m = machine(&[(0, 300.0), (0, 1.0)]);
        m.temperatures[1].lag = Some(Lag {
            source: LagSource::Operating {
                channel: 0,
                gain_k_per_unit: 0.001,
                power: 1,
            },
            tau_s: 300.0,
        });
        m.temperatures[2].lag = Some(Lag {
            source: LagSource::Operating {
                channel: 0,
                gain_k_per_unit: 1e-7,
                power: 2,
            },
            tau_s: 1.0,
        });
        m.operating.push(crate::machine::OperatingChannel {
            id: "spindle_rpm".into(),
            kind: crate::machine::OperatingKind::SpindleSpeed,
            axis: None,
        });
        m.check().unwrap();
        let mut lags = LagFilters::new(&m);
        let mut t = [20.0, 0.0, 0.0];
        lags.apply(0.0, &mut t, &[0.0]);
        assert_eq!(t[1..], [0.0, 0.0]);
        lags.apply(300.0, &mut t, &[6000.0]);
        assert!((t[1] - 3.792_723_35).abs() < 1e-6, "{}", t[1]);
        assert!((t[2] - 3.6).abs() < 1e-9, "{}", t[2]);
        // An unknown speed (NaN) gives NaN, never a number made up.
        lags.apply(1.0, &mut t, &[f64::NAN]);
        assert!(t[1].is_nan() && t[2].is_nan());
    }

    #[test]
    fn reset_restarts_in_steady_state() {
        let m = machine(&[(0, 10.0), (0, 1000.0)]);
        let mut lags = LagFilters::new(&m);
        let mut t = [20.0, 0.0, 0.0];
        lags.apply(0.0, &mut t, &[]);
        t[0] = 30.0;
        lags.apply(5.0, &mut t, &[]);
        assert!(t[1] > 20.0 && t[1] < 30.0 && t[2] < t[1]);
        lags.reset();
        lags.apply(5.0, &mut t, &[]);
        assert_eq!(t[1..], [30.0, 30.0]);
    }
}
