//! Evaluation of a model for one control cycle: no allocation, no I/O, no panic.

use core::fmt;

use crate::dynamic::DynamicError;
use crate::machine::{Reference, MAX_AXES};
use crate::model::{g_index, Model, PositionFactor, FACTORS, MAX_MODEL_DIFFERENCES};

/// How far (as a fraction of the axis length) a position may lie outside travel before it is
/// taken as a fault (wrong units, wrong axis) rather than feedback overshoot at a limit. Within
/// this margin the position factor is held at the end of travel.
pub const TRAVEL_TOLERANCE: f64 = 0.01;

/// The inputs of one cycle, in the machine description's channel order.
#[derive(Debug, Clone, Copy)]
pub struct CycleInput<'a> {
    /// Every temperature channel in °C.
    pub temperatures_c: &'a [f64],
    /// Every axis position (mm or degrees).
    pub positions: &'a [f64],
    /// Every operating-state channel (spindle speed, …); read by later model forms.
    pub operating: &'a [f64],
}

/// Why one cycle produced no correction. Every variant is `Copy` and carries indices only, so
/// that reporting it needs no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EvalError {
    /// A slice does not have one value per channel of the machine.
    InputLength {
        /// `temperatures_c`, `positions` or `operating`.
        input: &'static str,
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A temperature the model reads is NaN or infinite.
    NonFiniteTemperature {
        /// Temperature channel index.
        channel: usize,
    },
    /// A temperature the model reads lies outside the channel's valid range.
    TemperatureOutOfRange {
        /// Temperature channel index.
        channel: usize,
        /// The reading in °C.
        value: f64,
    },
    /// An axis position is NaN or infinite.
    NonFinitePosition {
        /// Axis index.
        axis: usize,
    },
    /// An axis position lies outside travel by more than [`TRAVEL_TOLERANCE`].
    PositionOutsideTravel {
        /// Axis index.
        axis: usize,
        /// The position.
        value: f64,
    },
    /// The sum overflowed to a non-finite value (absurd but finite inputs).
    NonFiniteResult {
        /// Axis index.
        axis: usize,
    },
    /// An operating input a dynamic model reads is NaN or infinite.
    NonFiniteOperating {
        /// Operating channel index.
        channel: usize,
    },
    /// A dynamic model's filters refused the step (a time step that is not > 0, an output that
    /// came out non-finite).
    Filter(DynamicError),
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::InputLength {
                input,
                expected,
                got,
            } => write!(f, "{input}: expected {expected} values, got {got}"),
            Self::NonFiniteTemperature { channel } => {
                write!(f, "temperature channel #{channel} is not a finite number")
            }
            Self::TemperatureOutOfRange { channel, value } => write!(
                f,
                "temperature channel #{channel} reads {value} °C, outside its valid range"
            ),
            Self::NonFinitePosition { axis } => {
                write!(f, "position of axis #{axis} is not a finite number")
            }
            Self::PositionOutsideTravel { axis, value } => {
                write!(
                    f,
                    "position {value} of axis #{axis} lies outside its travel"
                )
            }
            Self::NonFiniteResult { axis } => {
                write!(f, "the correction of axis #{axis} is not a finite number")
            }
            Self::NonFiniteOperating { channel } => {
                write!(f, "operating channel #{channel} is not a finite number")
            }
            Self::Filter(e) => write!(f, "dynamic model: {e}"),
        }
    }
}

impl core::error::Error for EvalError {}

/// The result of one cycle, per axis in machine order.
///
/// Sign convention (used throughout truepos): **error = actual − nominal** position of the tool
/// relative to the workpiece; the model predicts the error, and the **compensation added to the
/// set-point is −error**. The compensation value ΔA_n "superimposed on the set-point"
/// (docs/glossary.md) is therefore `compensation_um`, and a model file's coefficients describe the
/// error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correction {
    axes: usize,
    error_um: [f64; MAX_AXES],
}

impl Correction {
    /// A correction of `axes` zeros.
    pub const fn zero(axes: usize) -> Self {
        Self {
            axes: if axes > MAX_AXES { MAX_AXES } else { axes },
            error_um: [0.0; MAX_AXES],
        }
    }

    /// Number of axes.
    pub fn axis_count(&self) -> usize {
        self.axes
    }

    /// The predicted thermal error of each axis in µm.
    pub fn error_um(&self) -> &[f64] {
        &self.error_um[..self.axes]
    }

    /// The compensation to add to the set-point of `axis` in µm: −error.
    pub fn compensation_um(&self, axis: usize) -> f64 {
        if axis < self.axes {
            // 0 − e rather than −e: a zero error gives +0, not −0, in files and displays.
            0.0 - self.error_um[axis]
        } else {
            0.0
        }
    }
}

/// Each input slice has the length the model was bound for: `(input, expected, got)`, the first
/// that differs is the error.
pub(crate) fn check_lengths(lengths: &[(&'static str, usize, usize)]) -> Result<(), EvalError> {
    for &(name, expected, got) in lengths {
        if expected != got {
            return Err(EvalError::InputLength {
                input: name,
                expected,
                got,
            });
        }
    }
    Ok(())
}

impl Model {
    /// Evaluates every enabled part for one cycle.
    ///
    /// Only the temperatures the model reads are checked (finite, within their valid range), so a
    /// fault on an unrelated sensor does not stop this model. Positions must be finite and
    /// within travel (± [`TRAVEL_TOLERANCE`]). Nothing here allocates or panics.
    pub fn evaluate(&self, input: &CycleInput<'_>) -> Result<Correction, EvalError> {
        let lengths = [
            (
                "temperatures_c",
                self.temperature_count,
                input.temperatures_c.len(),
            ),
            ("positions", self.axes.len(), input.positions.len()),
            ("operating", self.operating_count, input.operating.len()),
        ];
        check_lengths(&lengths)?;
        for &ch in &self.used_sensors {
            let value = input.temperatures_c[ch];
            if !value.is_finite() {
                return Err(EvalError::NonFiniteTemperature { channel: ch });
            }
            let (lo, hi) = self.valid_ranges[ch];
            if value < lo || value > hi {
                return Err(EvalError::TemperatureOutOfRange { channel: ch, value });
            }
        }
        // g of every axis and factor, computed once per cycle: [r, r², KFA] per axis.
        let mut g = [0.0_f64; FACTORS * MAX_AXES];
        for (i, (axis, &pos)) in self.axes.iter().zip(input.positions).enumerate() {
            if !pos.is_finite() {
                return Err(EvalError::NonFinitePosition { axis: i });
            }
            let r = (pos - axis.travel_min) / axis.length;
            if !(-TRAVEL_TOLERANCE..=1.0 + TRAVEL_TOLERANCE).contains(&r) {
                return Err(EvalError::PositionOutsideTravel {
                    axis: i,
                    value: pos,
                });
            }
            let r = r.clamp(0.0, 1.0);
            g[g_index(i, PositionFactor::Ratio)] = PositionFactor::Ratio.of_ratio(r);
            g[g_index(i, PositionFactor::RatioSquared)] = PositionFactor::RatioSquared.of_ratio(r);
            g[g_index(i, PositionFactor::BedFactor)] = PositionFactor::BedFactor.of_ratio(r);
        }
        let mut delta = [0.0_f64; MAX_MODEL_DIFFERENCES];
        for (d, inp) in delta.iter_mut().zip(&self.difference_inputs) {
            let reference = match inp.minus {
                Reference::Sensor(s) => input.temperatures_c[s],
                Reference::Fixed(t) => t,
            };
            *d = input.temperatures_c[inp.plus] - reference;
        }
        let mut out = Correction::zero(self.axes.len());
        for s in &self.summands {
            if !self.part_enabled[s.part] {
                continue;
            }
            let mut bracket = s.k0;
            for &(gi, k) in &self.terms[s.terms_start..s.terms_end] {
                bracket += k * g[gi];
            }
            let mut value = delta[s.local_difference] * bracket;
            if let Some(b) = s.bed_multiplier {
                value *= g[g_index(b, PositionFactor::BedFactor)];
            }
            out.error_um[s.axis] += value;
        }
        for &(part, axis, value) in &self.constants {
            if self.part_enabled[part] {
                out.error_um[axis] += value;
            }
        }
        for (axis, e) in out.error_um().iter().enumerate() {
            if !e.is_finite() {
                return Err(EvalError::NonFiniteResult { axis });
            }
        }
        Ok(out)
    }
}
