#![forbid(unsafe_code)]
//! `truepos-hal-check`: the HAL component's development tools — the judge of the LinuxCNC
//! end-to-end test (`truepos-hal-check check …`, run by `scripts/linuxcnc_e2e.sh`) and the
//! timing benchmark of the component's cycle (`truepos-hal-check timing …`, no LinuxCNC
//! needed, run by `scripts/cycle_timing.sh`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::{Parser, Subcommand};
use truepos_hal_check::check::{check, events, load_samples, CheckConfig};
use truepos_hal_check::timing::{self, TimingConfig};
use truepos_hal_check::Error;
use truepos_io::limits::{finite_in, int_in};
use truepos_io::model_file::load_set;

#[derive(Parser)]
#[command(
    name = "truepos-hal-check",
    version,
    about = "Development tools of the truepos HAL component: the end-to-end judge and the timing benchmark"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Compare what LinuxCNC applied (halsampler files) with the models and the envelope.
    Check(CheckArgs),
    /// The cycle's timing without LinuxCNC: the service at a fixed period on the component's
    /// pacing, replaying a run, with the host's steal time sampled beside it; prints JSON.
    Timing(TimingArgs),
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

fn run_check(args: CheckArgs) -> Result<bool, Error> {
    let machine = truepos_io::machine_file::load(&args.machine)?;
    // With their axis-combination indices: the check selects by axis combination itself.
    let models = load_set(&args.models, &machine)?;
    let samples = load_samples(&args.motion, &args.temperatures, &machine.machine)?;
    let config = CheckConfig {
        period_s: args.period_ms / 1000.0,
        hold_ramp_s: args.hold_ramp_s,
        ..CheckConfig::default()
    };
    let mut report = check(&machine.machine, &models, &machine.axes, &samples, &config);
    if !args.expect_events.is_empty() {
        let Some(log) = &args.log else {
            return Err(Error::ExpectEventWithoutLog);
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
            if !events::holds(&events, want) {
                report
                    .failures
                    .push(format!("the log {} holds no event {want}", log.display()));
            }
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json())?);
    } else {
        print!("{}", report.text(&config));
    }
    Ok(report.passed())
}

fn run_timing(args: TimingArgs) -> Result<bool, Error> {
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))
        .map_err(Error::Signal)?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))
        .map_err(Error::Signal)?;
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
        "truepos-hal-check timing: {} s at {} ms, SCHED_FIFO {}, CPU {:?}",
        config.duration_s, config.period_ms, config.rt_priority, config.cpu
    );
    let s = timing::run(&config, &stop)?;
    println!("{}", serde_json::to_string_pretty(&s)?);
    let late = &s["late_cycles"];
    eprintln!(
        "truepos-hal-check timing: {} cycles; work p50 {} µs, p99 {} µs; CPU {:.2} % of one core; steal {:.2} % of the cycle's CPU",
        s["cycles"],
        s["cycle_work_us"]["p50"],
        s["cycle_work_us"]["p99"],
        s["cpu_percent_of_one_core"].as_f64().unwrap_or(f64::NAN),
        s["host"]["steal_percent_watched_cpu"].as_f64().unwrap_or(f64::NAN),
    );
    eprintln!(
        "truepos-hal-check timing: late by > {} ms: {} cycles in {} stalls; {} coincide with steal, {} not explained by steal (worst {} ms); a window sees steal by chance {:.1} %",
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
        Command::Check(args) => run_check(args),
        Command::Timing(args) => run_timing(args),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("truepos-hal-check: error: {e}");
            ExitCode::FAILURE
        }
    }
}
