//! The timing benchmark (`truepos-hal-check timing`): the runtime's service at a fixed period on
//! the component's own pacing ([`truepos_hal::pacer`]), replaying a recorded run and logging to
//! SQLite, with the host's steal time sampled beside it ([`host`]). It needs no LinuxCNC.
//!
//! A cycle is *late* when it finishes more than `late_ms` after its deadline. Late cycles whose
//! windows overlap form one stall (*episode*); an episode *coincides with steal* when the
//! watched CPU's steal counter advanced between the samples around it (widened by the
//! counter's 10 ms resolution plus one sampling interval). The bar is judged on the late
//! cycles not explained so; every figure is reported.

pub mod episodes;
pub mod host;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use serde_json::{json, Value};
use truepos_io::model_file::load_set;
use truepos_runtime::replay::ReplaySource;
use truepos_runtime::ServiceHost;

use episodes::{Episode, Episodes};
use host::{HostActivity, HostRecord, HostSampler, TICK_MS};
use truepos_hal::pacer::{realtime_setup, Pacer};
use truepos_hal::{ffi, pacer};

use crate::Error;

/// What to run.
#[derive(Debug, Clone)]
pub struct TimingConfig {
    /// Machine file.
    pub machine: PathBuf,
    /// Model files of the set.
    pub models: Vec<PathBuf>,
    /// Recorded run replayed as the source (real time).
    pub run: PathBuf,
    /// SQLite log, if any.
    pub log: Option<PathBuf>,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Cycle period, ms.
    pub period_ms: f64,
    /// `SCHED_FIFO` priority (0: normal scheduling).
    pub rt_priority: i32,
    /// CPU to bind the cycle to.
    pub cpu: Option<usize>,
    /// Interval of the host sampling, ms.
    pub sample_ms: f64,
    /// A cycle finishing later than this after its deadline is late, ms.
    pub late_ms: f64,
}

/// Upper edges (µs) of the histogram of how late cycles finished after their deadline.
pub const LATENESS_EDGES_US: [f64; 5] = [100.0, 250.0, 500.0, 1000.0, 2000.0];

/// Most episodes kept (late cycles beyond are counted, not attributed).
const MAX_EPISODES: usize = 1 << 16;

/// Percentiles of a sample in place (sorts it).
fn percentiles(samples: &mut [u32], qs: &[f64]) -> Vec<f64> {
    samples.sort_unstable();
    qs.iter()
        .map(|q| match samples.len() {
            0 => 0.0,
            n => f64::from(samples[((n - 1) as f64 * q).round() as usize]) / 1000.0,
        })
        .collect()
}

/// An episode with what the host did around it.
struct Attributed {
    episode: Episode,
    host: Option<HostActivity>,
}

/// What the cycle loop keeps of every cycle: its work and wake-up times (room for every cycle
/// allocated, and with mlockall locked, before the first), the lateness histogram, the largest
/// lateness and the episodes of cycles later than `late_ns`.
struct Record {
    work_ns: Vec<u32>,
    wake_ns: Vec<u32>,
    histogram: [u64; LATENESS_EDGES_US.len() + 1],
    episodes: Episodes,
    late_ns: u64,
    late_max_ns: u64,
}

impl Record {
    fn new(expected: usize, late_ns: u64) -> Self {
        Record {
            work_ns: Vec::with_capacity(expected.min(1 << 26)),
            wake_ns: Vec::with_capacity(expected.min(1 << 26)),
            histogram: [0u64; LATENESS_EDGES_US.len() + 1],
            episodes: Episodes::with_capacity(MAX_EPISODES),
            late_ns,
            late_max_ns: 0,
        }
    }

    /// Records a cycle that woke at `woke` and finished at `finish` for `deadline` (ns); no
    /// allocation, so that recording does not disturb the cycle it measures.
    fn cycle(&mut self, woke: u64, finish: u64, deadline: u64) {
        let late = finish.saturating_sub(deadline);
        if self.work_ns.len() < self.work_ns.capacity() {
            self.work_ns
                .push((finish - woke).min(u64::from(u32::MAX)) as u32);
            self.wake_ns
                .push(woke.saturating_sub(deadline).min(u64::from(u32::MAX)) as u32);
        }
        let late_us = late as f64 / 1000.0;
        let bucket = LATENESS_EDGES_US.iter().position(|&e| late_us < e);
        self.histogram[bucket.unwrap_or(LATENESS_EDGES_US.len())] += 1;
        self.late_max_ns = self.late_max_ns.max(late);
        if late > self.late_ns {
            self.episodes.push(deadline, finish);
        }
    }
}

/// Runs the benchmark; `stop` ends it early. Returns the JSON summary.
pub fn run(config: &TimingConfig, stop: &AtomicBool) -> Result<Value, Error> {
    if !(config.period_ms > 0.0 && config.period_ms <= 1000.0) {
        return Err(Error::Period(config.period_ms));
    }
    if !(config.duration_s > 0.0 && config.duration_s.is_finite()) {
        return Err(Error::Duration(config.duration_s));
    }
    let machine = truepos_io::machine_file::load(&config.machine)?;
    let m = &machine.machine;
    let entries = load_set(&config.models, &machine)?;
    let cycles = truepos_io::cycles::load(&config.run, m, &[])?;
    let run = cycles.run;
    let replay = ReplaySource::new(format!("replay {}", config.run.display()), run);
    if replay.duration_s() < config.duration_s {
        eprintln!(
            "truepos-hal-check timing: the run lasts {:.0} s, less than {} s; its last values stay",
            replay.duration_s(),
            config.duration_s
        );
    }
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    // The logger and sampling threads start before the cycle thread takes its CPU and
    // priority, so they inherit neither, and bound to the other CPUs.
    if let Some(cpu) = config.cpu {
        if let Err(e) = pacer::keep_off_cpu(cpu) {
            eprintln!("truepos-hal-check timing: warning: {e}");
        }
    }
    let mut service_host = ServiceHost::new(machine, entries)
        .period_s(config.period_ms / 1000.0)
        .source(Box::new(replay))
        .log(config.log.clone())
        .start()?;
    let service = &mut service_host.service;
    let sample_ns = (config.sample_ms * 1e6).round().max(1e5) as u64;
    let sampler = HostSampler::start(sample_ns, config.cpu);
    if let Err(e) = &sampler {
        eprintln!("truepos-hal-check timing: warning: no host sampling: {e}");
    }
    let setup = realtime_setup(config.rt_priority, config.cpu);
    for e in &setup.errors {
        eprintln!("truepos-hal-check timing: warning: {e}");
    }

    let period_ns = (config.period_ms * 1e6).round() as u64;
    let expected = (config.duration_s * 1000.0 / config.period_ms).ceil() as usize + 16;
    let mut record = Record::new(expected, (config.late_ms * 1e6).round() as u64);

    let cpu0 = ffi::process_cpu_ns();
    let start_ns = ffi::monotonic_ns() + period_ns;
    let mut pacer = Pacer::new(start_ns, period_ns);
    while pacer.deadline_s() < config.duration_s && !stop.load(Ordering::Relaxed) {
        let woke = pacer.wait();
        service.cycle(pacer.deadline_s());
        record.cycle(woke, ffi::monotonic_ns(), pacer.deadline_ns());
        pacer.advance();
    }
    let Record {
        mut work_ns,
        mut wake_ns,
        histogram,
        episodes,
        late_max_ns,
        ..
    } = record;
    let end_ns = ffi::monotonic_ns();
    let cpu_ns = ffi::process_cpu_ns() - cpu0;
    let ran = pacer.index();
    let host = sampler.map(HostSampler::stop).unwrap_or_default();
    let stopped = service_host.stop();
    if let Some((result, _)) = stopped.log {
        result?;
    }
    let service = &stopped.service;

    let wall_ns = (end_ns - start_ns).max(1) as f64;
    let service_cpu_ns = cpu_ns.saturating_sub(host.sampler_cpu_ns);
    let margin_ns = (TICK_MS * 1e6) as u64 + sample_ns;
    let attributed: Vec<Attributed> = episodes
        .list()
        .iter()
        .map(|&episode| Attributed {
            episode,
            host: host.around(episode.start_ns, episode.end_ns, margin_ns),
        })
        .collect();
    let summary = Summary {
        config,
        setup: &setup,
        ran,
        wall_ns,
        work_ns: &mut work_ns,
        wake_ns: &mut wake_ns,
        histogram: &histogram,
        late_max_ns,
        episodes: &episodes,
        attributed: &attributed,
        host: &host,
        margin_ns,
        start_ns,
        service_cpu_ns,
        cpus,
        records_dropped: service.records_dropped(),
        events_dropped: service.events().dropped(),
    };
    Ok(summary.into_json())
}

/// The figures of a run, for [`Summary::into_json`].
struct Summary<'a> {
    config: &'a TimingConfig,
    setup: &'a pacer::RealtimeSetup,
    ran: u64,
    wall_ns: f64,
    work_ns: &'a mut [u32],
    wake_ns: &'a mut [u32],
    histogram: &'a [u64],
    late_max_ns: u64,
    episodes: &'a Episodes,
    attributed: &'a [Attributed],
    host: &'a HostRecord,
    margin_ns: u64,
    start_ns: u64,
    service_cpu_ns: u64,
    cpus: usize,
    records_dropped: u64,
    events_dropped: u64,
}

impl Summary<'_> {
    fn into_json(self) -> Value {
        let qs = [0.5, 0.99, 0.999, 1.0];
        let work = percentiles(self.work_ns, &qs);
        let wake = percentiles(self.wake_ns, &qs);
        let with_steal = |a: &&Attributed| a.host.is_some_and(|h| h.stole());
        let late_total = self.episodes.cycles();
        let late_steal: u64 = self
            .attributed
            .iter()
            .filter(with_steal)
            .map(|a| a.episode.cycles)
            .sum();
        let unexplained: Vec<&Attributed> =
            self.attributed.iter().filter(|a| !with_steal(a)).collect();
        // Late cycles beyond the kept episodes cannot be attributed: they count as unexplained.
        let late_unexplained = unexplained.iter().map(|a| a.episode.cycles).sum::<u64>()
            + self.episodes.overflow_cycles;
        let unexplained_pressure = unexplained
            .iter()
            .filter(|a| {
                a.host
                    .and_then(|h| h.pressure_some_us)
                    .is_some_and(|p| p > 0)
            })
            .map(|a| a.episode.cycles)
            .sum::<u64>();
        let worst_unexplained_ms = unexplained
            .iter()
            .map(|a| a.episode.worst_ns)
            .max()
            .unwrap_or(0) as f64
            / 1e6;
        let total = self.host.total();
        let span_s = self.host.span_ns() as f64 * 1e-9;
        let steal_percent = |ticks: u64, cpus: f64| {
            (span_s > 0.0).then(|| ticks as f64 * TICK_MS / 1000.0 / (span_s * cpus) * 100.0)
        };
        let late_ns = (self.config.late_ms * 1e6) as u64;
        let chance = self.host.chance(late_ns, self.margin_ns, 1_000_000);
        let cpu_percent = self.service_cpu_ns as f64 / self.wall_ns * 100.0;
        let describe = |a: &&Attributed| {
            json!({
                "at_s": (a.episode.start_ns.saturating_sub(self.start_ns)) as f64 * 1e-9,
                "length_ms": (a.episode.end_ns - a.episode.start_ns) as f64 / 1e6,
                "cycles": a.episode.cycles,
                "worst_ms": a.episode.worst_ns as f64 / 1e6,
                "steal_ticks_all_cpus": a.host.map(|h| h.steal_ticks_all),
                "cpu_pressure_us": a.host.and_then(|h| h.pressure_some_us),
            })
        };
        json!({
            "duration_s": self.config.duration_s,
            "period_ms": self.config.period_ms,
            "cycles": self.ran,
            "wall_time_s": self.wall_ns * 1e-9,
            "realtime": {
                "sleep": "clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)",
                "sched_fifo_priority": self.setup.fifo_priority,
                "mlockall": self.setup.memory_locked,
                "cpu": self.setup.cpu,
                "timer_slack_1ns": self.setup.no_timer_slack,
                "refused": self.setup.errors,
                "cpus": self.cpus,
            },
            "cycle_work_us": { "p50": work[0], "p99": work[1], "p999": work[2], "max": work[3] },
            "wake_latency_us": { "p50": wake[0], "p99": wake[1], "p999": wake[2], "max": wake[3] },
            "finished_late_histogram": {
                "under_100us": self.histogram[0],
                "100_250us": self.histogram[1],
                "250_500us": self.histogram[2],
                "500us_1ms": self.histogram[3],
                "1_2ms": self.histogram[4],
                "over_2ms": self.histogram[5],
            },
            "late_max_ms": self.late_max_ns as f64 / 1e6,
            "late_cycles": {
                "bar_ms": self.config.late_ms,
                "total": late_total,
                "coinciding_with_steal": late_steal,
                "not_explained_by_steal": late_unexplained,
                "not_explained_but_with_guest_cpu_pressure": unexplained_pressure,
                "episodes": self.episodes.list().len(),
                "episodes_coinciding_with_steal": self.attributed.iter().filter(with_steal).count(),
                "episodes_not_explained": unexplained.len(),
                "worst_not_explained_ms": worst_unexplained_ms,
                "not_explained_first": unexplained.iter().take(20).map(describe).collect::<Vec<_>>(),
                "window_margin_ms": self.margin_ns as f64 / 1e6,
                "chance_a_window_sees_steal": chance,
            },
            "host": {
                "sample_interval_ms": self.config.sample_ms,
                "samples": self.host.samples.len(),
                "steal_resolution_ms": TICK_MS,
                "steal_ms_watched_cpu": total.map(|t| t.steal_ticks as f64 * TICK_MS),
                "steal_percent_watched_cpu": total.and_then(|t| steal_percent(t.steal_ticks, if self.setup.cpu.is_some() { 1.0 } else { self.cpus as f64 })),
                "steal_percent_all_cpus": total.and_then(|t| steal_percent(t.steal_ticks_all, self.cpus as f64)),
                "guest_cpu_pressure_some_ms": total.and_then(|t| t.pressure_some_us).map(|p| p as f64 / 1000.0),
                "sampler_cpu_percent": self.host.sampler_cpu_ns as f64 / self.wall_ns * 100.0,
            },
            "cpu_percent_of_one_core": cpu_percent,
            "bar": {
                "cpu_below_5_percent": cpu_percent < 5.0,
                "no_late_cycle": late_total == 0,
                "no_late_cycle_not_explained_by_steal": late_unexplained == 0,
            },
            "log_records_dropped": self.records_dropped,
            "events_dropped": self.events_dropped,
        })
    }
}
