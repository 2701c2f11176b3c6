//! `truepos run` and `truepos log`: the cyclic service beside a control, and its log's records
//! (`truepos status` is in `status.rs`).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::envelope_check;
use crate::error::CliError;
use truepos_fleet::MqttOptions;
use truepos_io::limits::{check_in, finite_in};
use truepos_io::model_file::signature::TrustedKeys;
use truepos_io::model_file::{load_entry_trusted, load_set_trusted};
use truepos_io::{cycles, machine_file};
use truepos_live::host::{HttpOptions, Live};
use truepos_model::RecordedRun;
use truepos_protocols::modbus::{ModbusConfig, ModbusSource};
use truepos_protocols::opcua::{OpcUaSink, OpcUaSource, SinkConfig, SourceConfig};
use truepos_protocols::shdr::{ShdrConfig, ShdrSource};
use truepos_runtime::host::{ModelLoader, ReloadSetup};
use truepos_runtime::log;
use truepos_runtime::probe::ProbeReplay;
use truepos_runtime::replay::{state_name, CsvSink, ReplaySource};
use truepos_runtime::{PathState, Running, Service, ServiceConfig, ServiceHost, Sink, Source};

/// The files `truepos run` reads (machine, models, replayed runs and configurations, the
/// log), none of which a CSV sink may write.
fn run_inputs(args: &RunArgs) -> Vec<(&'static str, &Path)> {
    let mut v: Vec<(&'static str, &Path)> = vec![("--machine", args.machine.as_path())];
    v.extend(args.models.iter().map(|m| ("--models", m.as_path())));
    for s in &args.sources {
        if let Some((_, rest)) = s.split_once(':') {
            let file = rest.rsplit_once('@').map_or(rest, |(f, _)| f);
            v.push(("--source", Path::new(file)));
        }
    }
    v.extend(args.log.as_deref().map(|l| ("--log", l)));
    v
}

/// Arguments of `truepos run`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Machine description (TOML). The defaults of --machine, --models and --source are the
    /// example VMC's, found from any directory.
    #[arg(long, default_value = "examples/vmc3/machine.toml")]
    machine: PathBuf,
    /// Model files of the model set, in order of preference (repeat, or separate with commas).
    #[arg(
        long = "models",
        value_delimiter = ',',
        default_value = "examples/vmc3/model.toml"
    )]
    models: Vec<PathBuf>,
    /// A list of public keys (one in hex a line, from `truepos sign --new-key`): every model
    /// must then carry a signature (MODEL.sig) by one of them, at start and at every reload.
    #[arg(long, value_name = "FILE")]
    trusted_keys: Option<PathBuf>,
    /// Sources: `replay:RUN.csv[@SPEED]` (a recorded run), `twin:SCENARIO[@SPEED]` (the
    /// thermal twin's sensors on a built-in scenario or scenario file; temperatures and
    /// operating state only, positions come from the other sources), `probes:RUN.csv[@SPEED]`
    /// (the probe events of a run: its `probe_<axis>_mm` and `probe_d<axis>_um` columns),
    /// `modbus:CONFIG.toml` (temperature modules), `shdr:CONFIG.toml` (an MTConnect adapter)
    /// and `opcua:CONFIG.toml`; see docs/network_sources.md for their configuration. SPEED
    /// (0.001–10⁶, one for the whole run) plays the recorded sources SPEED × faster than real
    /// time: the service then runs on the data's clock, so lags, rates, blends and every other
    /// time-dependent state follow the recorded time and the outputs are those of speed 1. A
    /// speed other than 1 is refused beside a live source (Modbus, SHDR, OPC UA), whose values
    /// arrive in real time.
    #[arg(long = "source", default_value = "replay:examples/vmc3/run.csv")]
    sources: Vec<String>,
    /// Sinks: `csv:OUT.csv` (one row per `--sink-every-s`) and `opcua:MAPPING.toml` (the model's
    /// per-axis line K0/tanβ/P0 written to a control's nodes; docs/controls.md).
    #[arg(long = "sink")]
    sinks: Vec<String>,
    /// SQLite log of inputs, outputs and events (WAL mode).
    #[arg(long)]
    log: Option<PathBuf>,
    /// Cycle period in ms on the service's clock, 0.1–10 000 (with `@SPEED`, the data's
    /// clock: cycles come SPEED × as often in real time).
    #[arg(long, default_value_t = 1.0, value_parser = finite_in(0.1, 10_000.0))]
    period_ms: f64,
    /// Stop after this many seconds, 0.001–31 536 000 (a year; default: when a replay ends).
    #[arg(long, value_parser = finite_in(0.001, MAX_RUN_S))]
    duration_s: Option<f64>,
    /// Run as fast as possible on a simulated clock (replays and tests), not in real time.
    #[arg(long)]
    fast: bool,
    /// Blend time in s for model switches and enabling/disabling, 0–3600.
    #[arg(long, default_value_t = 5.0, value_parser = finite_in(0.0, 3600.0))]
    blend_s: f64,
    /// Time in s over which a held compensation ramps to zero, 0–86 400.
    #[arg(long, default_value_t = 60.0, value_parser = finite_in(0.0, 86_400.0))]
    hold_ramp_s: f64,
    /// Interval in s between cycle records in the log, 0–3600 (0: every cycle).
    #[arg(long, default_value_t = 0.1, value_parser = finite_in(0.0, 3600.0))]
    log_every_s: f64,
    /// Interval in s between rows of a CSV sink, 0–3600 (0: every cycle).
    #[arg(long, default_value_t = 0.1, value_parser = finite_in(0.0, 3600.0))]
    sink_every_s: f64,
    /// Reload a model file of the set without a restart when it changes (its modification
    /// time or size, checked every 0.1 s on a thread of its own): the new model blends in like
    /// a model switch; a file that fails to load leaves the running model and logs why.
    #[arg(long)]
    reload_on_change: bool,
    /// Print a summary as JSON at the end (and no status line).
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    http: HttpOptions,
    #[command(flatten)]
    mqtt: MqttOptions,
}

/// Longest run in s, a year: bounds `--duration-s` and a replay's length at its speed, so that a
/// `--fast` run always ends.
const MAX_RUN_S: f64 = 31_536_000.0;

/// Arguments of `truepos log`.
#[derive(clap::Args)]
pub struct LogArgs {
    /// The service's log.
    #[arg(long)]
    log: PathBuf,
    /// Write the logged cycles as a run CSV (readable by `truepos eval` and `truepos fit`).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Print the events as JSON.
    #[arg(long)]
    json: bool,
}

/// The twin in the loop: the reference twin runs `scenario` (a built-in name or a TOML file)
/// and its sensors are delivered by their ids, as a temperature module would; the axis
/// positions stay with the control's source.
fn twin_source(
    scenario: &str,
    machine: &truepos_model::Machine,
    check: EnvelopeCheck<'_>,
) -> Result<ReplaySource, CliError> {
    let sc = match truepos_sim::Scenario::builtin(scenario) {
        Some(s) => s,
        None => {
            let text = truepos_files::read::read_text(
                std::path::Path::new(scenario),
                truepos_files::CONFIG,
            )
            .map_err(CliError::context(format!(
                "twin scenario `{scenario}`: not a built-in ({}) and not a readable file: ",
                truepos_sim::BUILTIN.join(", ")
            )))?;
            truepos_sim::Scenario::parse(&text, scenario, None)?
        }
    };
    let twin = truepos_sim::Twin::reference();
    let run = twin.run(&sc, 1)?;
    let time_s = run.column("time_s").unwrap_or_default();
    let rows = time_s.len();
    let column = |id: &str| run.column(id).unwrap_or_else(|| vec![f64::NAN; rows]);
    let temps: Vec<Vec<f64>> = machine.temperatures.iter().map(|t| column(&t.id)).collect();
    let ops: Vec<Vec<f64>> = machine.operating.iter().map(|o| column(&o.id)).collect();
    if temps.iter().all(|c| c.iter().all(|v| v.is_nan())) {
        return Err(CliError::refused(format!(
            "twin: none of machine `{}`'s temperature ids is a sensor of the twin ({}); use examples/twin/machine.toml",
            machine.name,
            run.sensor_ids.join(", ")
        )));
    }
    let run = RecordedRun {
        temperatures_c: (0..rows)
            .map(|i| temps.iter().map(|c| c[i]).collect())
            .collect(),
        positions: vec![vec![f64::NAN; machine.axes.len()]; rows],
        operating: (0..rows)
            .map(|i| ops.iter().map(|c| c[i]).collect())
            .collect(),
        time_s,
    };
    check(&format!("the twin's `{scenario}` day"), &run);
    Ok(ReplaySource::new(format!("twin {scenario}"), run).without_positions())
}

/// Cycle-time statistics in µs.
struct Timing {
    samples: Vec<u32>,
    late_max_us: f64,
    overruns: u64,
    /// Cycles by how late they finished after their deadline: < 0.1, 0.25, 0.5, 1, 2 ms, ≥ 2 ms.
    histogram: [u64; 6],
    /// Wall time of the run, s.
    wall_s: f64,
    /// CPU time of the process over the run in % of one core, if known.
    cpu_percent: Option<f64>,
}

/// Upper edges of the lateness histogram in µs.
const LATENESS_EDGES_US: [f64; 5] = [100.0, 250.0, 500.0, 1000.0, 2000.0];

/// CPU time (user + system) of this process in s, from /proc (Linux).
fn cpu_time_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    // The kernel's clock tick is 100 Hz on every Linux this runs on (USER_HZ).
    Some((utime + stime) / 100.0)
}

impl Timing {
    fn percentile(&mut self, q: f64) -> u32 {
        if self.samples.is_empty() {
            return 0;
        }
        self.samples.sort_unstable();
        let i = ((self.samples.len() - 1) as f64 * q).round() as usize;
        self.samples[i]
    }
}

pub fn run(mut args: RunArgs) -> Result<(), CliError> {
    args.machine = crate::examples::find(std::mem::take(&mut args.machine));
    args.models = args.models.drain(..).map(crate::examples::find).collect();
    let http = args.http.check().map_err(CliError::refused)?;
    let mqtt = args
        .mqtt
        .config(args.log.as_deref())
        .map_err(CliError::refused)?;
    let machine = machine_file::load(&args.machine)?;
    let trusted = args
        .trusted_keys
        .as_deref()
        .map(TrustedKeys::load)
        .transpose()?;
    let entries = load_set_trusted(&args.models, &machine, trusted.as_ref())?;
    let clock = run_clock(&args)?;
    // The service clock's zero, shared with network sources that stamp values themselves.
    let epoch = Instant::now();
    // Said before the first cycle: a model that runs into the envelope on the data it is about
    // to replay would be held at the limit, safe but not what its figures promise.
    let check = |what: &str, run: &RecordedRun| {
        for e in &entries {
            let beyond = envelope_check::beyond(&machine, &e.model, run);
            for w in envelope_check::warnings(&machine, &args.machine, &e.name, what, &beyond) {
                eprintln!("{w}");
            }
        }
    };
    let (sources, replay_end_s) = open_sources(&args, &machine.machine, epoch, &check)?;
    let sinks = open_sinks(&args, &machine, &entries)?;
    let source_names: Vec<String> = sources.iter().map(|s| s.name().to_string()).collect();
    let mut host = start_service(&args, machine, entries, trusted, (sources, sinks))?;
    let mut live = match http {
        Some(h) => Some(
            Live::start(h, &host, source_names, args.log.as_ref(), &args.models)
                .map_err(CliError::refused)?,
        ),
        None => None,
    };
    // Beside the service, on a thread of its own that reads the log: the cycle never waits on it.
    let publisher = mqtt.map(crate::fleet::start).transpose()?;
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(CliError::context("cannot install the signal handler: "))?;
    }

    let end_s = args
        .duration_s
        .or(replay_end_s.map(|e| e + args.period_ms / 1000.0));
    let status_line = !args.json && std::io::stderr().is_terminal();
    let cpu_start = cpu_time_s();
    let (mut timing, last_status) = cycle_loop(
        &args,
        (&mut host, live.as_mut()),
        (epoch, clock),
        end_s,
        &stop,
        status_line,
    );
    if let Some(l) = live {
        l.stop(&host, timing.overruns);
    }
    if status_line {
        eprintln!();
    }
    timing.wall_s = epoch.elapsed().as_secs_f64();
    timing.cpu_percent = match (cpu_start, cpu_time_s()) {
        (Some(a), Some(b)) if timing.wall_s > 0.0 => Some(100.0 * (b - a) / timing.wall_s),
        _ => None,
    };
    let stopped = host.stop();
    if let Some(p) = publisher {
        crate::fleet::finish(p);
    }
    let failures = run_failures(&stopped.service, stopped.log);
    summarize(
        &args,
        &stopped.service,
        &mut timing,
        &failures,
        &last_status,
        status_line,
    );
    if failures.is_empty() {
        Ok(())
    } else {
        Err(CliError::Refused(failures.join("; ")))
    }
}

/// The service's sources, in the order given.
type Sources = Vec<Box<dyn Source>>;

/// The service started on the run's machine, models, sources and sinks, with the run's blend,
/// hold and log settings, its log, and with `--reload-on-change` the thread that loads a model
/// file again (signature checked as at start) when it changes.
fn start_service(
    args: &RunArgs,
    machine: truepos_runtime::MachineConfig,
    entries: Vec<truepos_runtime::model_set::ModelEntry>,
    trusted: Option<TrustedKeys>,
    (sources, sinks): (Sources, Vec<Box<dyn Sink>>),
) -> Result<Running, CliError> {
    let config = ServiceConfig {
        blend_s: args.blend_s,
        hold_ramp_s: args.hold_ramp_s,
        log_every_s: args.log_every_s,
        ..ServiceConfig::default()
    };
    let reload = args.reload_on_change.then(|| {
        let loader_machine = machine.clone();
        ReloadSetup {
            files: args.models.clone(),
            loader: Box::new(move |path: &std::path::Path| {
                load_entry_trusted(path, &loader_machine, trusted.as_ref())
                    .map_err(|e| e.to_string())
            }) as ModelLoader,
            watch: true,
        }
    });
    ServiceHost::new(machine, entries)
        .period_s(args.period_ms / 1000.0)
        .reload(reload)
        .sources(sources)
        .sinks(sinks)
        .config(config)
        .log(args.log.clone())
        .start()
        .map_err(CliError::from)
}

/// Says when a model's predictions on a recorded source's data (named by the text) go beyond
/// the envelope.
type EnvelopeCheck<'a> = &'a dyn Fn(&str, &RecordedRun);

/// How the service's clock runs against real time.
#[derive(Clone, Copy)]
struct Clock {
    /// Service seconds per real second: the `@SPEED` of the recorded sources (1 without).
    speed: f64,
    /// Whether a live source (Modbus, SHDR, OPC UA) stamps values on the real clock since the
    /// epoch: then the service's clock is that one, from the epoch on.
    live: bool,
}

/// A `--source` as (kind, what, speed if `@SPEED` is given).
fn split_source(spec: &str) -> Result<(&str, &str, Option<f64>), CliError> {
    let (kind, rest) = spec.split_once(':').unwrap_or(("", spec));
    if !matches!(kind, "replay" | "twin" | "probes") {
        return Ok((kind, rest, None));
    }
    Ok(match rest.rsplit_once('@') {
        Some((what, s)) => (
            kind,
            what,
            Some(check_in(s.parse().unwrap_or(f64::NAN), 0.001, 1e6).map_err(
                CliError::context(format!("--source `{spec}`: speed after @: ")),
            )?),
        ),
        None => (kind, rest, None),
    })
}

/// The run's clock: one speed for every recorded source, since the service has one clock and
/// it is the data's (a recorded source has no speed of its own); a speed other than 1 only
/// with no live source and no OPC UA sink, whose values come and go in real time.
fn run_clock(args: &RunArgs) -> Result<Clock, CliError> {
    let mut speed: Option<(f64, &str)> = None;
    let mut live = None;
    for spec in &args.sources {
        let (kind, _, s) = split_source(spec)?;
        if matches!(kind, "modbus" | "shdr" | "opcua") {
            live.get_or_insert(spec.as_str());
        }
        let Some(s) = s else { continue };
        match speed {
            Some((first, other)) if first != s => {
                return Err(CliError::refused(format!(
                    "--source `{spec}`: speed {s}, but `{other}` plays at {first}: a run has one clock, give every recorded source the same @SPEED"
                )))
            }
            _ => speed = Some((s, spec)),
        }
    }
    let speed = speed.map_or(1.0, |(s, _)| s);
    if speed != 1.0 {
        let sink = args.sinks.iter().find(|s| s.starts_with("opcua:"));
        if let Some(other) = live.or(sink.map(String::as_str)) {
            return Err(CliError::refused(format!(
                "`{other}` delivers in real time, so the recorded sources cannot play at speed {speed} beside it: leave out @SPEED (or run them separately)"
            )));
        }
    }
    Ok(Clock {
        speed,
        live: live.is_some(),
    })
}

/// The sources of `--source`, and when the last replay ends (service time, s).
fn open_sources(
    args: &RunArgs,
    m: &truepos_model::Machine,
    epoch: Instant,
    check: EnvelopeCheck<'_>,
) -> Result<(Sources, Option<f64>), CliError> {
    let mut sources: Sources = Vec::new();
    let mut replay_end_s = None;
    for spec in &args.sources {
        let (kind, what, _) = split_source(spec)?;
        let source: Box<dyn Source> = match kind {
            "replay" => {
                let file = crate::examples::find(what.into());
                let run = cycles::load(&file, m, &[])?.run;
                check(&format!("replay {what}"), &run);
                let replay = ReplaySource::new(format!("replay {what}"), run);
                replay_end_s = Some(replay.duration_s());
                if args.duration_s.is_none() && replay.duration_s() > MAX_RUN_S {
                    return Err(CliError::refused(format!("--source `{spec}`: lasts {} s, over the {MAX_RUN_S} s (a year) a run may last; give --duration-s", replay.duration_s())));
                }
                Box::new(replay)
            }
            "twin" => Box::new(twin_source(what, m, check)?),
            "probes" => {
                let path = std::path::Path::new(what);
                let (events, start) = crate::reidentify::probes_csv::read_inputs(path, m)?;
                Box::new(ProbeReplay::new(format!("probes {what}"), events, start))
            }
            "modbus" => {
                let path = std::path::Path::new(what);
                let cfg = ModbusConfig::load(path)?;
                Box::new(ModbusSource::start(&cfg, m, epoch).map_err(|e| e.in_file(path, "modbus"))?)
            }
            "shdr" => {
                let path = std::path::Path::new(what);
                let cfg = ShdrConfig::load(path)?;
                Box::new(ShdrSource::start(&cfg, m, epoch).map_err(|e| e.in_file(path, "shdr"))?)
            }
            "opcua" => {
                let (cfg, identity, targets) =
                    SourceConfig::load(std::path::Path::new(what), m)?;
                Box::new(OpcUaSource::start(
                    &cfg, identity, targets, epoch,
                )?)
            }
            _ => {
                return Err(CliError::refused(format!(
                    "--source `{spec}`: expected `replay:FILE.csv[@SPEED]`, `probes:FILE.csv[@SPEED]`, `twin:SCENARIO[@SPEED]`, `modbus:CONFIG.toml`, `shdr:CONFIG.toml` or `opcua:CONFIG.toml`"
                )))
            }
        };
        sources.push(source);
    }
    Ok((sources, replay_end_s))
}

/// The sinks of `--sink`. An OPC UA sink projects the model when the set is one position-dependent
/// model (then an active service runs exactly it); a fitted dynamic model's form, and that of a
/// set of several models (which one runs is the service's choice, cycle by cycle), is the
/// service's output as a constant.
fn open_sinks(
    args: &RunArgs,
    machine: &truepos_runtime::MachineConfig,
    entries: &[truepos_runtime::model_set::ModelEntry],
) -> Result<Vec<Box<dyn Sink>>, CliError> {
    let m = &machine.machine;
    let axis_names: Vec<String> = m.axes.iter().map(|a| a.name.clone()).collect();
    let mut sinks: Vec<Box<dyn Sink>> = Vec::new();
    for spec in &args.sinks {
        if let Some(file) = spec.strip_prefix("opcua:") {
            let (cfg, identity, axes) = SinkConfig::load(std::path::Path::new(file), m)?;
            let model = match entries {
                [one] => one.model.as_static().cloned(),
                _ => None,
            };
            let sink = OpcUaSink::start(&cfg, identity, &axes, machine, model)?;
            sinks.push(Box::new(sink));
            continue;
        }
        let Some(file) = spec.strip_prefix("csv:") else {
            return Err(CliError::refused(format!(
                "--sink `{spec}`: expected `csv:FILE.csv` or `opcua:MAPPING.toml`"
            )));
        };
        let sink = CsvSink::create(
            std::path::Path::new(file),
            &axis_names,
            args.sink_every_s,
            &run_inputs(args),
        )?;
        sinks.push(Box::new(sink));
    }
    Ok(sinks)
}

/// Runs the cycles until `stop`, `end_s`, or the axes become unreachable; returns the timing
/// figures and the last status line. Cycle k runs at service time k × period, due at
/// k × period / speed of real time after the clock's start: the same service times at every
/// speed, so that a replay's outputs do not depend on how fast it plays.
fn cycle_loop(
    args: &RunArgs,
    (host, mut live): (&mut Running, Option<&mut Live>),
    (epoch, clock): (Instant, Clock),
    end_s: Option<f64>,
    stop: &AtomicBool,
    status_line: bool,
) -> (Timing, String) {
    let period_s = args.period_ms / 1000.0;
    // Real time between two cycles; a late cycle counts as an overrun against this.
    let period = Duration::from_secs_f64(period_s / clock.speed);
    let period_ns = period.as_nanos() as u64;
    let mut timing = Timing {
        samples: Vec::with_capacity(1 << 20),
        late_max_us: 0.0,
        overruns: 0,
        histogram: [0; 6],
        wall_s: 0.0,
        cpu_percent: None,
    };
    // A live source stamps values on the real clock since the epoch, so the service's clock is
    // that one and the first deadline is the first after start-up (the time spent loading is
    // not a backlog of cycles). Recorded sources alone start their data clock at the first
    // cycle, which then sees their first row whatever the loading took.
    let (start, mut k): (Instant, u64) = if args.fast || !clock.live {
        (Instant::now(), 0)
    } else {
        let k = (Instant::now().saturating_duration_since(epoch).as_nanos() as u64)
            .div_ceil(period_ns.max(1));
        (epoch, k)
    };
    // A status line every second of real time at the run's pace.
    let status_every_s = clock.speed.max(1.0);
    let mut next_status = status_every_s;
    let mut last_status = String::new();
    loop {
        let deadline = start + Duration::from_nanos(period_ns.saturating_mul(k));
        let now_s = k as f64 * period_s;
        if !args.fast {
            let now = Instant::now();
            if now < deadline {
                std::thread::sleep(deadline - now);
            }
            let late = Instant::now().saturating_duration_since(deadline);
            let late_us = late.as_secs_f64() * 1e6;
            timing.late_max_us = timing.late_max_us.max(late_us);
            if late > period {
                timing.overruns += 1;
            }
        }
        if stop.load(Ordering::Relaxed) || end_s.is_some_and(|e| now_s > e) {
            break;
        }
        if let Some(report) = host.poll_reload() {
            for (_, file) in &report.reloaded {
                eprintln!("reloaded {}", file.display());
            }
            for (_, why) in &report.failed {
                eprintln!("reload refused, the running model stays: {why}");
            }
        }
        let t0 = Instant::now();
        host.service.cycle(now_s);
        // Nothing computed from here on would reach the axes, nor could it resume bumplessly.
        if host.service.axes_unreachable().is_some() {
            break;
        }
        let took = t0.elapsed().as_micros().min(u32::MAX as u128) as u32;
        if timing.samples.len() < timing.samples.capacity() {
            timing.samples.push(took);
        }
        if !args.fast {
            let done_late_us = Instant::now()
                .saturating_duration_since(deadline)
                .as_secs_f64()
                * 1e6;
            let bucket = LATENESS_EDGES_US
                .iter()
                .position(|&e| done_late_us < e)
                .unwrap_or(LATENESS_EDGES_US.len());
            timing.histogram[bucket] += 1;
        }
        k += 1;
        if let Some(l) = live.as_deref_mut() {
            l.publish(host, timing.overruns, f64::from(took));
        }
        if now_s >= next_status {
            next_status += status_every_s;
            last_status = status(&host.service, host.model_names(), took);
            last_status += &faults_status(&host.service, host.log_health());
            if status_line {
                eprint!("\r{last_status}\x1b[K");
                let _ = std::io::stderr().flush();
            }
        }
    }
    (timing, last_status)
}

/// The end of a run: JSON (`--json`) or the last status line and the timing figures.
fn summarize(
    args: &RunArgs,
    service: &Service,
    timing: &mut Timing,
    failures: &[String],
    last_status: &str,
    status_line: bool,
) {
    let out = *service.output();
    let (wall_s, cpu_percent) = (timing.wall_s, timing.cpu_percent);
    let p50 = timing.percentile(0.5);
    let p99 = timing.percentile(0.99);
    let max = timing.percentile(1.0);
    if args.json {
        let axis_names = service
            .machine()
            .machine
            .axes
            .iter()
            .map(|a| a.name.clone());
        let v = serde_json::json!({
            "cycles": service.cycles(),
            "service_time_s": out.time_s,
            "wall_time_s": wall_s,
            "cycle_us": { "p50": p50, "p99": p99, "max": max },
            "late_max_us": if args.fast { None } else { Some(timing.late_max_us) },
            "overruns": timing.overruns,
            "cpu_percent_of_one_core": cpu_percent,
            "finished_late_histogram": if args.fast { None } else { Some(serde_json::json!({
                "under_100us": timing.histogram[0],
                "100_250us": timing.histogram[1],
                "250_500us": timing.histogram[2],
                "500us_1ms": timing.histogram[3],
                "1_2ms": timing.histogram[4],
                "over_2ms": timing.histogram[5],
            })) },
            "state": state_name(out.state),
            "offsets_um": axis_names.zip(out.offsets()).map(|(a, v)| (a, serde_json::Value::from(*v))).collect::<serde_json::Map<_, _>>(),
            "log_records_dropped": service.records_dropped(),
            "failures": failures,
        });
        println!("{v}");
    } else {
        if !status_line && !last_status.is_empty() {
            eprintln!("{last_status}");
        }
        eprintln!(
            "{} cycles in {wall_s:.1} s; cycle time p50 {p50} µs, p99 {p99} µs, max {max} µs; {} overruns; CPU {}",
            service.cycles(),
            timing.overruns,
            cpu_percent.map_or("unknown".into(), |c| format!("{c:.1} % of one core"))
        );
        if !args.fast {
            eprintln!(
                "finished after the deadline by: <0.1 ms {} | 0.1–0.25 ms {} | 0.25–0.5 ms {} | 0.5–1 ms {} | 1–2 ms {} | ≥2 ms {}",
                timing.histogram[0],
                timing.histogram[1],
                timing.histogram[2],
                timing.histogram[3],
                timing.histogram[4],
                timing.histogram[5]
            );
        }
    }
}

/// What went wrong with the sinks and the log over a run, one sentence each: any failure,
/// even one that recovered, makes the run's exit status non-zero (ARCHITECTURE.md).
fn run_failures(
    service: &Service,
    log: Option<(Result<(), log::LogError>, log::LogHealth)>,
) -> Vec<String> {
    let mut out = Vec::new();
    for (i, h) in service.sink_health().iter().enumerate() {
        let Some(first) = h.first_failure_s else {
            continue;
        };
        let name = service.sink_name(i);
        let now = match h.failing_since_s {
            Some(_) if service.axes_unreachable() == Some(i) => {
                "it drives the axes: the run stopped with this alarm".to_string()
            }
            Some(since) => format!("still failing at the end (since {since:.1} s)"),
            None => "it recovered".to_string(),
        };
        out.push(format!(
            "sink `{name}` failed at {first:.1} s: {}; {now}; {} cycles' output not taken",
            h.reason, h.failed_writes
        ));
    }
    if let Some((result, h)) = log {
        match result {
            Err(e) => out.push(format!("log {e}")),
            Ok(()) => {
                if let Some((t, reason)) = &h.first_failure {
                    out.push(format!(
                        "log: writing failed at {t:.1} s ({reason}) and resumed; {} records and \
                         {} events dropped",
                        h.records_dropped, h.events_dropped
                    ));
                }
            }
        }
    }
    out
}

/// The failing sinks and log, for the status line (empty when all is well).
fn faults_status(service: &Service, log: Option<log::LogHealth>) -> String {
    let mut out = String::new();
    for (i, h) in service.sink_health().iter().enumerate() {
        if h.failing_since_s.is_some() {
            out += &format!(" | sink `{}` FAILING: {}", service.sink_name(i), h.reason);
        }
    }
    if let Some(reason) = log.and_then(|h| h.failing) {
        out += &format!(" | log FAILING: {reason}");
    }
    out
}

/// The status line: time, cycle time, offsets, model per path, sensor health.
fn status(service: &Service, models: &[String], took_us: u32) -> String {
    let out = service.output();
    let m = &service.machine().machine;
    let offsets: Vec<String> = m
        .axes
        .iter()
        .zip(out.offsets())
        .map(|(a, v)| format!("{} {v:+.2}", a.name))
        .collect();
    let paths: Vec<String> = service
        .path_states()
        .iter()
        .enumerate()
        .map(|(p, s)| {
            let what = match s {
                PathState::Model(i) => models.get(*i).cloned().unwrap_or_default(),
                PathState::Holding => "holding".into(),
                PathState::NoModel => "no model".into(),
                PathState::Disabled => "off".into(),
            };
            format!("path {}: {what}", p + 1)
        })
        .collect();
    let health = service.validator().health();
    let good = health.iter().filter(|h| h.is_none()).count();
    let lost: String = (0..service.source_count())
        .filter_map(|i| {
            service
                .source_reason(i)
                .map(|r| format!(" | source {i} lost: {r}"))
        })
        .collect();
    format!(
        "t {:.1} s | cycle {took_us} µs | {} µm | {} | sensors {good}/{} ok | {}{lost}",
        out.time_s,
        offsets.join(" "),
        paths.join(", "),
        health.len(),
        state_name(out.state)
    )
}

pub fn show_log(args: LogArgs) -> Result<(), CliError> {
    if let Some(out) = &args.csv {
        let (names, rows) = log::read_cycles(&args.log, None)?;
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(&names)?;
        for r in &rows {
            w.write_record(r)?;
        }
        let bytes = w
            .into_inner()
            .map_err(|e| csv::Error::from(e.into_error()))?;
        crate::write::write_whole(out, bytes, &[("--log", &args.log)])?;
        eprintln!("{} cycles written to {}", rows.len(), out.display());
        return Ok(());
    }
    let events = log::read_events(&args.log)?;
    let mut out = std::io::stdout().lock();
    let written = if args.json {
        let text = serde_json::to_string(&events)?;
        writeln!(out, "{text}")
    } else {
        events.iter().try_for_each(|e| {
            writeln!(
                out,
                "{:>10.3} s  {:<18} {:<16} {}",
                e.time_s, e.kind, e.subject, e.detail
            )
        })
    };
    match written {
        // The reader (`head`, a pager) has seen enough.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(CliError::Stdout),
    }
}
