//! One model on a recorded run, row by row, whatever its form: seed A/C's model file evaluated
//! afresh each row, or a fitted dynamic model stepped through the rows in order (as the control
//! steps it every cycle). Shared by `truepos eval` and `truepos report`.

use truepos_io::cycles;
use truepos_io::dynamic_model_file::{self, BoundDynamicModel, MachineInput};
use truepos_io::model_file;
use truepos_model::{CycleInput, Machine, Model, MAX_AXES};

/// What evaluates a row: a static model, or a dynamic one stepped through the rows in order.
pub enum Evaluator {
    /// Seed A/C's form.
    Static(Box<Model>),
    /// A fitted dynamic model and its stepping state.
    Dynamic {
        /// The model bound to the machine.
        bound: Box<BoundDynamicModel>,
        /// Input buffer.
        input: Vec<f64>,
        /// Time of the last good step.
        last_s: Option<f64>,
    },
}

impl Evaluator {
    /// Reads a model file of either form, bound to the machine.
    pub fn load(path: &std::path::Path, machine: &Machine) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if dynamic_model_file::is_dynamic(&text) {
            let bound = dynamic_model_file::load(path, machine).map_err(|e| e.to_string())?;
            for name in &bound.unused_outputs {
                eprintln!("note: output `{name}` of the model names no axis and is not applied");
            }
            return Ok(Self::Dynamic {
                input: vec![0.0; bound.inputs.len()],
                bound: Box::new(bound),
                last_s: None,
            });
        }
        Ok(Self::Static(Box::new(
            model_file::load(path, machine).map_err(|e| e.to_string())?,
        )))
    }

    /// The model's name.
    pub fn name(&self) -> &str {
        match self {
            Self::Static(m) => m.name(),
            Self::Dynamic { bound, .. } => &bound.name,
        }
    }

    /// Reads a run for it: the sensors it reads must be there, the axis positions only if it
    /// reads them (a fitted dynamic model does not).
    pub fn load_run(
        &self,
        path: &std::path::Path,
        machine: &Machine,
    ) -> Result<cycles::Cycles, String> {
        let positions = match self {
            Self::Static(_) => cycles::Positions::Required,
            Self::Dynamic { .. } => cycles::Positions::Optional,
        };
        cycles::load_with(path, machine, &self.used_sensors(), positions).map_err(|e| e.to_string())
    }

    /// Temperature channels it reads.
    pub fn used_sensors(&self) -> Vec<usize> {
        match self {
            Self::Static(m) => m.used_sensors().to_vec(),
            Self::Dynamic { bound, .. } => bound.temperature_channels(),
        }
    }

    /// Axes it gives an error for.
    pub fn axis_count(&self, machine: &Machine) -> usize {
        match self {
            Self::Static(m) => m.axis_count(),
            Self::Dynamic { .. } => machine.axes.len(),
        }
    }

    /// The predicted error of every axis at row `i` (rows must come in order).
    pub fn error_um(
        &mut self,
        cycles: &cycles::Cycles,
        i: usize,
        machine: &Machine,
    ) -> Result<[f64; MAX_AXES], String> {
        match self {
            Self::Static(model) => {
                let input = CycleInput {
                    temperatures_c: &cycles.temperatures_c[i],
                    positions: &cycles.positions[i],
                    operating: &cycles.operating[i],
                };
                let c = model.evaluate(&input).map_err(|e| describe(&e, machine))?;
                let mut out = [0.0; MAX_AXES];
                out[..c.axis_count()].copy_from_slice(&c.error_um()[..c.axis_count()]);
                Ok(out)
            }
            Self::Dynamic {
                bound,
                input,
                last_s,
            } => {
                for (slot, m) in input.iter_mut().zip(&bound.inputs) {
                    *slot = match *m {
                        MachineInput::Temperature(c) => cycles.temperatures_c[i][c],
                        MachineInput::Operating(c) => cycles.operating[i][c],
                    };
                }
                if let Some(k) = input.iter().position(|v| !v.is_finite()) {
                    let name = match bound.inputs[k] {
                        MachineInput::Temperature(c) => &machine.temperatures[c].id,
                        MachineInput::Operating(c) => &machine.operating[c].id,
                    };
                    return Err(format!("input `{name}` is not a number"));
                }
                let t = cycles.time_s[i];
                let dt = last_s.map_or(0.0, |l| t - l);
                let out = bound.model.step(dt, input).map_err(|e| e.to_string())?;
                *last_s = Some(t);
                let mut errors = [0.0; MAX_AXES];
                for (e, axis) in out.iter().zip(&bound.axes) {
                    if let Some(a) = axis.filter(|&a| a < MAX_AXES) {
                        errors[a] = *e;
                    }
                }
                Ok(errors)
            }
        }
    }
}

/// An evaluation error with channel names instead of indices.
fn describe(e: &truepos_model::EvalError, machine: &Machine) -> String {
    use truepos_model::EvalError as E;
    let sensor = |c: usize| machine.temperatures.get(c).map_or("?", |t| t.id.as_str());
    let axis = |a: usize| machine.axes.get(a).map_or("?", |x| x.name.as_str());
    match *e {
        E::NonFiniteTemperature { channel } => {
            format!("temperature `{}` is not a number", sensor(channel))
        }
        E::TemperatureOutOfRange { channel, value } => {
            let t = &machine.temperatures[channel];
            format!(
                "temperature `{}` reads {value} °C, outside its valid range [{}, {}]",
                t.id, t.valid_min_c, t.valid_max_c
            )
        }
        E::NonFinitePosition { axis: a } => {
            format!("position of axis `{}` is not a number", axis(a))
        }
        E::PositionOutsideTravel { axis: a, value } => {
            let x = &machine.axes[a];
            format!(
                "position {value} of axis `{}` is outside its travel [{}, {}]",
                x.name, x.travel_min, x.travel_max
            )
        }
        E::NonFiniteResult { axis: a } => {
            format!(
                "the correction of axis `{}` is not a finite number",
                axis(a)
            )
        }
        E::InputLength { .. } => e.to_string(),
    }
}
