//! The publication point of the live view: the latest state of the service, one slot, latest
//! wins, for readers on other threads (`truepos-live`'s HTTP server).
//!
//! The host's loop calls [`Board::publish`] between cycles (never inside
//! [`Service::cycle`](crate::Service::cycle)), at most every [`PUBLISH_EVERY`] of real time.
//! A publication is a sequence lock over a fixed number of atomics sized when the board is
//! made: it allocates nothing, takes no lock and never waits, whatever the readers do (a
//! reader that races a publication retries, or gives up and reads again later). Readers
//! ([`Board::read`]) allocate on their own thread only.

use std::sync::atomic::{fence, AtomicU64, Ordering};
use std::time::Instant;

mod work;
pub use work::{bucket_edge_us, quantile_us, WorkStats, MAX_SLOTS, PER_DOUBLING, WORK_BUCKETS};

use crate::frame::NEVER;
use crate::output::CompensationState;
use crate::sensor_validation::Fault;
use crate::service::{PathState, Service};

/// Fastest rate the host publishes at (real time): four times faster than the live view's
/// stream, so that each streamed point is at most this old.
pub const PUBLISH_EVERY: std::time::Duration = std::time::Duration::from_millis(50);

/// Cells before the per-axis ones.
const HEADER: usize = 15;
/// Cells per axis: offset, target, position, clamping, clamps, blending.
const PER_AXIS: usize = 6;
/// Cells per temperature channel: value, fault code, fault figure, age.
const PER_TEMPERATURE: usize = 4;
/// Cells per path: state code, extrapolating.
const PER_PATH: usize = 2;
/// Cells per source: delivers, service time it last delivered at.
const PER_SOURCE: usize = 2;
/// Cells per sink: failing, failed writes.
const PER_SINK: usize = 2;

/// How many of each thing the board holds (the machine's and the service's counts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Axes.
    pub axes: usize,
    /// Temperature channels.
    pub temperatures: usize,
    /// Operating channels.
    pub operating: usize,
    /// Paths.
    pub paths: usize,
    /// Sources.
    pub sources: usize,
    /// Sinks.
    pub sinks: usize,
    /// Models of the set.
    pub models: usize,
}

impl Layout {
    /// The layout of a service's state.
    pub fn of(service: &Service) -> Self {
        let m = &service.machine().machine;
        Self {
            axes: service.output().axes,
            temperatures: m.temperatures.len(),
            operating: m.operating.len(),
            paths: service.path_states().len(),
            sources: service.source_count(),
            sinks: service.sink_health().len(),
            models: service.model_set().entries().len(),
        }
    }

    fn cells(&self) -> usize {
        HEADER
            + PER_AXIS * self.axes
            + PER_TEMPERATURE * self.temperatures
            + self.operating
            + PER_PATH * self.paths
            + PER_SOURCE * self.sources
            + PER_SINK * self.sinks
            + self.models
    }
}

/// What the host knows beside the service, published with it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HostFigures<'a> {
    /// Cycles that finished later than one period after their deadline.
    pub late_cycles: u64,
    /// Work of the latest cycle in µs.
    pub cycle_work_us: f64,
    /// The log's health, if there is a log (the host reads it at its status rate: it takes the
    /// logger's lock, so never at the cycle's rate).
    pub log: Option<LogFigures>,
    /// Per model of the set, its generation (`Running::model_generations`).
    pub generations: &'a [u64],
}

/// The log's health as published.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LogFigures {
    /// Whether writing fails now.
    pub failing: bool,
    /// Records, events and probe events waiting in the logger's buffer.
    pub pending: u64,
    /// Records, events and probe events the logger dropped.
    pub dropped: u64,
}

/// A path's state as published.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathView {
    /// Compensating with this model of the set.
    Model(usize),
    /// Holding the last compensation and ramping it to zero.
    Holding,
    /// No model matches the path's axis combination.
    NoModel,
    /// Compensation is off.
    Disabled,
}

/// One axis as published.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisView {
    /// Offset sent, µm (µrad on a rotary axis).
    pub offset_um: f64,
    /// Target before blending and the envelope (the model's compensation, a held value or 0).
    pub target_um: f64,
    /// Position (mm or degrees).
    pub position: f64,
    /// Whether the envelope clamps the axis now.
    pub clamping: bool,
    /// Clamps since start.
    pub clamps: u64,
    /// Whether a blend is running.
    pub blending: bool,
}

/// One temperature channel as published.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TemperatureView {
    /// Latest value in °C (NaN: none).
    pub value_c: f64,
    /// Validation verdict code: see [`fault_name`].
    pub fault: u8,
    /// The fault's figure (°C, K/s, s), NaN without one.
    pub figure: f64,
    /// Time since its last update in s (infinite: never updated).
    pub age_s: f64,
}

/// The state last published, decoded on the reader's thread.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Publication number (1 for the first; a reader that sees it unchanged has nothing new).
    pub seq: u64,
    /// Service time in s.
    pub time_s: f64,
    /// Overall state.
    pub state: CompensationState,
    /// Whether any axis was clamped in the latest cycle.
    pub clamped: bool,
    /// Whether any path's model extrapolates.
    pub extrapolating: bool,
    /// Cycles run.
    pub cycles: u64,
    /// Cycles that finished later than one period after their deadline.
    pub late_cycles: u64,
    /// Work of the latest cycle in µs.
    pub cycle_work_us: f64,
    /// Cycle records dropped because the logger fell behind.
    pub records_dropped: u64,
    /// Probe events dropped because the logger fell behind.
    pub probes_dropped: u64,
    /// Events dropped because the event queue was full.
    pub events_dropped: u64,
    /// The log's health (`None`: no log).
    pub log: Option<LogFigures>,
    /// Per axis.
    pub axes: Vec<AxisView>,
    /// Per temperature channel.
    pub temperatures: Vec<TemperatureView>,
    /// Per operating channel, its value.
    pub operating: Vec<f64>,
    /// Per path: state, and whether its model extrapolates.
    pub paths: Vec<(PathView, bool)>,
    /// Per source, whether it delivers.
    pub sources_ok: Vec<bool>,
    /// Per source, the service time of the latest publication at which it delivered (NaN: none
    /// since start).
    pub sources_last_ok_s: Vec<f64>,
    /// Per sink: whether it fails now, and its failed writes.
    pub sinks: Vec<(bool, u64)>,
    /// Per model, its generation.
    pub generations: Vec<u64>,
}

/// The name of a validation verdict code of [`TemperatureView::fault`].
pub fn fault_name(code: u8) -> &'static str {
    match code {
        0 => "ok",
        1 => "never-updated",
        2 => "not-a-number",
        3 => "out-of-range",
        4 => "too-fast",
        5 => "stuck",
        6 => "stale",
        _ => "unknown",
    }
}

/// Every verdict code, good first (for listing faults by kind).
pub const FAULT_CODES: [u8; 7] = [0, 1, 2, 3, 4, 5, 6];

fn fault_code(f: &Option<Fault>) -> (u8, f64) {
    match *f {
        None => (0, f64::NAN),
        Some(Fault::NeverUpdated) => (1, f64::NAN),
        Some(Fault::NotANumber) => (2, f64::NAN),
        Some(Fault::OutOfRange { value }) => (3, value),
        Some(Fault::TooFast { rate_k_per_s }) => (4, rate_k_per_s),
        Some(Fault::Stuck { for_s }) => (5, for_s),
        Some(Fault::Stale { age_s }) => (6, age_s),
    }
}

fn state_code(s: CompensationState) -> f64 {
    match s {
        CompensationState::Active => 0.0,
        CompensationState::Holding => 1.0,
        CompensationState::Disabled => 2.0,
        CompensationState::NoModel => 3.0,
    }
}

fn state_of(code: f64) -> CompensationState {
    match code as i64 {
        0 => CompensationState::Active,
        1 => CompensationState::Holding,
        3 => CompensationState::NoModel,
        _ => CompensationState::Disabled,
    }
}

fn path_code(s: PathState) -> f64 {
    match s {
        PathState::Model(m) => m as f64,
        PathState::Holding => -1.0,
        PathState::NoModel => -2.0,
        PathState::Disabled => -3.0,
    }
}

fn path_of(code: f64) -> PathView {
    match code as i64 {
        m if m >= 0 => PathView::Model(m as usize),
        -1 => PathView::Holding,
        -2 => PathView::NoModel,
        _ => PathView::Disabled,
    }
}

fn flag(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

/// The latest published state of one service: written by its host's loop, read by anyone.
#[derive(Debug)]
pub struct Board {
    layout: Layout,
    seq: AtomicU64,
    cells: Vec<AtomicU64>,
    work: WorkStats,
}

/// Writes cells in order during a publication.
struct Cursor<'a> {
    cells: &'a [AtomicU64],
    at: usize,
}

impl Cursor<'_> {
    fn put(&mut self, v: f64) {
        if let Some(c) = self.cells.get(self.at) {
            c.store(v.to_bits(), Ordering::Relaxed);
        }
        self.at += 1;
    }

    /// What the next cell holds from the publication before (the one writer reads its own).
    fn previous(&self) -> f64 {
        self.cells
            .get(self.at)
            .map_or(f64::NAN, |c| f64::from_bits(c.load(Ordering::Relaxed)))
    }
}

impl Board {
    /// A board for a service of this layout, never published.
    pub fn new(layout: Layout) -> Self {
        Self {
            layout,
            seq: AtomicU64::new(0),
            cells: (0..layout.cells())
                .map(|_| AtomicU64::new(f64::NAN.to_bits()))
                .collect(),
            work: WorkStats::new(),
        }
    }

    /// Records the work of a cycle (µs) the host's loop finished at `at`, every cycle (one
    /// writer: the host's loop). Allocates nothing, takes no lock, never waits.
    pub fn record_work(&self, work_us: f64, at: Instant) {
        self.work.record(work_us, at);
    }

    /// The cycles' work times recorded so far, for readers.
    pub fn work(&self) -> &WorkStats {
        &self.work
    }

    /// The layout it was made for.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Publishes the service's state after its latest cycle (one writer only: the host's
    /// loop, between cycles). Allocates nothing, takes no lock, never waits.
    pub fn publish(&self, service: &Service, host: &HostFigures<'_>) {
        let l = self.layout;
        let s = self.seq.load(Ordering::Relaxed);
        self.seq.store(s.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        let out = service.output();
        let mut c = Cursor {
            cells: &self.cells,
            at: 0,
        };
        let log = host.log.unwrap_or_default();
        for v in [
            out.time_s,
            state_code(out.state),
            flag(out.clamped),
            flag(out.extrapolating),
            service.cycles() as f64,
            host.late_cycles as f64,
            host.cycle_work_us,
            service.records_dropped() as f64,
            service.probes_dropped() as f64,
            service.events_dropped() as f64,
            flag(host.log.is_some()),
            flag(log.failing),
            log.pending as f64,
            log.dropped as f64,
            0.0,
        ] {
            c.put(v);
        }
        let env = service.envelope();
        let targets = service.targets();
        for a in 0..l.axes {
            c.put(out.offset_um.get(a).copied().unwrap_or(f64::NAN));
            c.put(targets.get(a).copied().unwrap_or(f64::NAN));
            c.put(out.positions.get(a).copied().unwrap_or(f64::NAN));
            c.put(flag(env.clamping(a)));
            c.put(env.clamps(a) as f64);
            c.put(flag(env.blend_origin(a).is_some()));
        }
        let health = service.validator().health();
        let frame = service.frame();
        for t in 0..l.temperatures {
            let (code, figure) = health.get(t).map_or((1, f64::NAN), fault_code);
            c.put(frame.temperatures_c.get(t).copied().unwrap_or(f64::NAN));
            c.put(f64::from(code));
            c.put(figure);
            let stamp = frame.temperature_stamp_s.get(t).copied().unwrap_or(NEVER);
            c.put(out.time_s - stamp);
        }
        let ops = &service.frame().operating;
        for o in 0..l.operating {
            c.put(ops.get(o).copied().unwrap_or(f64::NAN));
        }
        let states = service.path_states();
        for p in 0..l.paths {
            c.put(states.get(p).map_or(-3.0, |s| path_code(*s)));
            c.put(flag(service.path_extrapolating(p)));
        }
        for i in 0..l.sources {
            let ok = service.source_reason(i).is_none();
            c.put(flag(ok));
            let last_ok = if ok { out.time_s } else { c.previous() };
            c.put(last_ok);
        }
        let sinks = service.sink_health();
        for i in 0..l.sinks {
            let h = sinks.get(i).copied().unwrap_or_default();
            c.put(flag(h.failing_since_s.is_some()));
            c.put(h.failed_writes as f64);
        }
        for m in 0..l.models {
            c.put(host.generations.get(m).copied().unwrap_or(1) as f64);
        }
        self.seq.store(s.wrapping_add(2), Ordering::Release);
    }

    /// The latest publication, consistent (never two publications mixed); `None` before the
    /// first, or if the writer kept overwriting it (read again later).
    pub fn read(&self) -> Option<Snapshot> {
        let mut raw = vec![0.0; self.cells.len()];
        for _ in 0..64 {
            let s1 = self.seq.load(Ordering::Acquire);
            if s1 % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            if s1 == 0 {
                return None;
            }
            for (o, c) in raw.iter_mut().zip(&self.cells) {
                *o = f64::from_bits(c.load(Ordering::Relaxed));
            }
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == s1 {
                return Some(self.decode(s1 / 2, &raw));
            }
        }
        None
    }

    fn decode(&self, seq: u64, raw: &[f64]) -> Snapshot {
        let l = self.layout;
        let mut it = raw.iter().copied();
        let mut next = move || it.next().unwrap_or(f64::NAN);
        let count = |v: f64| if v.is_finite() { v as u64 } else { 0 };
        let time_s = next();
        let state = state_of(next());
        let clamped = next() == 1.0;
        let extrapolating = next() == 1.0;
        let cycles = count(next());
        let late_cycles = count(next());
        let cycle_work_us = next();
        let records_dropped = count(next());
        let probes_dropped = count(next());
        let events_dropped = count(next());
        let has_log = next() == 1.0;
        let log = LogFigures {
            failing: next() == 1.0,
            pending: count(next()),
            dropped: count(next()),
        };
        next();
        let axes = (0..l.axes)
            .map(|_| AxisView {
                offset_um: next(),
                target_um: next(),
                position: next(),
                clamping: next() == 1.0,
                clamps: count(next()),
                blending: next() == 1.0,
            })
            .collect();
        let temperatures = (0..l.temperatures)
            .map(|_| TemperatureView {
                value_c: next(),
                fault: count(next()).min(255) as u8,
                figure: next(),
                age_s: next(),
            })
            .collect();
        let operating = (0..l.operating).map(|_| next()).collect();
        let paths = (0..l.paths)
            .map(|_| (path_of(next()), next() == 1.0))
            .collect();
        let (sources_ok, sources_last_ok_s) =
            (0..l.sources).map(|_| (next() == 1.0, next())).unzip();
        let sinks = (0..l.sinks)
            .map(|_| (next() == 1.0, count(next())))
            .collect();
        let generations = (0..l.models).map(|_| count(next())).collect();
        Snapshot {
            seq,
            time_s,
            state,
            clamped,
            extrapolating,
            cycles,
            late_cycles,
            cycle_work_us,
            records_dropped,
            probes_dropped,
            events_dropped,
            log: has_log.then_some(log),
            axes,
            temperatures,
            operating,
            paths,
            sources_ok,
            sources_last_ok_s,
            sinks,
            generations,
        }
    }
}
