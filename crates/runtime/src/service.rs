//! The cycle: sources → validation → model set → evaluation → safety envelope → sinks.
//!
//! [`Service::cycle`] runs one control cycle. It allocates nothing, takes no lock and does no
//! I/O of its own (sources and sinks promise the same); events and log records leave through
//! lock-free queues that the logger thread drains.

use std::sync::Arc;

use crossbeam_queue::ArrayQueue;
use truepos_model::envelope::Beyond;
use truepos_model::{CycleInput, LagFilters, MachineInput, MAX_AXES};

use crate::config::MachineConfig;
use crate::envelope::Envelope;
use crate::events::{Event, EventKind, EventQueue, Reason};
use crate::frame::{Frame, NEVER};
use crate::io_traits::{LinkError, Sink, Source};
use crate::model_set::{ModelEntry, ModelSet};
use crate::output::{CompensationState, Output};
use crate::probe::{self, ProbeRecord};
use crate::sensor_validation::SensorValidator;

/// Most temperature channels a log record carries.
pub const MAX_LOG_TEMPERATURES: usize = 64;
/// Most operating channels a log record carries.
pub const MAX_LOG_OPERATING: usize = 16;
/// Most paths.
pub const MAX_PATHS: usize = 4;

/// Settings of the cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceConfig {
    /// Blend time in s for model switches and for switching compensation on or off.
    pub blend_s: f64,
    /// Time in s over which a held compensation ramps to zero when no valid model is left.
    pub hold_ramp_s: f64,
    /// Oldest usable axis position in s (the control's feedback must be current).
    pub position_max_age_s: f64,
    /// Interval in s between cycle records sent to the log (events are always logged).
    pub log_every_s: f64,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        Self {
            blend_s: 5.0,
            hold_ramp_s: 60.0,
            position_max_age_s: 0.5,
            log_every_s: 0.1,
        }
    }
}

/// What a path is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathState {
    /// Compensating with this model of the set.
    Model(usize),
    /// Holding the last compensation and ramping it to zero.
    Holding,
    /// No model matches the path's axis combination.
    NoModel,
    /// Compensation is off.
    Disabled,
}

/// How a sink is doing: whether it fails now, and whether it ever failed in this run (so the
/// end of a run can say so even after it recovered).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SinkHealth {
    /// Service time since which the sink fails (`None`: it takes the output).
    pub failing_since_s: Option<f64>,
    /// Why it failed last.
    pub reason: Reason,
    /// Cycles whose output the sink did not take.
    pub failed_writes: u64,
    /// Service time of the first failure in this run.
    pub first_failure_s: Option<f64>,
}

/// Where an axis' target comes from. A change of origin restarts the axis' blend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Origin {
    /// Zero: compensation off, no model, or the axis is in no path.
    Zero,
    /// A model of the set, evaluated for a path.
    Model { path: usize, model: usize },
    /// The output held when a path lost its inputs, ramping to zero.
    Hold { path: usize },
}

/// One cycle as the log keeps it (fixed size, so queuing it allocates nothing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleRecord {
    /// Service time in s.
    pub time_s: f64,
    /// Overall state.
    pub state: CompensationState,
    /// Axis positions.
    pub positions: [f64; MAX_AXES],
    /// Offsets sent (µm).
    pub offsets_um: [f64; MAX_AXES],
    /// What the offsets blend towards (µm): the model's value, or zero while holding or
    /// disabled; it differs from the offset during a blend and by a clamp.
    pub targets_um: [f64; MAX_AXES],
    /// Temperatures (first [`MAX_LOG_TEMPERATURES`] channels).
    pub temperatures_c: [f64; MAX_LOG_TEMPERATURES],
    /// Operating state (first [`MAX_LOG_OPERATING`] channels).
    pub operating: [f64; MAX_LOG_OPERATING],
    /// Model per path (−1: none).
    pub model_per_path: [i32; MAX_PATHS],
}

/// The cyclic compensation service.
pub struct Service {
    machine: MachineConfig,
    config: ServiceConfig,
    set: ModelSet,
    validator: SensorValidator,
    /// Lagged temperature channels, computed after validation.
    lags: LagFilters,
    /// Service time of the last lag update (NaN before the first).
    lags_time_s: f64,
    envelope: Envelope,
    sources: Vec<Box<dyn Source>>,
    sinks: Vec<Box<dyn Sink>>,
    source_ok: Vec<bool>,
    /// Per source, the reason of its current failure (empty while it delivers).
    source_reason: Vec<Reason>,
    sink_health: Vec<SinkHealth>,
    finished: bool,
    frame: Frame,
    configured_paths: Vec<Vec<usize>>,
    selected_once: bool,
    output: Output,
    events: Arc<EventQueue>,
    records: Arc<ArrayQueue<CycleRecord>>,
    records_dropped: u64,
    probes: Arc<ArrayQueue<ProbeRecord>>,
    probes_dropped: u64,
    enabled: bool,
    codes: Vec<u32>,
    states: Vec<PathState>,
    /// Per path: the input its model is extrapolating on now (beyond its training envelope).
    extrapolating: Vec<Option<MachineInput>>,
    preferred: Vec<Option<usize>>,
    axis_path: [Option<usize>; MAX_AXES],
    /// Per axis: where its target comes from, and the target of this cycle.
    origin: [Origin; MAX_AXES],
    target: [f64; MAX_AXES],
    hold_from: [f64; MAX_AXES],
    hold_start: [f64; MAX_AXES],
    positions_ok: bool,
    position_fault_seen: bool,
    last_log: f64,
    cycles: u64,
}

impl Service {
    /// A service for a machine and a model set. The initial axis configuration groups the axes
    /// by the `path` of the machine file, ordered by `number`; a control source may change it.
    pub fn new(
        machine: MachineConfig,
        models: Vec<ModelEntry>,
        sources: Vec<Box<dyn Source>>,
        sinks: Vec<Box<dyn Sink>>,
        config: ServiceConfig,
    ) -> Self {
        let m = &machine.machine;
        let codes: Vec<u32> = machine.axes.iter().map(|a| a.code()).collect();
        let max_path = machine
            .axes
            .iter()
            .map(|a| a.path as usize)
            .max()
            .unwrap_or(1)
            .clamp(1, MAX_PATHS);
        let mut paths: Vec<Vec<usize>> = (1..=max_path)
            .map(|p| {
                let mut axes: Vec<usize> = (0..m.axes.len())
                    .filter(|&a| machine.axes[a].path as usize == p)
                    .collect();
                axes.sort_by_key(|&a| machine.axes[a].number);
                axes
            })
            .collect();
        // Room for axis switching without allocating on the cycle.
        for p in &mut paths {
            p.reserve(m.axes.len());
        }
        let mut frame = Frame::new(m.temperatures.len(), m.axes.len(), m.operating.len());
        frame.paths = paths.clone();
        let n_paths = paths.len();
        let set = ModelSet::new(models, n_paths);
        Self {
            validator: SensorValidator::new(m, &machine.sensor_checks),
            lags: LagFilters::new(m),
            lags_time_s: f64::NAN,
            envelope: Envelope::new(&machine.axes),
            output: Output::zero(m.axes.len()),
            source_ok: vec![true; sources.len()],
            source_reason: vec![Reason::EMPTY; sources.len()],
            sink_health: vec![SinkHealth::default(); sinks.len()],
            sources,
            sinks,
            finished: false,
            frame,
            configured_paths: (0..n_paths)
                .map(|_| Vec::with_capacity(m.axes.len()))
                .collect(),
            selected_once: false,
            events: Arc::new(EventQueue::new(1 << 16)),
            records: Arc::new(ArrayQueue::new(1 << 14)),
            records_dropped: 0,
            probes: Arc::new(ArrayQueue::new(1 << 8)),
            probes_dropped: 0,
            enabled: true,
            codes,
            states: vec![PathState::Disabled; n_paths],
            extrapolating: vec![None; n_paths],
            preferred: vec![None; n_paths],
            axis_path: [None; MAX_AXES],
            origin: [Origin::Zero; MAX_AXES],
            target: [0.0; MAX_AXES],
            hold_from: [0.0; MAX_AXES],
            hold_start: [0.0; MAX_AXES],
            positions_ok: false,
            position_fault_seen: false,
            last_log: NEVER,
            cycles: 0,
            set,
            config,
            machine,
        }
    }

    /// Number of sources.
    pub fn source_count(&self) -> usize {
        self.sources.len()
    }

    /// Why source `i` does not deliver, as its latest `SourceLost` event said; `None` while it
    /// delivers (or for an index out of range). For the status line.
    pub fn source_reason(&self, i: usize) -> Option<&str> {
        match (self.source_ok.get(i), self.source_reason.get(i)) {
            (Some(false), Some(r)) => Some(r.as_str()),
            _ => None,
        }
    }

    /// The queue of events, for the logger.
    pub fn events(&self) -> Arc<EventQueue> {
        Arc::clone(&self.events)
    }

    /// The queue of cycle records, for the logger.
    pub fn records(&self) -> Arc<ArrayQueue<CycleRecord>> {
        Arc::clone(&self.records)
    }

    /// The queue of probe events, for the logger.
    pub fn probes(&self) -> Arc<ArrayQueue<ProbeRecord>> {
        Arc::clone(&self.probes)
    }

    /// Probe events dropped because the logger fell behind.
    pub fn probes_dropped(&self) -> u64 {
        self.probes_dropped
    }

    /// The machine.
    pub fn machine(&self) -> &MachineConfig {
        &self.machine
    }

    /// The model set.
    pub fn model_set(&self) -> &ModelSet {
        &self.set
    }

    /// The last output.
    pub fn output(&self) -> &Output {
        &self.output
    }

    /// The frame of the last cycle.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// What each path is doing.
    pub fn path_states(&self) -> &[PathState] {
        &self.states
    }

    /// The validator (sensor health).
    pub fn validator(&self) -> &SensorValidator {
        &self.validator
    }

    /// Whether a source has said it has nothing more to give.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// How each sink is doing, in service order.
    pub fn sink_health(&self) -> &[SinkHealth] {
        &self.sink_health
    }

    /// The name of sink `i` (empty if there is none).
    pub fn sink_name(&self, i: usize) -> &str {
        self.sinks.get(i).map_or("", |s| s.name())
    }

    /// A sink that drives the axes and fails now, if any: the offsets no longer reach the
    /// axes and the run must stop with an alarm; a failing recording sink does not stop it.
    pub fn axes_unreachable(&self) -> Option<usize> {
        self.sink_health
            .iter()
            .zip(&self.sinks)
            .position(|(h, s)| h.failing_since_s.is_some() && s.drives_axes())
    }

    /// This cycle's target per axis: the compensation its origin asks for (a model's value, a
    /// held value or zero), before blending and the envelope.
    pub fn targets(&self) -> &[f64] {
        &self.target[..self.output.axes]
    }

    /// The safety envelope (blends and clamps per axis).
    pub fn envelope(&self) -> &Envelope {
        &self.envelope
    }

    /// Per path, whether its model is extrapolating now (beyond its training envelope).
    pub fn path_extrapolating(&self, path: usize) -> bool {
        self.extrapolating.get(path).is_some_and(Option::is_some)
    }

    /// Events dropped because the event queue was full.
    pub fn events_dropped(&self) -> u64 {
        self.events.dropped()
    }

    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// Cycle records dropped because the logger fell behind.
    pub fn records_dropped(&self) -> u64 {
        self.records_dropped
    }

    /// Switches compensation on or off; the output blends to the new value (bumpless).
    pub fn set_enabled(&mut self, enabled: bool) {
        if enabled != self.enabled {
            self.enabled = enabled;
            self.events.push(Event {
                time_s: self.frame.time_s,
                kind: EventKind::Enabled(enabled),
            });
        }
    }

    /// Prefers a model of the set for a path (0-based) when it matches and its sensors are
    /// good; `None` returns to the set's order. The switch blends (bumpless).
    pub fn prefer_model(&mut self, path: usize, model: Option<usize>) {
        if let Some(p) = self.preferred.get_mut(path) {
            *p = model;
        }
    }

    /// Replaces model `i` of the set by a reloaded one, between cycles, without a restart: an axis
    /// whose output comes from model `i` restarts its one blend from the output last sent, exactly
    /// as on a change of origin, so the new model blends in through the envelope. The new model
    /// must serve the same axis combination (axis-combination index) and give as many axes;
    /// otherwise nothing changes and the error says why. Returns the model replaced, for the caller
    /// to drop off the cycle.
    pub fn replace_model(&mut self, i: usize, entry: ModelEntry) -> Result<ModelEntry, String> {
        let Some(old) = self.set.entries().get(i) else {
            return Err(format!(
                "the model set has {} models, no model #{}",
                self.set.entries().len(),
                i + 1
            ));
        };
        if entry.index != old.index {
            return Err(format!(
                "it serves the axis combination {:?}, the model it replaces (`{}`) {:?}",
                entry.index, old.name, old.index
            ));
        }
        if entry.model.axis_count() != old.model.axis_count() {
            return Err(format!(
                "it gives offsets for {} axes, the model it replaces (`{}`) for {}",
                entry.model.axis_count(),
                old.name,
                old.model.axis_count()
            ));
        }
        let Some(old) = self.set.replace(i, entry) else {
            return Err(format!("no model #{}", i + 1));
        };
        let now_s = self.frame.time_s;
        for a in 0..self.output.axes {
            if matches!(self.origin[a], Origin::Model { model, .. } if model == i) {
                self.envelope.restart_blend(a, now_s, self.config.blend_s);
            }
        }
        Ok(old)
    }

    /// Runs one cycle at service time `now_s` and returns its output.
    pub fn cycle(&mut self, now_s: f64) -> &Output {
        self.cycles += 1;
        self.frame.time_s = now_s;
        self.read_sources(now_s);
        self.validator.check(&self.frame, &self.events);
        self.update_lags(now_s);
        self.step_dynamic_models(now_s);
        self.check_positions(now_s);
        self.select_models(now_s);
        for p in 0..self.states.len() {
            self.update_path(p, now_s);
        }
        self.update_free_axes(now_s);
        self.record_probe(now_s);
        let n = self.output.axes;
        let clamped = self.envelope.apply(
            &self.target[..n],
            now_s,
            &mut self.output.offset_um[..n],
            &self.events,
        );
        self.output.time_s = now_s;
        self.output.clamped = clamped;
        self.output.extrapolating = self.extrapolating();
        self.output.state = self.overall_state();
        for (a, p) in self.output.positions[..n].iter_mut().enumerate() {
            *p = self.frame.positions[a];
        }
        self.write_sinks(now_s);
        self.log_cycle(now_s);
        &self.output
    }

    /// Computes the lagged temperature channels from the sources the validation found good.
    fn update_lags(&mut self, now_s: f64) {
        if self.lags.is_empty() {
            return;
        }
        let dt = if self.lags_time_s.is_finite() {
            now_s - self.lags_time_s
        } else {
            0.0
        };
        self.lags_time_s = now_s;
        let validator = &self.validator;
        self.lags.apply_checked(
            dt,
            &mut self.frame.temperatures_c,
            &self.frame.operating,
            |c| validator.health().get(c).is_some_and(|h| h.is_none()),
        );
    }

    /// Advances the filters of every dynamic model, selected or not, from good inputs only.
    fn step_dynamic_models(&mut self, now_s: f64) {
        let validator = &self.validator;
        let frame = &self.frame;
        self.set
            .step_all(now_s, &frame.temperatures_c, &frame.operating, |c| {
                validator.health().get(c).is_some_and(|h| h.is_none())
            });
    }

    /// Reads every source; raises `SourceLost` when a source stops delivering or its reason
    /// changes while it stays lost, and `SourceBack` when it delivers again.
    fn read_sources(&mut self, now_s: f64) {
        for (i, s) in self.sources.iter_mut().enumerate() {
            let reason = match s.read(&mut self.frame) {
                Ok(()) => None,
                Err(LinkError::Finished) => {
                    self.finished = true;
                    None
                }
                Err(LinkError::Disconnected(why)) => Some(why),
                // Only sources that allocate anyway return `Failed`.
                Err(LinkError::Failed(why)) => Some(Reason::new(&why)),
            };
            let kind = match reason {
                None if !self.source_ok[i] => EventKind::SourceBack { source: i },
                Some(why) if self.source_ok[i] || why != self.source_reason[i] => {
                    EventKind::SourceLost {
                        source: i,
                        reason: why,
                    }
                }
                _ => continue,
            };
            self.source_ok[i] = reason.is_none();
            self.source_reason[i] = reason.unwrap_or(Reason::EMPTY);
            self.events.push(Event {
                time_s: now_s,
                kind,
            });
        }
    }

    /// A position fault: an axis position that is not finite, never came, is older than
    /// `position_max_age_s`, or is implausible (see [`plausible_position`]).
    fn check_positions(&mut self, now_s: f64) {
        let mut bad = None;
        for (a, (&p, &stamp)) in self
            .frame
            .positions
            .iter()
            .zip(&self.frame.position_stamp_s)
            .enumerate()
        {
            if !p.is_finite()
                || stamp == NEVER
                || now_s - stamp > self.config.position_max_age_s
                || !plausible_position(&self.machine.machine.axes[a], p)
            {
                bad = Some(a);
                break;
            }
        }
        let ok = bad.is_none();
        if ok != self.positions_ok {
            let kind = match bad {
                Some(axis) => EventKind::PositionFault { axis },
                None => EventKind::PositionRecovered,
            };
            // Positions arriving at start-up are not worth an event; their loss (which can only
            // follow a good state) and every recovery after a loss are.
            if !ok || self.position_fault_seen {
                self.events.push(Event {
                    time_s: now_s,
                    kind,
                });
            }
            self.position_fault_seen |= !ok;
            self.positions_ok = ok;
        }
    }

    fn select_models(&mut self, now_s: f64) {
        let same = (0..self.configured_paths.len()).all(|p| {
            self.frame.paths.get(p).map(Vec::as_slice).unwrap_or(&[])
                == self.configured_paths[p].as_slice()
        });
        if same && self.selected_once {
            return;
        }
        let first = !self.selected_once;
        self.selected_once = true;
        // Copied into reserved capacity: an axis switch allocates nothing.
        for (p, kept) in self.configured_paths.iter_mut().enumerate() {
            kept.clear();
            if let Some(axes) = self.frame.paths.get(p) {
                kept.extend_from_slice(axes);
            }
        }
        self.set.select(&self.frame.paths, &self.codes);
        self.axis_path = [None; MAX_AXES];
        for (p, axes) in self.frame.paths.iter().enumerate().take(self.states.len()) {
            for &a in axes {
                if a < MAX_AXES {
                    self.axis_path[a] = Some(p);
                }
            }
        }
        if !first {
            self.events.push(Event {
                time_s: now_s,
                kind: EventKind::AxisSwitch,
            });
        }
    }

    /// The state a path should be in now.
    fn wanted_state(&self, p: usize) -> PathState {
        if !self.enabled {
            return PathState::Disabled;
        }
        let candidates = self.set.candidates(p);
        if candidates.is_empty() {
            return PathState::NoModel;
        }
        if !self.positions_ok {
            return PathState::Holding;
        }
        let good = |&c: &usize| {
            self.validator
                .all_good(self.set.entries()[c].model.used_sensors())
        };
        if let Some(pref) = self.preferred[p] {
            if candidates.contains(&pref) && good(&pref) {
                return PathState::Model(pref);
            }
        }
        match candidates.iter().find(|c| good(c)) {
            Some(&c) => PathState::Model(c),
            None => PathState::Holding,
        }
    }

    /// The state path `p` takes this cycle, with the model's compensation in `fresh` when it is
    /// a model: a model that fails on this cycle's values (a position outside travel, a value
    /// that is not finite) is treated like a bad sensor.
    fn evaluate_path(&mut self, p: usize, fresh: &mut [f64; MAX_AXES]) -> PathState {
        let wanted = self.wanted_state(p);
        let PathState::Model(m) = wanted else {
            return wanted;
        };
        let input = CycleInput {
            temperatures_c: &self.frame.temperatures_c,
            positions: &self.frame.positions,
            operating: &self.frame.operating,
        };
        let ok = self.set.compensation(m, &input, fresh)
            && (0..self.output.axes)
                .filter(|&a| self.axis_path[a] == Some(p))
                .all(|a| fresh[a].is_finite());
        if ok {
            wanted
        } else {
            PathState::Holding
        }
    }

    /// Records a change of a path's state and raises its event.
    fn note_path_state(&mut self, p: usize, wanted: PathState, now_s: f64) {
        if wanted == self.states[p] {
            return;
        }
        self.states[p] = wanted;
        let path = p as u32 + 1;
        let kind = match wanted {
            PathState::Model(m) => {
                let first = self.set.candidates(p).first().copied();
                match first {
                    Some(f) if f != m && self.preferred[p] != Some(m) => {
                        EventKind::ModelSubstituted {
                            path,
                            from: f,
                            to: m,
                        }
                    }
                    _ => EventKind::ModelSelected { path, model: m },
                }
            }
            PathState::Holding => EventKind::Holding { path },
            PathState::NoModel => EventKind::NoModel {
                path,
                target: self.set.target(p),
            },
            // `set_enabled` raised it already.
            PathState::Disabled => return,
        };
        self.events.push(Event {
            time_s: now_s,
            kind,
        });
    }

    /// Raises `extrapolating` when path `p`'s model goes beyond its training envelope or the
    /// input farthest beyond changes, and `extrapolation-ended` when it is back inside.
    fn note_extrapolation(&mut self, p: usize, beyond: Option<Beyond>, now_s: f64) {
        let now = beyond.map(|b| b.input);
        if now == self.extrapolating[p] {
            return;
        }
        self.extrapolating[p] = now;
        let path = p as u32 + 1;
        let kind = match beyond {
            Some(b) => EventKind::Extrapolating {
                path,
                input: b.input,
                value: b.value,
                limit: b.limit,
            },
            None => EventKind::ExtrapolationEnded { path },
        };
        self.events.push(Event {
            time_s: now_s,
            kind,
        });
    }

    /// Whether any path's model is extrapolating now (beyond its training envelope).
    pub fn extrapolating(&self) -> bool {
        self.extrapolating.iter().any(Option::is_some)
    }

    fn update_path(&mut self, p: usize, now_s: f64) {
        let mut fresh = [0.0; MAX_AXES];
        let wanted = self.evaluate_path(p, &mut fresh);
        self.note_path_state(p, wanted, now_s);
        let beyond = match wanted {
            PathState::Model(m) => self.set.beyond(m),
            _ => None,
        };
        self.note_extrapolation(p, beyond, now_s);
        let origin = match wanted {
            PathState::Model(model) => Origin::Model { path: p, model },
            PathState::Holding => Origin::Hold { path: p },
            PathState::NoModel | PathState::Disabled => Origin::Zero,
        };
        for (a, &value) in fresh.iter().enumerate().take(self.output.axes) {
            if self.axis_path[a] != Some(p) {
                continue;
            }
            self.set_origin(a, origin, now_s);
            self.target[a] = match origin {
                Origin::Model { .. } => value,
                Origin::Hold { .. } => self.held(a, now_s),
                Origin::Zero => 0.0,
            };
        }
    }

    /// Axes outside every path (handed over or parked) go to zero.
    fn update_free_axes(&mut self, now_s: f64) {
        for a in 0..self.output.axes {
            if self.axis_path[a].is_none() {
                self.set_origin(a, Origin::Zero, now_s);
                self.target[a] = 0.0;
            }
        }
    }

    /// Changes where `axis`' target comes from. Any change restarts the axis' one blend from the
    /// output last sent; entering a hold takes that output as the value to hold.
    fn set_origin(&mut self, a: usize, origin: Origin, now_s: f64) {
        if origin == self.origin[a] {
            return;
        }
        self.origin[a] = origin;
        if let Origin::Hold { .. } = origin {
            self.hold_from[a] = self.envelope.last()[a];
            self.hold_start[a] = now_s;
        }
        self.envelope.restart_blend(a, now_s, self.config.blend_s);
    }

    /// The held value of `axis` now: the output when the hold began, ramped linearly to zero.
    fn held(&self, a: usize, now_s: f64) -> f64 {
        let left = if self.config.hold_ramp_s > 0.0 {
            (1.0 - (now_s - self.hold_start[a]) / self.config.hold_ramp_s).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.hold_from[a] * left
    }

    fn overall_state(&self) -> CompensationState {
        let all = |f: fn(&PathState) -> bool| self.states.iter().all(f);
        let any = |f: fn(&PathState) -> bool| self.states.iter().any(f);
        if all(|s| matches!(s, PathState::Model(_))) {
            CompensationState::Active
        } else if any(|s| *s == PathState::NoModel) {
            CompensationState::NoModel
        } else if any(|s| *s == PathState::Holding) {
            CompensationState::Holding
        } else {
            CompensationState::Disabled
        }
    }

    /// Writes the output to every sink; a failure is an event on the change (not one per
    /// cycle) and stays visible in [`Service::sink_health`]. Allocates nothing unless a sink
    /// does: the reason is copied into a fixed-size [`Reason`] once, when the sink fails.
    fn write_sinks(&mut self, now_s: f64) {
        for (i, s) in self.sinks.iter_mut().enumerate() {
            let h = &mut self.sink_health[i];
            let kind = match s.write_cycle(&self.output, &self.frame) {
                Ok(()) => match h.failing_since_s.take() {
                    Some(_) => EventKind::SinkBack { sink: i },
                    None => continue,
                },
                Err(e) => {
                    h.failed_writes += 1;
                    if h.failing_since_s.is_some() {
                        continue;
                    }
                    h.failing_since_s = Some(now_s);
                    h.first_failure_s.get_or_insert(now_s);
                    h.reason = match e {
                        LinkError::Disconnected(why) => why,
                        // Only sinks that allocate anyway (a file) return `Failed`.
                        LinkError::Failed(why) => Reason::new(&why),
                        LinkError::Finished => Reason::new("finished"),
                    };
                    EventKind::SinkFailed {
                        sink: i,
                        reason: h.reason,
                    }
                }
            };
            self.events.push(Event {
                time_s: now_s,
                kind,
            });
        }
    }

    /// Takes this cycle's probe event, if a source delivered one, checks it and queues it for
    /// the log with the inputs of the cycle and what the model in effect predicts at the
    /// probed position. Rejected (with the reason): a value out of bounds, or a temperature a
    /// model of the set reads that failed validation this cycle. Allocates nothing.
    fn record_probe(&mut self, now_s: f64) {
        let Some(p) = self.frame.probe.take() else {
            return;
        };
        let n = self.output.axes;
        let axes = &self.machine.machine.axes;
        let mut rejected = match probe::check(&p, axes) {
            Ok(()) => Reason::EMPTY,
            Err(why) => why,
        };
        if rejected.is_empty() {
            let health = self.validator.health();
            let bad = self
                .set
                .entries()
                .iter()
                .flat_map(|e| e.model.used_sensors())
                .find(|&&c| health.get(c).is_some_and(|h| h.is_some()));
            if let Some(&c) = bad {
                rejected = probe::reason(format_args!(
                    "temperature `{}` failed validation this cycle",
                    self.machine.machine.temperatures[c].id
                ));
            }
        }
        let mut r = ProbeRecord {
            time_s: now_s,
            rejected,
            probe: p,
            predicted_um: [f64::NAN; MAX_AXES],
            state: self.output.state,
            positions: [f64::NAN; MAX_AXES],
            temperatures_c: [f64::NAN; MAX_LOG_TEMPERATURES],
            operating: [f64::NAN; MAX_LOG_OPERATING],
            model_per_path: [-1; MAX_PATHS],
        };
        for (d, s) in r.positions.iter_mut().zip(&self.frame.positions) {
            *d = *s;
        }
        for (d, s) in r.temperatures_c.iter_mut().zip(&self.frame.temperatures_c) {
            *d = *s;
        }
        for (d, s) in r.operating.iter_mut().zip(&self.frame.operating) {
            *d = *s;
        }
        let input = CycleInput {
            temperatures_c: &self.frame.temperatures_c,
            positions: &p.position_mm[..n],
            operating: &self.frame.operating,
        };
        for (path, state) in self.states.iter().enumerate().take(MAX_PATHS) {
            let PathState::Model(m) = *state else {
                continue;
            };
            r.model_per_path[path] = m as i32;
            let mut comp = [f64::NAN; MAX_AXES];
            if !self.set.compensation(m, &input, &mut comp) {
                continue;
            }
            for a in (0..n).filter(|&a| self.axis_path[a] == Some(path)) {
                // The model predicts the error; its compensation is the opposite.
                r.predicted_um[a] = 0.0 - comp[a];
            }
        }
        if self.probes.push(r).is_err() {
            self.probes_dropped += 1;
        }
    }

    fn log_cycle(&mut self, now_s: f64) {
        if now_s - self.last_log < self.config.log_every_s {
            return;
        }
        self.last_log = now_s;
        let mut r = CycleRecord {
            time_s: now_s,
            state: self.output.state,
            positions: self.output.positions,
            offsets_um: self.output.offset_um,
            targets_um: self.target,
            temperatures_c: [f64::NAN; MAX_LOG_TEMPERATURES],
            operating: [f64::NAN; MAX_LOG_OPERATING],
            model_per_path: [-1; MAX_PATHS],
        };
        for (d, s) in r.temperatures_c.iter_mut().zip(&self.frame.temperatures_c) {
            *d = *s;
        }
        for (d, s) in r.operating.iter_mut().zip(&self.frame.operating) {
            *d = *s;
        }
        for (d, s) in r.model_per_path.iter_mut().zip(&self.states) {
            if let PathState::Model(m) = s {
                *d = *m as i32;
            }
        }
        if self.records.push(r).is_err() {
            self.records_dropped += 1;
        }
    }
}

/// Whether a position can come from the axis at all: within its travel widened by the travel's
/// own length on each side. A position beyond travel by less is the model's business (it holds
/// with the reason); one beyond that (1e308 from a retyped node, a wrong scale) is a faulty
/// position source.
fn plausible_position(axis: &truepos_model::Axis, p: f64) -> bool {
    let span = (axis.travel_max - axis.travel_min).abs();
    p >= axis.travel_min - span && p <= axis.travel_max + span
}
