//! Dynamic thermal models: structures lag their sensors, so a model may read first-order low-pass
//! filtered temperatures, their filtered rates of change, and filtered operating state (spindle
//! speed and its square), besides the temperature rises themselves; and the rises again while
//! the spindle runs, because the error a given rise stands for differs between running and
//! standing (the temperature field behind a surface sensor has another shape when the spindle's
//! own heat and forced convection act on it).
//!
//! The filters are stateful and run every cycle on the control. [`FeatureBank`] holds their
//! states (allocated once, at construction) and turns one cycle's inputs into the feature vector;
//! [`DynamicModel`] adds the fitted coefficients and produces the predicted error of every output.
//! `truepos-fit` builds its regressors by running this very `FeatureBank` over a recorded run, so
//! what was fitted offline is what runs online.
//!
//! ## The filters
//! First-order lag τ·dy/dt = x − y, discretised exactly for an input held over the step
//! (zero-order hold): y_k = y_{k−1} + a·(x_k − y_{k−1}) with a = 1 − exp(−Δt/τ). Its rate of
//! change is dy/dt = (x − y)/τ, evaluated with the updated state: a derivative that needs no
//! differencing of noisy samples.
//!
//! ## Features, in this order
//! For every temperature input i (°C): the rise ΔT_i = T_i − T_i(first cycle) if `temperature_rise`,
//! then LPF_τ(ΔT_i) for each τ of `temperature_taus_s`, then the rate (ΔT_i − LPF_τ(ΔT_i))/τ in
//! K/s for each τ of `rate_taus_s`. Then for every operating input u: LPF_τ(u) for each τ of
//! `operating_taus_s`, followed (if `operating_square`) by LPF_τ(u²) for each τ, followed (if
//! `rise_while_running`) by ΔT_i·[u ≠ 0] for every temperature input i: a commanded value of 0
//! means standing (a measured speed that is never exactly 0 needs a threshold, not provided).
//!
//! Temperatures are taken relative to the first cycle after [`FeatureBank::reset`], so a model
//! predicts the error relative to the moment it was started; every filter starts in steady state
//! at its first input.

use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use core::fmt;

/// Which features a [`FeatureBank`] computes from its inputs (see the module documentation for
/// the order).
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureSpec {
    /// Number of temperature inputs (°C); they come first in the input slice.
    pub temperatures: usize,
    /// Number of operating-state inputs (spindle speed in 1/min, …); they follow the temperatures.
    pub operating: usize,
    /// Whether the temperature rises ΔT themselves are features.
    pub temperature_rise: bool,
    /// Time constants (s) of low-pass filtered temperature rises.
    pub temperature_taus_s: Vec<f64>,
    /// Time constants (s) of filtered rates of change of temperature.
    pub rate_taus_s: Vec<f64>,
    /// Time constants (s) of low-pass filtered operating inputs.
    pub operating_taus_s: Vec<f64>,
    /// Whether the squares of the operating inputs are filtered too (spindle heat grows with
    /// speed faster than linearly).
    pub operating_square: bool,
    /// Whether every temperature rise is a feature again while each operating input is
    /// non-zero (a regime-dependent gain: running vs standing).
    pub rise_while_running: bool,
}

/// What a feature is, for names and reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FeatureKind {
    /// ΔT of a temperature input.
    Rise,
    /// LPF_τ(ΔT).
    LowPass {
        /// τ in s.
        tau_s: f64,
    },
    /// (ΔT − LPF_τ(ΔT))/τ in K/s.
    Rate {
        /// τ in s.
        tau_s: f64,
    },
    /// LPF_τ(u) of an operating input.
    Operating {
        /// τ in s.
        tau_s: f64,
    },
    /// LPF_τ(u²) of an operating input.
    OperatingSquared {
        /// τ in s.
        tau_s: f64,
    },
    /// ΔT of a temperature input while an operating input is non-zero, else 0.
    RiseWhileRunning {
        /// Index of the operating input (in the input slice).
        running: usize,
    },
}

impl FeatureKind {
    /// The time constant of a filtered feature (s); `None` for the unfiltered ones.
    pub fn tau_s(self) -> Option<f64> {
        match self {
            Self::LowPass { tau_s }
            | Self::Rate { tau_s }
            | Self::Operating { tau_s }
            | Self::OperatingSquared { tau_s } => Some(tau_s),
            Self::Rise | Self::RiseWhileRunning { .. } => None,
        }
    }
}

/// One feature: the input it reads and what it computes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    /// Index into the input slice.
    pub input: usize,
    /// Its kind.
    pub kind: FeatureKind,
}

impl Feature {
    /// A readable name, e.g. `lp3600(t5_c)` or `rise(t5_c)·running(spindle_rpm)`, given the
    /// name of each input by its index.
    pub fn name<'a>(&self, names: impl Fn(usize) -> &'a str) -> String {
        use core::fmt::Write;
        let input_name = names(self.input);
        let mut s = String::new();
        let _ = match self.kind {
            FeatureKind::Rise => write!(s, "rise({input_name})"),
            FeatureKind::LowPass { tau_s } => write!(s, "lp{tau_s}({input_name})"),
            FeatureKind::Rate { tau_s } => write!(s, "rate{tau_s}({input_name})"),
            FeatureKind::Operating { tau_s } => write!(s, "lp{tau_s}({input_name})"),
            FeatureKind::OperatingSquared { tau_s } => write!(s, "lp{tau_s}({input_name}^2)"),
            FeatureKind::RiseWhileRunning { running } => {
                write!(s, "rise({input_name})·running({})", names(running))
            }
        };
        s
    }
}

/// Why a cycle of a dynamic model produced nothing, or why a model could not be built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DynamicError {
    /// The input slice does not hold one value per input.
    InputLength {
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// An input is NaN or infinite; the filter states are left as they were.
    NonFiniteInput {
        /// Input index.
        input: usize,
    },
    /// The time step is not a finite positive number of seconds.
    BadTimeStep,
    /// A time constant is not finite and positive.
    BadTimeConstant,
    /// The coefficient table does not have one row per output and one column per feature, or
    /// holds a NaN/∞.
    BadCoefficients,
    /// An output came out non-finite (absurd but finite inputs).
    NonFiniteOutput {
        /// Output index.
        output: usize,
    },
}

impl fmt::Display for DynamicError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::InputLength { expected, got } => {
                write!(f, "expected {expected} input values, got {got}")
            }
            Self::NonFiniteInput { input } => write!(f, "input #{input} is not a finite number"),
            Self::BadTimeStep => write!(f, "the time step must be a finite number of seconds > 0"),
            Self::BadTimeConstant => write!(f, "every time constant must be finite and > 0 s"),
            Self::BadCoefficients => write!(
                f,
                "coefficients must be finite, one row per output and one column per feature"
            ),
            Self::NonFiniteOutput { output } => {
                write!(f, "output #{output} is not a finite number")
            }
        }
    }
}

impl core::error::Error for DynamicError {}

/// The stateful filters of a dynamic model: inputs of one cycle in, features out. Allocates only
/// in [`FeatureBank::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureBank {
    spec: FeatureSpec,
    features: Vec<Feature>,
    /// Temperatures at the first cycle.
    initial: Vec<f64>,
    /// Filter states in feature order (unused slots for rise features).
    state: Vec<f64>,
    values: Vec<f64>,
    started: bool,
    /// Per feature, the filter gain 1 − e^(−dt/τ) at `gain_dt` (0: none yet): a control cycle's
    /// dt rarely changes, and the exponential is most of a step's cost.
    gains: Vec<f64>,
    gain_dt: f64,
}

impl FeatureBank {
    /// A bank for this spec, with every filter waiting for its first input.
    pub fn new(spec: FeatureSpec) -> Result<Self, DynamicError> {
        let all_taus = spec
            .temperature_taus_s
            .iter()
            .chain(&spec.rate_taus_s)
            .chain(&spec.operating_taus_s);
        for &tau in all_taus {
            if !(tau.is_finite() && tau > 0.0) {
                return Err(DynamicError::BadTimeConstant);
            }
        }
        let mut features = Vec::new();
        for input in 0..spec.temperatures {
            if spec.temperature_rise {
                features.push(Feature {
                    input,
                    kind: FeatureKind::Rise,
                });
            }
            for &tau_s in &spec.temperature_taus_s {
                features.push(Feature {
                    input,
                    kind: FeatureKind::LowPass { tau_s },
                });
            }
            for &tau_s in &spec.rate_taus_s {
                features.push(Feature {
                    input,
                    kind: FeatureKind::Rate { tau_s },
                });
            }
        }
        for input in spec.temperatures..spec.temperatures + spec.operating {
            for &tau_s in &spec.operating_taus_s {
                features.push(Feature {
                    input,
                    kind: FeatureKind::Operating { tau_s },
                });
            }
            if spec.operating_square {
                for &tau_s in &spec.operating_taus_s {
                    features.push(Feature {
                        input,
                        kind: FeatureKind::OperatingSquared { tau_s },
                    });
                }
            }
            if spec.rise_while_running {
                for temperature in 0..spec.temperatures {
                    features.push(Feature {
                        input: temperature,
                        kind: FeatureKind::RiseWhileRunning { running: input },
                    });
                }
            }
        }
        let n = features.len();
        Ok(Self {
            initial: vec![0.0; spec.temperatures],
            spec,
            features,
            state: vec![0.0; n],
            values: vec![0.0; n],
            started: false,
            gains: vec![0.0; n],
            gain_dt: 0.0,
        })
    }

    /// The spec it was built from.
    pub fn spec(&self) -> &FeatureSpec {
        &self.spec
    }

    /// Number of inputs one cycle must give.
    pub fn input_count(&self) -> usize {
        self.spec.temperatures + self.spec.operating
    }

    /// The features, in output order.
    pub fn features(&self) -> &[Feature] {
        &self.features
    }

    /// Forgets every state: the next cycle is a first cycle again (machine restart).
    pub fn reset(&mut self) {
        self.started = false;
    }

    /// Advances every filter by one cycle of `dt_s` seconds (ignored on the first cycle) and
    /// returns the features. A NaN/∞ input or a bad `dt_s` gives an error and leaves every state
    /// untouched. Allocates nothing.
    pub fn step(&mut self, dt_s: f64, inputs: &[f64]) -> Result<&[f64], DynamicError> {
        let expected = self.input_count();
        if inputs.len() != expected {
            return Err(DynamicError::InputLength {
                expected,
                got: inputs.len(),
            });
        }
        if let Some(input) = inputs.iter().position(|v| !v.is_finite()) {
            return Err(DynamicError::NonFiniteInput { input });
        }
        let first = !self.started;
        let good_step = dt_s.is_finite() && dt_s > 0.0;
        if !first && !good_step {
            return Err(DynamicError::BadTimeStep);
        }
        if first {
            self.initial
                .copy_from_slice(&inputs[..self.spec.temperatures]);
        } else if dt_s != self.gain_dt {
            for (gain, f) in self.gains.iter_mut().zip(&self.features) {
                if let Some(tau_s) = f.kind.tau_s() {
                    *gain = lag_gain(dt_s, tau_s);
                }
            }
            self.gain_dt = dt_s;
        }
        for (k, f) in self.features.iter().enumerate() {
            let x = match f.kind {
                FeatureKind::Rise | FeatureKind::LowPass { .. } | FeatureKind::Rate { .. } => {
                    inputs[f.input] - self.initial[f.input]
                }
                FeatureKind::RiseWhileRunning { running } => {
                    if inputs[running] != 0.0 {
                        inputs[f.input] - self.initial[f.input]
                    } else {
                        0.0
                    }
                }
                FeatureKind::Operating { .. } => inputs[f.input],
                FeatureKind::OperatingSquared { .. } => inputs[f.input] * inputs[f.input],
            };
            let value = match f.kind {
                FeatureKind::Rise | FeatureKind::RiseWhileRunning { .. } => x,
                FeatureKind::LowPass { .. }
                | FeatureKind::Operating { .. }
                | FeatureKind::OperatingSquared { .. } => {
                    low_pass(&mut self.state[k], x, self.gains[k], first)
                }
                FeatureKind::Rate { tau_s } => {
                    let y = low_pass(&mut self.state[k], x, self.gains[k], first);
                    (x - y) / tau_s
                }
            };
            self.values[k] = value;
        }
        self.started = true;
        Ok(&self.values)
    }
}

/// The gain of one step of a first-order lag, 1 − e^(−dt/τ): the exact discrete form of
/// τ·ẏ + y = x with x held over the step. Every filter of the bank, and every offline copy of
/// one, uses this so that they agree to the last bit.
#[inline]
pub fn lag_gain(dt_s: f64, tau_s: f64) -> f64 {
    1.0 - libm::exp(-dt_s / tau_s)
}

/// One step of the first-order lag; on the first cycle the state starts at the input.
#[inline]
fn low_pass(state: &mut f64, x: f64, gain: f64, first: bool) -> f64 {
    if first {
        *state = x;
    } else {
        *state += gain * (x - *state);
    }
    *state
}

/// A fitted dynamic model: a [`FeatureBank`] and, per output, an intercept and one coefficient
/// per feature. Output k = intercept_k + Σ_j coefficient_kj · feature_j, the predicted error
/// (actual − nominal) in µm; the compensation is its negative.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicModel {
    bank: FeatureBank,
    intercepts: Vec<f64>,
    /// Row-major, outputs × features.
    coefficients: Vec<f64>,
    outputs: Vec<f64>,
}

impl DynamicModel {
    /// Binds coefficients (row-major, one row of `features().len()` values per output) to a bank.
    pub fn new(
        bank: FeatureBank,
        intercepts: Vec<f64>,
        coefficients: Vec<f64>,
    ) -> Result<Self, DynamicError> {
        let n = bank.features().len();
        if coefficients.len() != intercepts.len() * n
            || !coefficients
                .iter()
                .chain(&intercepts)
                .all(|c| c.is_finite())
        {
            return Err(DynamicError::BadCoefficients);
        }
        Ok(Self {
            outputs: vec![0.0; intercepts.len()],
            bank,
            intercepts,
            coefficients,
        })
    }

    /// The filters.
    pub fn bank(&self) -> &FeatureBank {
        &self.bank
    }

    /// Number of outputs.
    pub fn output_count(&self) -> usize {
        self.intercepts.len()
    }

    /// Intercepts, one per output (µm).
    pub fn intercepts(&self) -> &[f64] {
        &self.intercepts
    }

    /// Coefficients, row-major outputs × features.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// Restarts the filters (see [`FeatureBank::reset`]).
    pub fn reset(&mut self) {
        self.bank.reset();
    }

    /// One control cycle: advances the filters and returns the predicted error of every output in
    /// µm. Allocates nothing; never returns a NaN.
    pub fn step(&mut self, dt_s: f64, inputs: &[f64]) -> Result<&[f64], DynamicError> {
        let features = self.bank.step(dt_s, inputs)?;
        let n = features.len();
        for (k, out) in self.outputs.iter_mut().enumerate() {
            let row = &self.coefficients[k * n..(k + 1) * n];
            let mut sum = self.intercepts[k];
            for (c, f) in row.iter().zip(features) {
                sum += c * f;
            }
            if !sum.is_finite() {
                return Err(DynamicError::NonFiniteOutput { output: k });
            }
            *out = sum;
        }
        Ok(&self.outputs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> FeatureSpec {
        FeatureSpec {
            temperatures: 1,
            operating: 1,
            temperature_rise: true,
            temperature_taus_s: vec![100.0],
            rate_taus_s: vec![100.0],
            operating_taus_s: vec![50.0],
            operating_square: true,
            rise_while_running: false,
        }
    }

    #[test]
    fn filter_steps_by_hand() {
        let mut bank = FeatureBank::new(spec()).unwrap();
        // First cycle: 20 °C, 1000 rpm. Rise 0, filters at their inputs, rate 0.
        let f = bank.step(0.0, &[20.0, 1000.0]).unwrap().to_vec();
        assert_eq!(f, vec![0.0, 0.0, 0.0, 1000.0, 1.0e6]);
        // Second cycle, dt = 10 s: 21 °C (ΔT = 1), 2000 rpm.
        // a(τ=100) = 1 − e^−0.1 = 0.0951625820; LPF = 0.0951625820;
        // rate = (1 − 0.0951625820)/100 = 0.00904837418 K/s.
        // a(τ=50) = 1 − e^−0.2 = 0.181269247; LPF(u) = 1000 + 0.181269247·1000 = 1181.269247;
        // LPF(u²) = 1e6 + 0.181269247·3e6 = 1.543807741e6.
        let f = bank.step(10.0, &[21.0, 2000.0]).unwrap().to_vec();
        let want = [1.0, 0.0951625820, 0.00904837418, 1181.269247, 1.543807741e6];
        for (g, w) in f.iter().zip(want) {
            assert!((g - w).abs() <= 1e-8 * w.abs().max(1.0), "{g} vs {w}");
        }
    }

    /// Two temperatures, one spindle: the rises come back as features while the spindle runs.
    /// Cycle 1: 20 °C, 30 °C, standing → rises 0, 0 and 0, 0. Cycle 2: 22 °C, 31 °C, 800 rpm →
    /// rises 2, 1 and while running 2, 1. Cycle 3: 23 °C, 33 °C, stopped → rises 3, 3, while
    /// running 0, 0. Names carry both inputs.
    #[test]
    fn rises_while_running_follow_the_operating_input() {
        let mut bank = FeatureBank::new(FeatureSpec {
            temperatures: 2,
            operating: 1,
            temperature_rise: true,
            temperature_taus_s: vec![],
            rate_taus_s: vec![],
            operating_taus_s: vec![],
            operating_square: false,
            rise_while_running: true,
        })
        .unwrap();
        let names = ["t1_c", "t2_c", "spindle_rpm"];
        let named: Vec<String> = bank
            .features()
            .iter()
            .map(|f| f.name(|i| names[i]))
            .collect();
        assert_eq!(
            named,
            [
                "rise(t1_c)",
                "rise(t2_c)",
                "rise(t1_c)·running(spindle_rpm)",
                "rise(t2_c)·running(spindle_rpm)"
            ]
        );
        assert_eq!(bank.step(0.0, &[20.0, 30.0, 0.0]).unwrap(), &[0.0; 4]);
        assert_eq!(
            bank.step(15.0, &[22.0, 31.0, 800.0]).unwrap(),
            &[2.0, 1.0, 2.0, 1.0]
        );
        assert_eq!(
            bank.step(15.0, &[23.0, 33.0, 0.0]).unwrap(),
            &[3.0, 3.0, 0.0, 0.0]
        );
    }

    #[test]
    fn step_response_reaches_63_percent_after_tau() {
        let mut bank = FeatureBank::new(FeatureSpec {
            temperatures: 1,
            operating: 0,
            temperature_rise: false,
            temperature_taus_s: vec![60.0],
            rate_taus_s: vec![],
            operating_taus_s: vec![],
            operating_square: false,
            rise_while_running: false,
        })
        .unwrap();
        bank.step(0.0, &[0.0]).unwrap();
        let mut y = 0.0;
        for _ in 0..60 {
            y = bank.step(1.0, &[1.0]).unwrap()[0];
        }
        // 1 − e^−1 = 0.632120559 exactly for the zero-order-hold discretisation.
        assert!((y - 0.632_120_558_8).abs() < 1e-9, "{y}");
    }

    #[test]
    fn bad_inputs_are_errors_and_leave_state() {
        let mut bank = FeatureBank::new(spec()).unwrap();
        bank.step(0.0, &[20.0, 0.0]).unwrap();
        let before = bank.clone();
        assert_eq!(
            bank.step(1.0, &[f64::NAN, 0.0]),
            Err(DynamicError::NonFiniteInput { input: 0 })
        );
        assert_eq!(bank.step(0.0, &[20.0, 0.0]), Err(DynamicError::BadTimeStep));
        assert_eq!(
            bank.step(1.0, &[20.0]),
            Err(DynamicError::InputLength {
                expected: 2,
                got: 1
            })
        );
        assert_eq!(bank, before);
        assert!(FeatureBank::new(FeatureSpec {
            rate_taus_s: vec![0.0],
            ..spec()
        })
        .is_err());
    }

    #[test]
    fn model_output_is_intercept_plus_weighted_features() {
        let bank = FeatureBank::new(spec()).unwrap();
        // Two outputs; output 0 = 1 + 2·ΔT, output 1 = −0.001·LPF50(u).
        let coefficients = vec![2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.001, 0.0];
        let mut model = DynamicModel::new(bank, vec![1.0, 0.0], coefficients).unwrap();
        let out = model.step(0.0, &[20.0, 1000.0]).unwrap();
        assert_eq!(out, &[1.0, -1.0]);
        let out = model.step(10.0, &[23.0, 1000.0]).unwrap();
        assert_eq!(out, &[7.0, -1.0]);
        assert!(
            DynamicModel::new(FeatureBank::new(spec()).unwrap(), vec![0.0], vec![1.0]).is_err()
        );
    }

    #[test]
    fn step_allocates_nothing() {
        let bank = FeatureBank::new(spec()).unwrap();
        let mut model = DynamicModel::new(bank, vec![0.5], vec![1.0; 5]).unwrap();
        let info = allocation_counter::measure(|| {
            for k in 0..100 {
                let t = 20.0 + f64::from(k) * 0.01;
                let _ = model.step(1.0, &[t, 1000.0]).unwrap();
            }
        });
        assert_eq!(info.count_total, 0);
    }
}
