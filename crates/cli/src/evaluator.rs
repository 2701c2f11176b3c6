//! What is CLI-specific about running a model on a recorded run (`truepos eval`, `truepos
//! report`): loading through the one door (`truepos_io::model_file`), reading the run with the
//! columns the model needs, stepping the model through the rows in order with the time between
//! them (as the control steps it every cycle), and naming channels in errors.

use std::path::PathBuf;

use crate::error::CliError;
use crate::shape::ShapeArgs;
use truepos_io::{cycles, machine_file, model_file};
use truepos_model::config::MachineConfig;
use truepos_model::{CompensationModel, CycleInput, Machine, MAX_AXES};

/// A model on a recorded run, as `truepos export` and `truepos report` name them (flattened
/// into their arguments).
#[derive(clap::Args)]
pub struct ModelOnRun {
    /// Machine description (TOML).
    #[arg(long)]
    pub machine: PathBuf,
    /// Model file: a position-dependent thermal model or a reference-sensor regression
    /// (TOML/JSON), or a fitted dynamic model (JSON).
    #[arg(long)]
    pub model: PathBuf,
    /// Run CSV (or workbook) with the model's inputs (for `report`, and the measured errors; a
    /// dynamic model's filters run through it).
    #[arg(long)]
    pub run: PathBuf,
    /// The time column: seconds or ISO 8601 date-times. Default: `time_s` if there is one,
    /// else the row number.
    #[arg(long, conflicts_with = "sample_period")]
    pub time: Option<String>,
    #[command(flatten)]
    pub shape: ShapeArgs,
}

/// A run file's runs, each with its name.
pub type Runs = Vec<(String, cycles::Cycles)>;

impl ModelOnRun {
    /// The machine's configuration, the model bound to it and the run file's runs.
    pub fn load(&self) -> Result<(MachineConfig, Evaluator, Runs), CliError> {
        let config = machine_file::load(&self.machine)?;
        let model = Evaluator::load(&self.model, &config.machine)?;
        let runs = model.load_runs(
            &self.run,
            &config.machine,
            &self.shape,
            self.time.as_deref(),
        )?;
        Ok((config, model, runs))
    }
}

/// A model and the time of its last good step on a run.
pub struct Evaluator {
    model: CompensationModel,
    last_s: Option<f64>,
    /// The inputs clamped to the model's training envelope, as the service does.
    scratch: (Vec<f64>, Vec<f64>),
    /// Rows evaluated beyond the training envelope so far.
    beyond: usize,
}

impl Evaluator {
    /// Reads a model file of either form, bound to the machine.
    pub fn load(path: &std::path::Path, machine: &Machine) -> Result<Self, CliError> {
        let loaded = model_file::load(path, machine)?;
        if let Some(d) = loaded.model.as_dynamic() {
            for name in d.unused_outputs() {
                eprintln!("note: output `{name}` of the model names no axis and is not applied");
            }
        }
        Ok(Self {
            model: loaded.model,
            last_s: None,
            scratch: (Vec::new(), Vec::new()),
            beyond: 0,
        })
    }

    /// The model.
    pub fn model(&self) -> &CompensationModel {
        &self.model
    }

    /// The model's name.
    pub fn name(&self) -> &str {
        self.model.name()
    }

    /// Whether a run must hold the axis positions: only if the model reads them (a fitted
    /// dynamic model does not).
    fn positions(&self) -> cycles::Positions {
        if self.model.reads_positions() {
            cycles::Positions::Required
        } else {
            cycles::Positions::Optional
        }
    }

    /// Reads every run of a run file laid out as `shape` says, each with its name (the value of
    /// the run column, else the file and sheet): the sensors the model reads must be there.
    pub fn load_runs(
        &self,
        path: &std::path::Path,
        machine: &Machine,
        shape: &ShapeArgs,
        time: Option<&str>,
    ) -> Result<Runs, CliError> {
        let options = cycles::Options {
            positions: self.positions(),
            shape: shape.shape(),
            time: shape.time(time),
        };
        Ok(cycles::load_runs(
            path,
            machine,
            self.model.used_sensors(),
            &options,
        )?)
    }

    /// Starts the model afresh for the next run: its filters from that run's first row.
    pub fn restart(&mut self) {
        self.model.reset();
        self.last_s = None;
    }

    /// Rows evaluated so far with an input beyond the model's training envelope (clamped,
    /// the output capped, as on the machine).
    pub fn rows_beyond(&self) -> usize {
        self.beyond
    }

    /// Axes it gives an error for.
    pub fn axis_count(&self) -> usize {
        self.model.axis_count()
    }

    /// The predicted error of every axis at row `i` (rows must come in order): one step of the
    /// model over the time since its last good row.
    pub fn error_um(
        &mut self,
        cycles: &cycles::Cycles,
        i: usize,
        machine: &Machine,
    ) -> Result<[f64; MAX_AXES], CliError> {
        let input = CycleInput {
            temperatures_c: &cycles.run.temperatures_c[i],
            positions: &cycles.run.positions[i],
            operating: &cycles.run.operating[i],
        };
        let t = cycles.run.time_s[i];
        let dt = self.last_s.map_or(0.0, |l| t - l);
        let (t_scratch, o_scratch) = &mut self.scratch;
        let (error_um, beyond) = self
            .model
            .step_guarded(dt, &input, (t_scratch, o_scratch))
            .map_err(|e| CliError::Model(describe(&e, machine)))?;
        self.beyond += usize::from(beyond.is_some());
        self.last_s = Some(t);
        Ok(error_um)
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
        E::NonFiniteOperating { channel } => format!(
            "operating input `{}` is not a number",
            machine
                .operating
                .get(channel)
                .map_or("?", |o| o.id.as_str())
        ),
        E::InputLength { .. } | E::Filter(_) => e.to_string(),
    }
}
