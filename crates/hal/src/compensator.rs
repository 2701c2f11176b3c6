//! The cycle the component runs until the runtime's full service takes over: evaluate the
//! selected model, hold and ramp on a fault, and keep every offset inside the machine file's
//! safety envelope (largest magnitude, largest rate). The rate limit also makes enabling,
//! disabling and switching models bumpless: the output walks to its new value at no more than
//! the envelope's rate.

use truepos_io::machine_file::AxisRuntime;
use truepos_model::{CycleInput, EvalError, Model, MAX_AXES};
use truepos_runtime::{CompensationState, Frame, Output};

/// Something the operator should know about, raised on the cycle without allocating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// An input the model reads is bad: the last good offsets are held and ramped to zero.
    Fault {
        /// Service time in s.
        time_s: f64,
        /// What is wrong (names the channel by index).
        error: EvalError,
    },
    /// Inputs are good again: compensation resumes (rate-limited from the held value).
    Recovered {
        /// Service time in s.
        time_s: f64,
    },
    /// Another model was selected.
    ModelSwitch {
        /// Service time in s.
        time_s: f64,
        /// Previous model (index of `--model`).
        from: usize,
        /// New model.
        to: usize,
    },
    /// `truepos.model-select` names no loaded model; the current one stays.
    NoSuchModel {
        /// Service time in s.
        time_s: f64,
        /// The requested index.
        requested: i32,
    },
    /// The envelope limited an axis (raised when limiting starts, not every cycle).
    Clamped {
        /// Service time in s.
        time_s: f64,
        /// Axis index.
        axis: usize,
        /// The offset wanted, µm.
        wanted_um: f64,
        /// The offset sent, µm.
        sent_um: f64,
    },
    /// Compensation was switched on or off.
    Enabled {
        /// Service time in s.
        time_s: f64,
        /// The new state.
        on: bool,
    },
}

/// Settings of the interim cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensatorConfig {
    /// Envelope per machine axis (from the machine file).
    pub limits: Vec<AxisRuntime>,
    /// Time over which held offsets ramp to zero after a fault, s.
    pub hold_ramp_s: f64,
    /// Nominal cycle period, s. The rate limit allows rate × min(elapsed, period) per cycle, so
    /// a cycle that comes late (the scheduler stalled the process) does not catch up in one step:
    /// over any time T the offset moves at most rate × (T + period).
    pub period_s: f64,
}

/// The interim cycle: models → hold/ramp → envelope.
#[derive(Debug)]
pub struct Compensator {
    models: Vec<Model>,
    config: CompensatorConfig,
    active: usize,
    enabled: bool,
    out: [f64; MAX_AXES],
    held: [f64; MAX_AXES],
    hold_since: Option<f64>,
    last_time: Option<f64>,
    clamping: [bool; MAX_AXES],
    bad_select: i32,
}

impl Compensator {
    /// A cycle over `models` (at least one, all for the same machine), starting with model 0,
    /// enabled, with every offset at zero.
    pub fn new(models: Vec<Model>, config: CompensatorConfig) -> Self {
        Self {
            models,
            config,
            active: 0,
            enabled: true,
            out: [0.0; MAX_AXES],
            held: [0.0; MAX_AXES],
            hold_since: None,
            last_time: None,
            clamping: [false; MAX_AXES],
            bad_select: -1,
        }
    }

    /// The model in use (index of the list given to [`Compensator::new`]).
    pub fn active_model(&self) -> usize {
        self.active
    }

    /// Makes the offsets currently in force `offsets_um` (what the control applies when it
    /// starts accepting offsets), so that the next cycles walk from there at the envelope's rate.
    pub fn restart_from(&mut self, offsets_um: &[f64]) {
        for (o, &v) in self.out.iter_mut().zip(offsets_um) {
            *o = if v.is_finite() { v } else { 0.0 };
        }
    }

    /// One cycle on `frame` (its `time_s` is the service clock). `enabled` and `select` come
    /// from the control pins. Allocates nothing.
    pub fn step(
        &mut self,
        frame: &Frame,
        enabled: bool,
        select: i32,
        mut event: impl FnMut(Event),
    ) -> Output {
        let t = frame.time_s;
        let axes = self
            .models
            .first()
            .map_or(0, Model::axis_count)
            .min(MAX_AXES);
        // A stalled or jumping clock must not open the rate limit: at most 0.1 s per cycle.
        let dt = self
            .last_time
            .map_or(0.0, |last| (t - last).clamp(0.0, 0.1));
        self.last_time = Some(t);

        if select != self.active as i32 {
            if select >= 0 && (select as usize) < self.models.len() {
                event(Event::ModelSwitch {
                    time_s: t,
                    from: self.active,
                    to: select as usize,
                });
                self.active = select as usize;
                self.bad_select = -1;
            } else if select != self.bad_select {
                event(Event::NoSuchModel {
                    time_s: t,
                    requested: select,
                });
                self.bad_select = select;
            }
        }
        if enabled != self.enabled {
            event(Event::Enabled {
                time_s: t,
                on: enabled,
            });
            self.enabled = enabled;
        }

        let mut target = [0.0; MAX_AXES];
        let state = if !enabled {
            CompensationState::Disabled
        } else {
            let input = CycleInput {
                temperatures_c: &frame.temperatures_c,
                positions: &frame.positions,
                operating: &frame.operating,
            };
            match self.models[self.active].evaluate(&input) {
                Ok(correction) => {
                    if self.hold_since.take().is_some() {
                        event(Event::Recovered { time_s: t });
                    }
                    for (a, slot) in target.iter_mut().enumerate().take(axes) {
                        *slot = correction.compensation_um(a);
                    }
                    self.held = target;
                    CompensationState::Active
                }
                Err(error) => {
                    let since = *self.hold_since.get_or_insert_with(|| {
                        event(Event::Fault { time_s: t, error });
                        t
                    });
                    let keep = if self.config.hold_ramp_s > 0.0 {
                        (1.0 - (t - since) / self.config.hold_ramp_s).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    for (t, h) in target.iter_mut().zip(&self.held).take(axes) {
                        *t = h * keep;
                    }
                    CompensationState::Holding
                }
            }
        };

        let mut output = Output::zero(axes);
        output.time_s = t;
        output.state = state;
        #[allow(clippy::needless_range_loop)] // `a` indexes five arrays and the limits
        for a in 0..axes {
            let (max_abs, max_rate) = self
                .config
                .limits
                .get(a)
                .map_or((0.0, 0.0), |l| (l.max_offset_um, l.max_rate_um_per_s));
            let wanted = target[a];
            let bounded = wanted.clamp(-max_abs, max_abs);
            let step = max_rate * dt.min(self.config.period_s);
            let next = bounded.clamp(self.out[a] - step, self.out[a] + step);
            // Limiting a model's value (not the walk to zero or to a new model after a switch,
            // which is the intended bumpless transition) is what the operator must hear about.
            let limited = state == CompensationState::Active && (next - wanted).abs() > 1e-9;
            if limited && !self.clamping[a] && bounded != wanted {
                event(Event::Clamped {
                    time_s: t,
                    axis: a,
                    wanted_um: wanted,
                    sent_um: next,
                });
            }
            self.clamping[a] = limited && bounded != wanted;
            output.clamped |= self.clamping[a];
            self.out[a] = next;
            output.offset_um[a] = next;
            output.positions[a] = frame.positions.get(a).copied().unwrap_or(0.0);
        }
        output
    }
}
