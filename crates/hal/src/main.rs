#![forbid(unsafe_code)]
//! `truepos-hal`: the `truepos` userspace HAL component (`loadusr -W truepos-hal run …`) and
//! the end-to-end check of what LinuxCNC applied (`truepos-hal check …`).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::{Parser, Subcommand};
use truepos_hal::check::{check, load_samples, CheckConfig};
use truepos_hal::ffi::Component;
use truepos_hal::{pins, Compensator, CompensatorConfig, Event, HalSink, HalSource};
use truepos_io::machine_file::MachineFile;
use truepos_model::Model;
use truepos_runtime::{Frame, Sink, Source};

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
    /// After a sensor fault, ramp the held offsets to zero over this time (s).
    #[arg(long, default_value_t = 10.0)]
    hold_ramp_s: f64,
    /// Append events as JSON lines to this file.
    #[arg(long)]
    events: Option<PathBuf>,
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

fn event_json(e: &Event, machine: &MachineFile) -> serde_json::Value {
    use serde_json::json;
    match *e {
        Event::Fault { time_s, error } => {
            json!({"time_s": time_s, "kind": "fault", "reason": error.to_string(),
                   "channel": fault_channel(&error, machine)})
        }
        Event::Recovered { time_s } => json!({"time_s": time_s, "kind": "recovered"}),
        Event::ModelSwitch { time_s, from, to } => {
            json!({"time_s": time_s, "kind": "model-switch", "from": from, "to": to})
        }
        Event::NoSuchModel { time_s, requested } => {
            json!({"time_s": time_s, "kind": "no-such-model", "requested": requested})
        }
        Event::Clamped {
            time_s,
            axis,
            wanted_um,
            sent_um,
        } => json!({"time_s": time_s, "kind": "clamped",
                    "axis": machine.machine.axes.get(axis).map(|a| a.name.clone()),
                    "wanted_um": wanted_um, "sent_um": sent_um}),
        Event::Enabled { time_s, on } => json!({"time_s": time_s, "kind": "enabled", "on": on}),
    }
}

fn fault_channel(error: &truepos_model::EvalError, machine: &MachineFile) -> Option<String> {
    use truepos_model::EvalError as E;
    let m = &machine.machine;
    match *error {
        E::NonFiniteTemperature { channel } | E::TemperatureOutOfRange { channel, .. } => {
            m.temperatures.get(channel).map(|t| t.id.clone())
        }
        E::NonFinitePosition { axis }
        | E::PositionOutsideTravel { axis, .. }
        | E::NonFiniteResult { axis } => m.axes.get(axis).map(|a| a.name.clone()),
        E::InputLength { input, .. } => Some(input.to_string()),
    }
}

/// Writes events off the cycle: the cycle `try_send`s into a bounded channel (preallocated,
/// never blocks); this thread formats and appends them.
fn event_writer(rx: Receiver<Event>, machine: MachineFile, path: Option<PathBuf>) {
    let mut file = path.and_then(|p| {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&p)
            .map_err(|e| eprintln!("truepos-hal: cannot open events file {}: {e}", p.display()))
            .ok()
    });
    for e in rx {
        let line = event_json(&e, &machine).to_string();
        eprintln!("truepos-hal: event {line}");
        if let Some(f) = file.as_mut() {
            let _ = writeln!(f, "{line}");
            let _ = f.flush();
        }
    }
}

/// Histogram bucket edges of the cycle-to-cycle interval, ms.
const EDGES_MS: [f64; 8] = [0.5, 0.9, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0];

fn run(args: RunArgs) -> Result<(), Box<dyn std::error::Error>> {
    let (machine, models) = load(&args.machine, &args.models)?;
    if !(args.period_ms > 0.0 && args.period_ms <= 1000.0) {
        return Err(format!("--period-ms {} must lie in (0, 1000]", args.period_ms).into());
    }
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))?;

    let component = Component::new(&args.name)?;
    let all = pins::create(&component, &machine.machine)?;
    let control = all.control;
    let mut source = HalSource::new(&args.name, all.inputs);
    let mut sink = HalSink::new(&args.name, all.outputs);
    control.enable.set(true);
    component.ready()?;

    let m = &machine.machine;
    let mut frame = Frame::new(m.temperatures.len(), m.axes.len(), m.operating.len());
    let mut compensator = Compensator::new(
        models,
        CompensatorConfig {
            limits: machine.axis_runtime.clone(),
            hold_ramp_s: args.hold_ramp_s,
            period_s: args.period_ms / 1000.0,
        },
    );
    let (tx, rx) = sync_channel::<Event>(1024);
    let writer = {
        let machine = machine.clone();
        let path = args.events.clone();
        std::thread::spawn(move || event_writer(rx, machine, path))
    };
    eprintln!(
        "truepos-hal: component {} ready, {} axes, {} temperatures, {} model(s), {} ms",
        args.name,
        m.axes.len(),
        m.temperatures.len(),
        args.models.len(),
        args.period_ms
    );

    if args.rt_priority > 0 {
        match truepos_hal::ffi::set_realtime_priority(args.rt_priority) {
            Ok(()) => eprintln!("truepos-hal: SCHED_FIFO priority {}", args.rt_priority),
            Err(e) => eprintln!("truepos-hal: warning: no realtime priority: {e}"),
        }
    }
    let period = Duration::from_secs_f64(args.period_ms / 1000.0);
    let start = Instant::now();
    let mut next = start;
    let mut last = start;
    let mut cycles: u64 = 0;
    let mut histogram = [0u64; EDGES_MS.len() + 1];
    let mut max_interval_ms = 0.0f64;
    let mut max_work_us = 0.0f64;
    let mut dropped_events = 0u64;
    let mut was_ready = false;
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if cycles > 0 {
            let interval_ms = (now - last).as_secs_f64() * 1000.0;
            let bucket = EDGES_MS.iter().position(|&e| interval_ms < e);
            histogram[bucket.unwrap_or(EDGES_MS.len())] += 1;
            max_interval_ms = max_interval_ms.max(interval_ms);
        }
        last = now;
        frame.time_s = (now - start).as_secs_f64();
        let _ = source.read(&mut frame);
        // LinuxCNC takes offsets only with motion enabled and every joint homed; when it starts
        // to, walk from what it holds (0 after machine-on) rather than jump.
        let ready = sink.control_ready();
        if ready && !was_ready {
            compensator.restart_from(&sink.requested_um());
        }
        was_ready = ready;
        let output = compensator.step(
            &frame,
            control.enable.get() && ready,
            control.model_select.get(),
            |e| {
                if let Err(TrySendError::Full(_)) = tx.try_send(e) {
                    dropped_events += 1;
                }
            },
        );
        let _ = sink.write(&output);
        cycles += 1;
        let work_us = now.elapsed().as_secs_f64() * 1e6;
        max_work_us = max_work_us.max(work_us);
        sink.set_cycle_stats(work_us, cycles);

        next += period;
        let after = Instant::now();
        if next > after {
            std::thread::sleep(next - after);
        } else if after - next > period * 10 {
            // Far behind (the process was stopped): start afresh rather than race.
            next = after;
        }
    }

    // Bumpless stop: walk the offsets to zero at the envelope's rate before leaving HAL.
    let ramp_start = Instant::now();
    let mut frame_disabled = frame.clone();
    loop {
        let now = Instant::now();
        frame_disabled.time_s = (now - start).as_secs_f64();
        let _ = source.read(&mut frame_disabled);
        let output = compensator.step(
            &frame_disabled,
            false,
            compensator.active_model() as i32,
            |_| {},
        );
        let _ = sink.write(&output);
        if output.offsets().iter().all(|o| o.abs() < 1e-9)
            || ramp_start.elapsed() > Duration::from_secs(5)
        {
            break;
        }
        std::thread::sleep(period);
    }
    drop(tx);
    let _ = writer.join();

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
        "dropped_events": dropped_events,
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
    let report = check(
        &machine.machine,
        &models,
        &machine.axis_runtime,
        &samples,
        &config,
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json())?);
    } else {
        println!(
            "{} servo cycles, {} compared with the model; joint = nominal + eoffset within {:.2e} mm",
            report.samples, report.compared, report.joint_mismatch_mm
        );
        println!(
            "applied − model: max {:.4} µm, rms {:.4} µm; lag error {:.4} % of the position-dependent span (limit {} %)",
            report.max_diff_um,
            report.rms_diff_um,
            report.max_lag_fraction * 100.0,
            config.max_lag_fraction * 100.0
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
            "{} cycles holding after a sensor fault, {} model switch(es)",
            report.holding_samples, report.model_switches
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
