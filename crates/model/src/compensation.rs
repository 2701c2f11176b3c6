//! A compensation model the control runs, whatever its form: a position-dependent [`Model`],
//! evaluated afresh every cycle, or a fitted [`DynamicModel`] bound to the machine, whose filters
//! advance every cycle. Every user — the runtime's model set, `truepos eval` and `truepos report`,
//! the LinuxCNC check — steps it through [`CompensationModel::step`], so that input gathering, time
//! stepping and the mapping of outputs to axes exist once.
//!
//! Nothing here allocates after construction: a dynamic model gathers its inputs into a buffer
//! made when it was bound.

use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use core::fmt;

use crate::dynamic::DynamicModel;
use crate::envelope::{Beyond, TrainingEnvelope};
use crate::evaluate::{check_lengths, CycleInput, EvalError};
use crate::machine::MAX_AXES;
use crate::model::Model;

/// Where a dynamic model's input comes from on the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MachineInput {
    /// A temperature channel (index into `Machine::temperatures`).
    Temperature(usize),
    /// An operating channel (index into `Machine::operating`).
    Operating(usize),
}

/// Why a dynamic model cannot be bound: the mapping does not fit the model or the machine.
/// The file loader checks all of this with names and keys first; this is the core's own guard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindError {
    /// Not one machine channel per model input.
    InputCount {
        /// The model's inputs.
        expected: usize,
        /// Channels given.
        got: usize,
    },
    /// Not one axis entry per model output.
    OutputCount {
        /// The model's outputs.
        expected: usize,
        /// Axis entries given.
        got: usize,
    },
    /// An input names a channel the machine does not have.
    NoSuchChannel {
        /// Model input index.
        input: usize,
    },
    /// An output names an axis beyond the machine's (or beyond [`MAX_AXES`]).
    NoSuchAxis {
        /// Model output index.
        output: usize,
    },
}

impl fmt::Display for BindError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::InputCount { expected, got } => {
                write!(f, "expected {expected} input channels, got {got}")
            }
            Self::OutputCount { expected, got } => {
                write!(f, "expected {expected} output axes, got {got}")
            }
            Self::NoSuchChannel { input } => {
                write!(f, "input #{input} names no channel of the machine")
            }
            Self::NoSuchAxis { output } => {
                write!(f, "output #{output} names no axis of the machine")
            }
        }
    }
}

impl core::error::Error for BindError {}

/// The machine's channel counts a model is bound to (the lengths of a [`CycleInput`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Channels {
    /// Temperature channels (lagged ones included).
    pub temperatures: usize,
    /// Operating channels.
    pub operating: usize,
    /// Axes.
    pub axes: usize,
}

/// A fitted dynamic model bound to a machine: which channel feeds each input, which axis each
/// output compensates.
#[derive(Debug, Clone)]
pub struct BoundDynamicModel {
    name: String,
    model: DynamicModel,
    inputs: Vec<MachineInput>,
    axes: Vec<Option<usize>>,
    unused_outputs: Vec<String>,
    channels: Channels,
    /// The temperature channels it reads, sorted, each once.
    sensors: Vec<usize>,
    /// This cycle's input values, in the model's order.
    buffer: Vec<f64>,
    /// Where it was trained, if its file says ([`crate::envelope`]).
    envelope: Option<TrainingEnvelope>,
}

/// Equal when model (with its filters' state) and mapping are; the input buffer is scratch.
impl PartialEq for BoundDynamicModel {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.model == other.model
            && self.inputs == other.inputs
            && self.axes == other.axes
            && self.unused_outputs == other.unused_outputs
            && self.channels == other.channels
            && self.envelope == other.envelope
    }
}

impl BoundDynamicModel {
    /// Binds `model` to a machine with `channels`: `inputs` gives the channel of every model
    /// input, `axes` the axis of every output (`None`: no axis takes it; its name goes in
    /// `unused_outputs`, for reports).
    pub fn new(
        name: String,
        model: DynamicModel,
        inputs: Vec<MachineInput>,
        axes: Vec<Option<usize>>,
        unused_outputs: Vec<String>,
        channels: Channels,
    ) -> Result<Self, BindError> {
        let expected = model.bank().input_count();
        if inputs.len() != expected {
            return Err(BindError::InputCount {
                expected,
                got: inputs.len(),
            });
        }
        if axes.len() != model.output_count() {
            return Err(BindError::OutputCount {
                expected: model.output_count(),
                got: axes.len(),
            });
        }
        if let Some(input) = inputs.iter().position(|i| match *i {
            MachineInput::Temperature(c) => c >= channels.temperatures,
            MachineInput::Operating(c) => c >= channels.operating,
        }) {
            return Err(BindError::NoSuchChannel { input });
        }
        if let Some(output) = axes
            .iter()
            .position(|a| a.is_some_and(|a| a >= channels.axes.min(MAX_AXES)))
        {
            return Err(BindError::NoSuchAxis { output });
        }
        let mut sensors: Vec<usize> = inputs
            .iter()
            .filter_map(|i| match *i {
                MachineInput::Temperature(c) => Some(c),
                MachineInput::Operating(_) => None,
            })
            .collect();
        sensors.sort_unstable();
        sensors.dedup();
        Ok(Self {
            buffer: vec![0.0; inputs.len()],
            name,
            model,
            inputs,
            axes,
            unused_outputs,
            channels,
            sensors,
            envelope: None,
        })
    }

    /// Where the model was trained, if known.
    pub fn envelope(&self) -> Option<&TrainingEnvelope> {
        self.envelope.as_ref()
    }

    /// Stores where the model was trained (from its file or its fit).
    pub fn set_envelope(&mut self, envelope: Option<TrainingEnvelope>) {
        self.envelope = envelope;
    }

    /// Name for events and reports (the file's stem).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The real-time model (features, coefficients).
    pub fn model(&self) -> &DynamicModel {
        &self.model
    }

    /// The machine channel of every model input, in the model's order.
    pub fn inputs(&self) -> &[MachineInput] {
        &self.inputs
    }

    /// Per output: the machine axis it compensates, `None` for an output no axis takes.
    pub fn axes(&self) -> &[Option<usize>] {
        &self.axes
    }

    /// Names of the outputs no axis takes (reported, never applied).
    pub fn unused_outputs(&self) -> &[String] {
        &self.unused_outputs
    }

    /// The temperature channels it reads, sorted, each once (its sensors, for validation).
    pub fn temperature_channels(&self) -> &[usize] {
        &self.sensors
    }

    /// The machine's channel counts it was bound to.
    pub fn channels(&self) -> Channels {
        self.channels
    }

    /// One cycle: gathers the inputs from `input`, advances the filters by `dt_s` (ignored on
    /// the first cycle after a reset) and returns the predicted error of every axis, µm. A
    /// non-finite input is refused naming its channel, before the filters move; a bad `dt_s` is
    /// [`EvalError::Filter`] with [`crate::DynamicError::BadTimeStep`]. Allocates nothing.
    pub fn step(
        &mut self,
        dt_s: f64,
        input: &CycleInput<'_>,
    ) -> Result<[f64; MAX_AXES], EvalError> {
        let lengths = [
            (
                "temperatures_c",
                self.channels.temperatures,
                input.temperatures_c.len(),
            ),
            ("operating", self.channels.operating, input.operating.len()),
        ];
        check_lengths(&lengths)?;
        for (slot, source) in self.buffer.iter_mut().zip(&self.inputs) {
            *slot = match *source {
                MachineInput::Temperature(channel) => {
                    let v = input.temperatures_c[channel];
                    if !v.is_finite() {
                        return Err(EvalError::NonFiniteTemperature { channel });
                    }
                    v
                }
                MachineInput::Operating(channel) => {
                    let v = input.operating[channel];
                    if !v.is_finite() {
                        return Err(EvalError::NonFiniteOperating { channel });
                    }
                    v
                }
            };
        }
        let outputs = self
            .model
            .step(dt_s, &self.buffer)
            .map_err(EvalError::Filter)?;
        let mut error_um = [0.0; MAX_AXES];
        for (e, axis) in outputs.iter().zip(&self.axes) {
            if let Some(a) = *axis {
                error_um[a] = *e;
            }
        }
        Ok(error_um)
    }

    /// Forgets the filters' history: the next step is a first cycle again.
    pub fn reset(&mut self) {
        self.model.reset();
    }
}

/// A compensation model the control runs, in one of two forms: position-dependent (with the
/// reference-sensor regression) or filtered (a fitted dynamic model).
// Built once at load time and kept in one Vec: the variants' sizes cost nothing on the cycle,
// a Box would cost an indirection on it.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum CompensationModel {
    /// A position-dependent model or the reference-sensor regression: a function of this
    /// cycle's values.
    Position(Model),
    /// A fitted filtered (dynamic) model: its filters carry history from cycle to cycle.
    Filtered(BoundDynamicModel),
}

impl From<Model> for CompensationModel {
    fn from(m: Model) -> Self {
        Self::Position(m)
    }
}

impl From<BoundDynamicModel> for CompensationModel {
    fn from(m: BoundDynamicModel) -> Self {
        Self::Filtered(m)
    }
}

impl CompensationModel {
    /// Its name.
    pub fn name(&self) -> &str {
        match self {
            Self::Position(m) => m.name(),
            Self::Filtered(d) => d.name(),
        }
    }

    /// The temperature channels it reads (lagged channels count as what they are), sorted.
    pub fn used_sensors(&self) -> &[usize] {
        match self {
            Self::Position(m) => m.used_sensors(),
            Self::Filtered(d) => d.temperature_channels(),
        }
    }

    /// Where it was trained, if its file says ([`crate::envelope`]).
    pub fn envelope(&self) -> Option<&TrainingEnvelope> {
        match self {
            Self::Position(m) => m.envelope(),
            Self::Filtered(d) => d.envelope(),
        }
    }

    /// Whether it keeps state between cycles (its filters), so that it must be stepped every
    /// cycle, in order, to be current.
    pub fn keeps_state(&self) -> bool {
        matches!(self, Self::Filtered(_))
    }

    /// Whether it reads axis positions (a fitted dynamic model does not).
    pub fn reads_positions(&self) -> bool {
        matches!(self, Self::Position(_))
    }

    /// Number of axes it gives an error for (the machine's).
    pub fn axis_count(&self) -> usize {
        match self {
            Self::Position(m) => m.axis_count(),
            Self::Filtered(d) => d.channels().axes.min(MAX_AXES),
        }
    }

    /// The static model, if it is one.
    pub fn as_static(&self) -> Option<&Model> {
        match self {
            Self::Position(m) => Some(m),
            Self::Filtered(_) => None,
        }
    }

    /// The static model, if it is one, to switch its parts.
    pub fn as_static_mut(&mut self) -> Option<&mut Model> {
        match self {
            Self::Position(m) => Some(m),
            Self::Filtered(_) => None,
        }
    }

    /// The dynamic model, if it is one.
    pub fn as_dynamic(&self) -> Option<&BoundDynamicModel> {
        match self {
            Self::Position(_) => None,
            Self::Filtered(d) => Some(d),
        }
    }

    /// One cycle of `dt_s` seconds: the predicted error (actual − nominal) of every machine axis
    /// in µm, zero beyond [`Self::axis_count`] and on axes the model does not serve. A static
    /// model evaluates `input` and ignores `dt_s`; a dynamic one see [`BoundDynamicModel::step`].
    /// Allocates nothing, never panics, never returns a NaN or ∞.
    pub fn step(
        &mut self,
        dt_s: f64,
        input: &CycleInput<'_>,
    ) -> Result<[f64; MAX_AXES], EvalError> {
        match self {
            Self::Position(m) => {
                let c = m.evaluate(input)?;
                let mut error_um = [0.0; MAX_AXES];
                error_um[..c.axis_count()].copy_from_slice(c.error_um());
                Ok(error_um)
            }
            Self::Filtered(d) => d.step(dt_s, input),
        }
    }

    /// [`Self::step`] with the model's training envelope applied, when it has one
    /// ([`crate::envelope`]): the inputs clamped to their widened training ranges (into
    /// `scratch`, temperatures and operating inputs) and each axis' error capped. Returns the
    /// error per axis and the input farthest beyond the envelope. Allocates nothing once the
    /// scratch holds the machine's channels.
    pub fn step_guarded(
        &mut self,
        dt_s: f64,
        input: &CycleInput<'_>,
        (t, o): (&mut Vec<f64>, &mut Vec<f64>),
    ) -> Result<([f64; MAX_AXES], Option<Beyond>), EvalError> {
        let beyond = match self.envelope() {
            None => return self.step(dt_s, input).map(|e| (e, None)),
            Some(env) => {
                t.clear();
                t.resize(input.temperatures_c.len(), 0.0);
                o.clear();
                o.resize(input.operating.len(), 0.0);
                env.clamp(input, t, o)
            }
        };
        let guarded = CycleInput {
            temperatures_c: t,
            positions: input.positions,
            operating: o,
        };
        let mut error_um = self.step(dt_s, &guarded)?;
        if let Some(env) = self.envelope() {
            env.cap(&mut error_um);
        }
        Ok((error_um, beyond))
    }

    /// Forgets a dynamic model's history (nothing for a static model).
    pub fn reset(&mut self) {
        if let Self::Filtered(d) = self {
            d.reset();
        }
    }
}
