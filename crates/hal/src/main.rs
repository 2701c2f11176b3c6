#![forbid(unsafe_code)]
//! `truepos-hal`: the `truepos` userspace HAL component (`loadusr -W truepos-hal run …`) and
//! the end-to-end check of what LinuxCNC applied (`truepos-hal check …`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::{Parser, Subcommand};
use truepos_hal::check::{check, load_samples, CheckConfig};
use truepos_hal::ffi::Component;
use truepos_hal::{pins, HalSink, HalSource};
use truepos_io::machine_file::MachineFile;
use truepos_model::Model;
use truepos_runtime::log::{LogSetup, Logger};
use truepos_runtime::model_set::load_entries;
use truepos_runtime::{Service, ServiceConfig, Sink, Source};

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
    /// Cycle period in ms.
    #[arg(long, default_value_t = 1.0)]
    period_ms: f64,
    /// With no valid model left after a sensor fault, ramp the held offsets to zero over this
    /// time (s).
    #[arg(long, default_value_t = 60.0)]
    hold_ramp_s: f64,
    /// Blend time of model switches and of switching compensation on or off (s).
    #[arg(long, default_value_t = 5.0)]
    blend_s: f64,
    /// SQLite log (WAL) of inputs, outputs and events, readable with `truepos log`.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Write cycle-timing figures as JSON to this file on exit.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Run the cycle thread under SCHED_FIFO at this priority (1–99; needs root or
    /// CAP_SYS_NICE). 0 keeps normal scheduling.
    #[arg(long, default_value_t = 0)]
    rt_priority: i32,
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
    /// Servo period in ms.
    #[arg(long, default_value_t = 1.0)]
    period_ms: f64,
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

fn load(
    machine: &std::path::Path,
    models: &[PathBuf],
) -> Result<(MachineFile, Vec<Model>), Box<dyn std::error::Error>> {
    let machine = truepos_io::machine_file::load(machine)?;
    let models = models
        .iter()
        .map(|p| truepos_io::model_file::load(p, &machine.machine))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((machine, models))
}

/// CPU time the process has used so far in ns (Linux `/proc/self/schedstat`, first field), if
/// the kernel reports it.
fn cpu_time_ns() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// Histogram bucket edges of the cycle-to-cycle interval, ms.
const EDGES_MS: [f64; 8] = [0.5, 0.9, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0];

fn run(args: RunArgs) -> Result<(), Box<dyn std::error::Error>> {
    if !(args.period_ms > 0.0 && args.period_ms <= 1000.0) {
        return Err(format!("--period-ms {} must lie in (0, 1000]", args.period_ms).into());
    }
    let machine = truepos_io::machine_file::load(&args.machine)?;
    let m = &machine.machine;
    // Seed D: a model without an index in its file serves path 1's axes.
    let entries = load_entries(&args.models, &machine)?;
    let model_names: Vec<String> = entries.iter().map(|e| e.name.clone()).collect();

    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))?;

    let component = Component::new(&args.name)?;
    let all = pins::create(&component, m)?;
    let control = all.control;
    let (cycle_us_pin, cycles_pin) = (all.outputs.cycle_us.clone(), all.outputs.cycles.clone());
    let (motion_enabled, all_homed) = (
        all.outputs.motion_enabled.clone(),
        all.outputs.all_homed.clone(),
    );
    let source = HalSource::new(&args.name, all.inputs);
    let sink = HalSink::new(&args.name, all.outputs);
    let (source_name, sink_name) = (source.name().to_string(), sink.name().to_string());
    control.enable.set(true);
    component.ready()?;

    let axes = m.axes.len();
    let config = ServiceConfig {
        blend_s: args.blend_s,
        hold_ramp_s: args.hold_ramp_s,
        ..ServiceConfig::default()
    };
    let mut service = Service::new(
        machine.clone(),
        entries,
        vec![Box::new(source)],
        vec![Box::new(sink)],
        config,
    );
    let logger = match &args.log {
        Some(path) => Some(Logger::start(
            LogSetup {
                path,
                machine: &machine,
                models: model_names.clone(),
                sources: vec![source_name],
                sinks: vec![sink_name],
                paths: service.path_states().len(),
                commit_every: Duration::from_millis(500),
            },
            service.events(),
            service.records(),
        )?),
        None => None,
    };
    eprintln!(
        "truepos-hal: component {} ready, {axes} axes, {} temperatures, models {:?}, {} ms",
        args.name,
        m.temperatures.len(),
        model_names,
        args.period_ms
    );
    if args.rt_priority > 0 {
        match truepos_hal::ffi::set_realtime_priority(args.rt_priority) {
            Ok(()) => eprintln!("truepos-hal: SCHED_FIFO priority {}", args.rt_priority),
            Err(e) => eprintln!("truepos-hal: warning: no realtime priority: {e}"),
        }
    }

    let period = Duration::from_secs_f64(args.period_ms / 1000.0);
    let cpu_start = cpu_time_ns();
    let start = Instant::now();
    let mut next = start;
    let mut last = start;
    let mut cycles: u64 = 0;
    let mut histogram = [0u64; EDGES_MS.len() + 1];
    let mut max_interval_ms = 0.0f64;
    let mut max_work_us = 0.0f64;
    let mut selected = -1;
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if cycles > 0 {
            let interval_ms = (now - last).as_secs_f64() * 1000.0;
            let bucket = EDGES_MS.iter().position(|&e| interval_ms < e);
            histogram[bucket.unwrap_or(EDGES_MS.len())] += 1;
            max_interval_ms = max_interval_ms.max(interval_ms);
        }
        last = now;
        // LinuxCNC takes offsets only with motion enabled and every joint homed (the sink holds
        // its counts meanwhile); compensation is off until then and blends in afterwards.
        let ready = motion_enabled.get() && all_homed.get();
        service.set_enabled(control.enable.get() && ready);
        let select = control.model_select.get();
        if select != selected {
            selected = select;
            let preferred = usize::try_from(select)
                .ok()
                .filter(|&i| i < model_names.len());
            service.prefer_model(0, preferred);
        }
        service.cycle((now - start).as_secs_f64());
        cycles += 1;
        let work_us = now.elapsed().as_secs_f64() * 1e6;
        max_work_us = max_work_us.max(work_us);
        cycle_us_pin.set(work_us);
        cycles_pin.set(cycles as u32 as i32);

        next += period;
        let after = Instant::now();
        if next > after {
            std::thread::sleep(next - after);
        } else if after - next > period * 10 {
            // Far behind (the process was stopped): start afresh rather than race.
            next = after;
        }
    }

    let wall_ns = start.elapsed().as_secs_f64() * 1e9;
    let cpu_percent = match (cpu_start, cpu_time_ns()) {
        (Some(a), Some(b)) if wall_ns > 0.0 => Some((b - a) / wall_ns * 100.0),
        _ => None,
    };
    // Bumpless stop: blend the offsets to zero before leaving HAL.
    service.set_enabled(false);
    let ramp_start = Instant::now();
    loop {
        let now = Instant::now();
        let out = service.cycle((now - start).as_secs_f64());
        if out.offsets().iter().all(|o| o.abs() < 1e-9)
            || ramp_start.elapsed() > Duration::from_secs_f64(args.blend_s + 1.0)
        {
            break;
        }
        std::thread::sleep(period);
    }
    if let Some(logger) = logger {
        logger.stop()?;
    }

    let late = histogram[EDGES_MS.iter().position(|&e| e == 2.0).unwrap_or(0) + 1..]
        .iter()
        .sum::<u64>();
    let stats = serde_json::json!({
        "cycles": cycles,
        "period_ms": args.period_ms,
        "interval_histogram_ms": {
            "edges": EDGES_MS,
            "counts": histogram,
        },
        "intervals_over_2ms": late,
        "max_interval_ms": max_interval_ms,
        "max_work_us": max_work_us,
        "cpu_percent_of_one_core": cpu_percent,
        "events_dropped": service.events().dropped(),
    });
    eprintln!("truepos-hal: stopped after {cycles} cycles: {stats}");
    if let Some(p) = &args.stats {
        std::fs::write(p, format!("{stats}\n"))?;
    }
    Ok(())
}

fn run_check(args: CheckArgs) -> Result<bool, Box<dyn std::error::Error>> {
    let (machine, models) = load(&args.machine, &args.models)?;
    let samples = load_samples(&args.motion, &args.temperatures, &machine.machine)?;
    let config = CheckConfig {
        period_s: args.period_ms / 1000.0,
        ..CheckConfig::default()
    };
    let mut report = check(
        &machine.machine,
        &models,
        &machine.axis_runtime,
        &samples,
        &config,
    );
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
            "{} cycles holding after a sensor fault, {} model switch(es); update gaps: {:.3} % of moving cycles, longest {} servo cycles",
            report.holding_samples,
            report.model_switches,
            report.gap_fraction * 100.0,
            report.longest_update_gap_cycles
        );
        for f in &report.failures {
            println!("FAIL: {f}");
        }
        println!("{}", if report.passed() { "PASS" } else { "FAIL" });
    }
    Ok(report.passed())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run(args).map(|()| true),
        Command::Check(args) => run_check(args),
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
