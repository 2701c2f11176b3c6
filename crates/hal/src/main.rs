#![forbid(unsafe_code)]
//! `truepos-hal`: the `truepos` userspace HAL component (`loadusr -W truepos-hal run …`). Its
//! development tools — the judge of the LinuxCNC end-to-end test and the timing benchmark of
//! the cycle — are `truepos-hal-check` (`crates/hal-check`), not shipped with it.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::{Parser, Subcommand};
use truepos_fleet::MqttOptions;
use truepos_hal::ffi::{self, Component, HalError};
use truepos_hal::pacer::{keep_off_cpu, realtime_setup, Pacer};
use truepos_hal::source::Edge;
use truepos_hal::{pins, Error, HalSink, HalSource};
use truepos_io::limits::{finite_in, int_in};
use truepos_io::model_file::signature::TrustedKeys;
use truepos_io::model_file::{load_entry_trusted, load_set_trusted};
use truepos_live::host::{HttpArgs, HttpOptions, Live};
use truepos_runtime::admission;
use truepos_runtime::host::ReloadSetup;
use truepos_runtime::{MachineConfig, PathState, Running, Service, ServiceConfig, ServiceHost};

#[derive(Parser)]
#[command(
    name = "truepos-hal",
    version,
    about = "truepos beside LinuxCNC: the `truepos` HAL component"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Create the HAL component and compensate every cycle until SIGTERM (for `loadusr -W`).
    Run(RunArgs),
}

#[derive(clap::Args)]
struct RunArgs {
    /// Machine description (TOML), with the safety envelope per axis.
    #[arg(long)]
    machine: PathBuf,
    /// Model file; repeat for several (`truepos.model-select` picks one, 0-based).
    #[arg(long = "model", required = true)]
    models: Vec<PathBuf>,
    /// A list of public keys (one in hex a line, from `truepos sign --new-key`): every model
    /// must then carry a signature (MODEL.sig) by one of them, at start and at every reload.
    #[arg(long, value_name = "FILE")]
    trusted_keys: Option<PathBuf>,
    /// HAL component name.
    #[arg(long, default_value = "truepos")]
    name: String,
    /// Cycle period in ms, 0.1–1000.
    #[arg(long, default_value_t = 1.0, value_parser = finite_in(0.1, 1000.0))]
    period_ms: f64,
    /// With no valid model left after a sensor fault, ramp the held offsets to zero over this
    /// time (s), 0–86 400.
    #[arg(long, default_value_t = 60.0, value_parser = finite_in(0.0, 86_400.0))]
    hold_ramp_s: f64,
    /// Blend time of model switches and of switching compensation on or off (s), 0–3600.
    #[arg(long, default_value_t = 5.0, value_parser = finite_in(0.0, 3600.0))]
    blend_s: f64,
    /// SQLite log (WAL) of inputs, outputs and events, readable with `truepos log`.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Write cycle-timing figures as JSON to this file on exit.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Run the cycle thread under SCHED_FIFO at this priority (1–99; needs root or
    /// CAP_SYS_NICE). 0 keeps normal scheduling.
    #[arg(long, default_value_t = 0, value_parser = int_in(0i32, 99))]
    rt_priority: i32,
    /// Bind the cycle thread to this CPU, 0–1023 (leave unset beside LinuxCNC's own realtime
    /// thread unless that is bound elsewhere).
    #[arg(long, value_parser = int_in(0usize, 1023))]
    cpu: Option<usize>,
    #[command(flatten)]
    http: HttpOptions,
    #[command(flatten)]
    mqtt: MqttOptions,
}

/// Histogram bucket edges of the cycle-to-cycle interval, ms.
const EDGES_MS: [f64; 8] = [0.5, 0.9, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0];

/// The pins the cycle loop reads and writes itself (the sink writes the offsets).
struct LoopPins {
    control: pins::ControlPins,
    cycle_us: ffi::FloatPin,
    cycles: ffi::S32Pin,
    motion_enabled: ffi::BitPin,
    all_homed: ffi::BitPin,
    path_models: Vec<ffi::S32Pin>,
}

/// Creates the component's pins, and the HAL source and sink on them.
fn create_pins(
    component: &Component,
    name: &str,
    machine: &MachineConfig,
) -> Result<(HalSource, HalSink, LoopPins), HalError> {
    let paths = machine
        .axes
        .iter()
        .map(|a| a.path as usize)
        .max()
        .unwrap_or(1)
        .clamp(1, truepos_runtime::service::MAX_PATHS);
    let all = pins::create(component, &machine.machine, paths)?;
    let loop_pins = LoopPins {
        control: all.control,
        cycle_us: all.outputs.cycle_us.clone(),
        cycles: all.outputs.cycles.clone(),
        motion_enabled: all.outputs.motion_enabled.clone(),
        all_homed: all.outputs.all_homed.clone(),
        path_models: all.outputs.path_models.clone(),
    };
    let source = HalSource::new(name, all.inputs, &machine.axes);
    let sink = HalSink::new(name, all.outputs);
    Ok((source, sink, loop_pins))
}

/// Figures of the cycle loop.
struct LoopStats {
    /// Monotonic time of the service's zero, ns.
    start: u64,
    cycles: u64,
    skipped: u64,
    histogram: [u64; EDGES_MS.len() + 1],
    max_interval_ms: f64,
    max_work_us: f64,
    cpu_percent: f64,
}

fn run(args: RunArgs) -> Result<(), Error> {
    let period_s = args.period_ms / 1000.0;
    let Checked {
        http,
        mqtt,
        machine,
        trusted,
        entries,
    } = check_before_hal(&args, period_s)?;

    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))
        .map_err(Error::Signal)?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))
        .map_err(Error::Signal)?;

    let component = Component::new(&args.name)?;
    let (source, sink, loop_pins) = create_pins(&component, &args.name, &machine)?;
    loop_pins.control.enable.set(true);
    component.ready()?;

    let config = ServiceConfig {
        blend_s: args.blend_s,
        hold_ramp_s: args.hold_ramp_s,
        ..ServiceConfig::default()
    };
    // The logger thread inherits the CPUs of this one: keep it off the cycle's CPU.
    if let Some(cpu) = args.cpu {
        if let Err(e) = keep_off_cpu(cpu) {
            eprintln!("truepos-hal: warning: {e}");
        }
    }
    // `truepos.model.reload`: the files are read on the reload thread, never in the cycle.
    let loader_machine = machine.clone();
    let reload = ReloadSetup {
        files: args.models.clone(),
        loader: Box::new(move |path| {
            load_entry_trusted(path, &loader_machine, trusted.as_ref()).map_err(|e| e.to_string())
        }),
        watch: false,
    };
    let source_names = vec![truepos_runtime::Source::name(&source).to_string()];
    let mut host = ServiceHost::new(machine, entries)
        .period_s(period_s)
        .reload(Some(reload))
        .source(Box::new(source))
        .sink(Box::new(sink))
        .config(config)
        .log(args.log.clone())
        .start()?;
    let m = &host.service.machine().machine;
    eprintln!(
        "truepos-hal: component {} ready, {} axes, {} temperatures, models {:?}, {} ms",
        args.name,
        m.axes.len(),
        m.temperatures.len(),
        host.model_names(),
        args.period_ms
    );
    // The live view's threads, like the logger's, start before the cycle thread's priority.
    let mut live = match http {
        Some(h) => Some(
            Live::start(h, &host, source_names, args.log.as_ref(), &args.models)
                .map_err(Error::Refused)?,
        ),
        None => None,
    };
    // Like the logger's and the live view's, before the cycle thread's priority.
    let publisher = match mqtt {
        Some(c) => Some(truepos_fleet::Publisher::start(c).map_err(Error::Refused)?),
        None => None,
    };
    // After the logger has started, so that its thread inherits neither priority nor CPU.
    let setup = realtime_setup(args.rt_priority, args.cpu);
    if let Some(p) = setup.fifo_priority {
        eprintln!("truepos-hal: SCHED_FIFO priority {p}, memory locked");
    }
    for e in &setup.errors {
        eprintln!("truepos-hal: warning: {e}");
    }

    let period_ns = (args.period_ms * 1e6).round() as u64;
    let s = cycle_loop(&mut host, live.as_mut(), &loop_pins, period_ns, &stop);
    if let Some(l) = live {
        l.stop(&host, s.skipped);
    }
    // Bumpless stop: blend the offsets to zero before leaving HAL.
    ramp_to_zero(&mut host.service, s.start, period_ns, args.blend_s);
    let stopped = host.stop();
    if let Some(p) = publisher {
        let m = p.stop(std::time::Duration::from_secs(10));
        eprintln!(
            "truepos-hal: mqtt: {} of {} messages acknowledged, caught up: {}",
            m.acknowledged, m.published, m.caught_up
        );
    }
    if let Some((result, _)) = stopped.log {
        result?;
    }

    report_stats(&args, &s, stopped.service.events().dropped())
}

/// What `run` reads and checks before HAL is touched, so that `loadusr -W` sees a refusal and
/// no pins appear.
struct Checked {
    http: Option<HttpArgs>,
    mqtt: Option<truepos_fleet::Config>,
    machine: MachineConfig,
    trusted: Option<TrustedKeys>,
    entries: Vec<truepos_runtime::model_set::ModelEntry>,
}

/// Checks the live view's and the fleet's addresses, reads the machine file and the models
/// (with their signatures if keys are trusted) and admits the models at this period; the host
/// admits again at start and at every reload.
fn check_before_hal(args: &RunArgs, period_s: f64) -> Result<Checked, Error> {
    // A live view beyond loopback without a token is refused here.
    let http = args.http.check().map_err(Error::Refused)?;
    // As the live view's address.
    let mqtt = args
        .mqtt
        .config(args.log.as_deref())
        .map_err(Error::Refused)?;
    let machine = truepos_io::machine_file::load(&args.machine)?;
    // A channel id that is no pin name is the machine file's mistake.
    pins::check_names(&machine.machine)?;
    // A model without an axis-combination index in its file serves path 1's axes.
    let trusted = args
        .trusted_keys
        .as_deref()
        .map(TrustedKeys::load)
        .transpose()?;
    let entries = load_set_trusted(&args.models, &machine, trusted.as_ref())?;
    admission::admit_set(&entries, &machine, period_s).map_err(Error::Refused)?;
    Ok(Checked {
        http,
        mqtt,
        machine,
        trusted,
        entries,
    })
}

/// The cycle loop's figures on stopping, as JSON on standard error and, with `--stats`, in a
/// file (the LinuxCNC end-to-end script reads it).
fn report_stats(args: &RunArgs, s: &LoopStats, events_dropped: u64) -> Result<(), Error> {
    let late = s.histogram[EDGES_MS.iter().position(|&e| e == 2.0).unwrap_or(0) + 1..]
        .iter()
        .sum::<u64>();
    let stats = serde_json::json!({
        "cycles": s.cycles,
        "period_ms": args.period_ms,
        "interval_histogram_ms": {
            "edges": EDGES_MS,
            "counts": s.histogram,
        },
        "intervals_over_2ms": late,
        "deadlines_skipped": s.skipped,
        "max_interval_ms": s.max_interval_ms,
        "max_work_us": s.max_work_us,
        "cpu_percent_of_one_core": s.cpu_percent,
        "events_dropped": events_dropped,
    });
    eprintln!("truepos-hal: stopped after {} cycles: {stats}", s.cycles);
    if let Some(p) = &args.stats {
        truepos_files::write::write_whole(p, format!("{stats}\n").as_bytes(), &[])
            .map_err(|e| Error::Stats(std::io::Error::other(e.to_string())))?;
    }
    Ok(())
}

/// Compensates every period until `stop`: reads the control pins, runs the cycle, writes the
/// loop's own output pins.
fn cycle_loop(
    host: &mut Running,
    mut live: Option<&mut Live>,
    pins: &LoopPins,
    period_ns: u64,
    stop: &AtomicBool,
) -> LoopStats {
    let model_count = host.model_names().len();
    let mut reload_edge = Edge::default();
    let mut reloads: i32 = 0;
    let cpu_start = ffi::process_cpu_ns();
    let start = ffi::monotonic_ns();
    let mut pacer = Pacer::new(start, period_ns);
    let mut last = start;
    let mut s = LoopStats {
        start,
        cycles: 0,
        skipped: 0,
        histogram: [0u64; EDGES_MS.len() + 1],
        max_interval_ms: 0.0,
        max_work_us: 0.0,
        cpu_percent: 0.0,
    };
    let mut selected = -1;
    while !stop.load(Ordering::Relaxed) {
        let now = pacer.wait();
        if s.cycles > 0 {
            let interval_ms = (now - last) as f64 / 1e6;
            let bucket = EDGES_MS.iter().position(|&e| interval_ms < e);
            s.histogram[bucket.unwrap_or(EDGES_MS.len())] += 1;
            s.max_interval_ms = s.max_interval_ms.max(interval_ms);
        }
        last = now;
        // LinuxCNC takes offsets only with motion enabled and every joint homed (the sink holds
        // its counts meanwhile); compensation is off until then and blends in afterwards.
        let ready = pins.motion_enabled.get() && pins.all_homed.get();
        if reload_edge.rising(pins.control.reload.get()) {
            host.request_reload();
        }
        if let Some(report) = host.poll_reload() {
            reloads = reloads.wrapping_add(report.reloaded.len() as i32);
            pins.control.reloads.set(reloads);
            for (_, file) in &report.reloaded {
                eprintln!("truepos-hal: reloaded {}", file.display());
            }
            for (_, why) in &report.failed {
                eprintln!("truepos-hal: reload refused, the running model stays: {why}");
            }
        }
        let service = &mut host.service;
        service.set_enabled(pins.control.enable.get() && ready);
        let select = pins.control.model_select.get();
        if select != selected {
            selected = select;
            let preferred = usize::try_from(select).ok().filter(|&i| i < model_count);
            service.prefer_model(0, preferred);
        }
        // The time of reading, not the deadline: LinuxCNC's positions are those of now.
        service.cycle((now - start) as f64 * 1e-9);
        for (pin, state) in pins.path_models.iter().zip(service.path_states()) {
            pin.set(match state {
                PathState::Model(i) => i32::try_from(*i).unwrap_or(-1),
                _ => -1,
            });
        }
        s.cycles += 1;
        let after = ffi::monotonic_ns();
        let work_us = (after - now) as f64 / 1e3;
        s.max_work_us = s.max_work_us.max(work_us);
        pins.cycle_us.set(work_us);
        pins.cycles.set(s.cycles as u32 as i32);
        if let Some(l) = live.as_deref_mut() {
            // Between cycles: at most every 50 ms a copy into atomics, no allocation.
            l.publish(host, s.skipped, work_us);
        }

        pacer.advance();
        if after > pacer.deadline_ns() {
            // Behind (the host held the process up): act on the next deadline with current
            // values rather than race through the missed ones.
            s.skipped += pacer.skip_to(after);
        }
    }
    let wall_ns = (ffi::monotonic_ns() - start) as f64;
    // Every thread of the process, the SQLite logger included.
    s.cpu_percent = (ffi::process_cpu_ns() - cpu_start) as f64 / wall_ns.max(1.0) * 100.0;
    s
}

/// Blends the offsets to zero (compensation off), giving up after the blend time and a second.
fn ramp_to_zero(service: &mut Service, start: u64, period_ns: u64, blend_s: f64) {
    let period = Duration::from_nanos(period_ns);
    service.set_enabled(false);
    let ramp_start = std::time::Instant::now();
    loop {
        let now = ffi::monotonic_ns();
        let out = service.cycle((now - start) as f64 * 1e-9);
        if out.offsets().iter().all(|o| o.abs() < 1e-9)
            || ramp_start.elapsed() > Duration::from_secs_f64(blend_s + 1.0)
        {
            break;
        }
        std::thread::sleep(period);
    }
}

fn main() -> ExitCode {
    let Command::Run(args) = Cli::parse().command;
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("truepos-hal: error: {e}");
            ExitCode::FAILURE
        }
    }
}
