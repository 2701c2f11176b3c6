#![forbid(unsafe_code)]
//! `truepos-hal`: the `truepos` userspace HAL component (`loadusr -W truepos-hal run …`) and
//! the end-to-end check of what LinuxCNC applied (`truepos-hal check …`), and the timing
//! benchmark of its cycle (`truepos-hal timing …`, no LinuxCNC needed).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::{Parser, Subcommand};
use truepos_hal::check::{check, load_samples, CheckConfig};
use truepos_hal::ffi::{self, Component};
use truepos_hal::pacer::{keep_off_cpu, realtime_setup, Pacer};
use truepos_hal::timing::{self, TimingConfig};
use truepos_hal::{pins, HalSink, HalSource};
use truepos_io::limits::{finite_in, int_in};
use truepos_runtime::model_set::load_entries;
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
    /// Compare what LinuxCNC applied (halsampler files) with the models and the envelope.
    Check(CheckArgs),
    /// The cycle's timing without LinuxCNC: the service at a fixed period on the component's
    /// pacing, replaying a run, with the host's steal time sampled beside it; prints JSON.
    Timing(TimingArgs),
}

#[derive(clap::Args)]
struct TimingArgs {
    /// Machine description (TOML).
    #[arg(long, default_value = "examples/vmc3/machine.toml")]
    machine: PathBuf,
    /// Model file; repeat for a set.
    #[arg(long = "model", default_value = "examples/vmc3/model.toml")]
    models: Vec<PathBuf>,
    /// Recorded run replayed in real time as the source.
    #[arg(long, default_value = "examples/vmc3/run.csv")]
    run: PathBuf,
    /// SQLite log of the service (as in production); none if not given.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Length of the run in s, 0.001–86 400.
    #[arg(long, default_value_t = 600.0, value_parser = finite_in(0.001, 86_400.0))]
    duration_s: f64,
    /// Cycle period in ms, 0.1–1000.
    #[arg(long, default_value_t = 1.0, value_parser = finite_in(0.1, 1000.0))]
    period_ms: f64,
    /// SCHED_FIFO priority of the cycle, 0–99 (0: normal scheduling).
    #[arg(long, default_value_t = 50, value_parser = int_in(0i32, 99))]
    rt_priority: i32,
    /// CPU to bind the cycle to, 0–1023 (default: the last one).
    #[arg(long, value_parser = int_in(0usize, 1023))]
    cpu: Option<usize>,
    /// Interval of the steal-time sampling in ms, 0.1–60 000.
    #[arg(long, default_value_t = 5.0, value_parser = finite_in(0.1, 60_000.0))]
    sample_ms: f64,
    /// A cycle finishing more than this after its deadline is late (ms), 0.01–60 000.
    #[arg(long, default_value_t = 2.0, value_parser = finite_in(0.01, 60_000.0))]
    late_ms: f64,
}

#[derive(clap::Args)]
struct RunArgs {
    /// Machine description (TOML), with the safety envelope per axis.
    #[arg(long)]
    machine: PathBuf,
    /// Model file; repeat for several (`truepos.model-select` picks one, 0-based).
    #[arg(long = "model", required = true)]
    models: Vec<PathBuf>,
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
}

#[derive(clap::Args)]
struct CheckArgs {
    /// Machine description (TOML).
    #[arg(long)]
    machine: PathBuf,
    /// The model files, in the order given to `run`.
    #[arg(long = "model", required = true)]
    models: Vec<PathBuf>,
    /// `halsampler -t` output of the motion sampler.
    #[arg(long)]
    motion: PathBuf,
    /// `halsampler -t` output of the temperature sampler.
    #[arg(long)]
    temperatures: PathBuf,
    /// Servo period in ms, 0.1–1000.
    #[arg(long, default_value_t = 1.0, value_parser = finite_in(0.1, 1000.0))]
    period_ms: f64,
    /// The component's `--hold-ramp-s` (a held offset ramps to zero over it), s.
    #[arg(long, default_value_t = 60.0)]
    hold_ramp_s: f64,
    /// The component's SQLite log, for `--expect-event`.
    #[arg(long)]
    log: Option<PathBuf>,
    /// An event the log must hold: `kind`, `kind:subject` or `kind:subject:text in the detail`
    /// (e.g. `sensor-fault:x_slide_bottom`, `model-selected:path 1:vmc3-e2e-alternative`).
    #[arg(long = "expect-event")]
    expect_events: Vec<String>,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
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
) -> Result<(HalSource, HalSink, LoopPins), Box<dyn std::error::Error>> {
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

fn run(args: RunArgs) -> Result<(), Box<dyn std::error::Error>> {
    let machine = truepos_io::machine_file::load(&args.machine)?;
    // Seed D: a model without an index in its file serves path 1's axes.
    let entries = load_entries(&args.models, &machine)?;

    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))?;

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
    let mut host = ServiceHost::new(machine, entries)
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
    // After the logger has started, so that its thread inherits neither priority nor CPU.
    let setup = realtime_setup(args.rt_priority, args.cpu);
    if let Some(p) = setup.fifo_priority {
        eprintln!("truepos-hal: SCHED_FIFO priority {p}, memory locked");
    }
    for e in &setup.errors {
        eprintln!("truepos-hal: warning: {e}");
    }

    let period_ns = (args.period_ms * 1e6).round() as u64;
    let s = cycle_loop(&mut host, &loop_pins, period_ns, &stop);
    // Bumpless stop: blend the offsets to zero before leaving HAL.
    ramp_to_zero(&mut host.service, s.start, period_ns, args.blend_s);
    let stopped = host.stop();
    if let Some((result, _)) = stopped.log {
        result?;
    }

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
        "events_dropped": stopped.service.events().dropped(),
    });
    eprintln!("truepos-hal: stopped after {} cycles: {stats}", s.cycles);
    if let Some(p) = &args.stats {
        std::fs::write(p, format!("{stats}\n"))?;
    }
    Ok(())
}

/// Compensates every period until `stop`: reads the control pins, runs the cycle, writes the
/// loop's own output pins.
fn cycle_loop(host: &mut Running, pins: &LoopPins, period_ns: u64, stop: &AtomicBool) -> LoopStats {
    let model_count = host.model_names().len();
    let service = &mut host.service;
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

fn run_check(args: CheckArgs) -> Result<bool, Box<dyn std::error::Error>> {
    let machine = truepos_io::machine_file::load(&args.machine)?;
    // With their axis-combination indices: the check applies seed D's rule itself.
    let models = load_entries(&args.models, &machine)?;
    let samples = load_samples(&args.motion, &args.temperatures, &machine.machine)?;
    let config = CheckConfig {
        period_s: args.period_ms / 1000.0,
        hold_ramp_s: args.hold_ramp_s,
        ..CheckConfig::default()
    };
    let mut report = check(&machine.machine, &models, &machine.axes, &samples, &config);
    if !args.expect_events.is_empty() {
        let Some(log) = &args.log else {
            return Err("--expect-event needs --log".into());
        };
        let events = truepos_runtime::log::read_events(log)?;
        if !args.json {
            for e in &events {
                println!(
                    "event {:10.3} s  {:18} {:22} {}",
                    e.time_s, e.kind, e.subject, e.detail
                );
            }
        }
        for want in &args.expect_events {
            let mut parts = want.splitn(3, ':');
            let kind = parts.next().unwrap_or_default();
            let subject = parts.next();
            let detail = parts.next();
            let found = events.iter().any(|e| {
                e.kind == kind
                    && subject.is_none_or(|s| e.subject == s)
                    && detail.is_none_or(|d| e.detail.contains(d))
            });
            if !found {
                report
                    .failures
                    .push(format!("the log {} holds no event {want}", log.display()));
            }
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json())?);
    } else {
        println!(
            "{} servo cycles, {} compared with the model; joint = nominal + eoffset within {:.2e} mm",
            report.samples, report.compared, report.joint_mismatch_mm
        );
        println!(
            "applied − model: max {:.4} µm, rms {:.4} µm; lag error {:.4} % of the position-dependent span at 1 kHz updates (limit {} %), {:.4} % including update gaps",
            report.max_diff_um,
            report.rms_diff_um,
            report.max_lag_fraction * 100.0,
            config.max_lag_fraction * 100.0,
            report.max_lag_fraction_all * 100.0
        );
        println!(
            "largest offset {:.2} µm; fastest axis {:.0} mm/min; offset rate per axis {:?} µm/s (envelope {:?})",
            report.max_offset_um,
            report.max_feed_mm_per_min,
            report
                .max_rate_um_per_s
                .iter()
                .map(|r| (r * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            report.rate_limit_um_per_s
        );
        println!(
            "{} cycles holding after a sensor fault, {} model switch(es), {} axis switch(es) ({} settled cycles on another model than seed D selects, {:.3} µm largest offset on an axis in no path); update gaps: {:.3} % of moving cycles, longest {} servo cycles; {} moving cycles in step",
            report.holding_samples,
            report.model_switches,
            report.axis_switches,
            report.wrong_model_cycles,
            report.max_parked_offset_um,
            report.gap_fraction * 100.0,
            report.longest_update_gap_cycles,
            report.in_step_moving_cycles
        );
        let inv = &report.invariant;
        let round = |v: &[f64], k: f64| v.iter().map(|x| (x * k).round() / k).collect::<Vec<_>>();
        println!(
            "output invariant on the applied offsets, per axis: largest |offset| {:?} µm; largest step {:?} µm, {:?} of the envelope's rate over the real time; outside the bracket (from, target) by at most {:?} µm (limit {} µm); {} non-finite; {} changes of state; {} cycles kept the previous target",
            round(&inv.max_abs_um, 1000.0),
            round(&inv.max_step_um, 1000.0),
            round(&inv.max_step_ratio, 1000.0),
            round(&inv.max_bracket_excess_um, 1000.0),
            config.max_bracket_excess_um,
            inv.nonfinite_cycles,
            inv.state_changes,
            inv.target_kept_cycles
        );
        for f in &report.failures {
            println!("FAIL: {f}");
        }
        println!("{}", if report.passed() { "PASS" } else { "FAIL" });
    }
    Ok(report.passed())
}

fn run_timing(args: TimingArgs) -> Result<bool, Box<dyn std::error::Error>> {
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))?;
    // The last CPU: the kernel and most other work start on the first.
    let cpu = args.cpu.or_else(|| {
        std::thread::available_parallelism()
            .ok()
            .map(|n| n.get() - 1)
    });
    let config = TimingConfig {
        machine: args.machine,
        models: args.models,
        run: args.run,
        log: args.log,
        duration_s: args.duration_s,
        period_ms: args.period_ms,
        rt_priority: args.rt_priority,
        cpu,
        sample_ms: args.sample_ms,
        late_ms: args.late_ms,
    };
    eprintln!(
        "truepos-hal timing: {} s at {} ms, SCHED_FIFO {}, CPU {:?}",
        config.duration_s, config.period_ms, config.rt_priority, config.cpu
    );
    let s = timing::run(&config, &stop)?;
    println!("{}", serde_json::to_string_pretty(&s)?);
    let late = &s["late_cycles"];
    eprintln!(
        "truepos-hal timing: {} cycles; work p50 {} µs, p99 {} µs; CPU {:.2} % of one core; steal {:.2} % of the cycle's CPU",
        s["cycles"],
        s["cycle_work_us"]["p50"],
        s["cycle_work_us"]["p99"],
        s["cpu_percent_of_one_core"].as_f64().unwrap_or(f64::NAN),
        s["host"]["steal_percent_watched_cpu"].as_f64().unwrap_or(f64::NAN),
    );
    eprintln!(
        "truepos-hal timing: late by > {} ms: {} cycles in {} stalls; {} coincide with steal, {} not explained by steal (worst {} ms); a window sees steal by chance {:.1} %",
        late["bar_ms"],
        late["total"],
        late["episodes"],
        late["coinciding_with_steal"],
        late["not_explained_by_steal"],
        late["worst_not_explained_ms"],
        late["chance_a_window_sees_steal"].as_f64().unwrap_or(0.0) * 100.0,
    );
    Ok(true)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run(args).map(|()| true),
        Command::Check(args) => run_check(args),
        Command::Timing(args) => run_timing(args),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("truepos-hal: error: {e}");
            ExitCode::FAILURE
        }
    }
}
