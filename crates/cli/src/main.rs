//! `truepos`: the one binary. Each subcommand lives in its own module; this file only parses the
//! command line and dispatches.

#![forbid(unsafe_code)]
// The argument docs are clap's `--help` text, where `<axis>_mm` is the usual placeholder.
#![allow(rustdoc::invalid_html_tags)]

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod demo;
mod envelope_check;
mod error;
mod eval;
mod evaluator;
mod examples;
mod export;
mod fit;
mod fleet;
mod kin;
mod reidentify;
mod report;
mod run;
mod shape;
mod sign;
mod sim;
mod status;
mod update_period;
mod volume_map;
mod write;

/// truepos keeps the tool tip of a CNC machine tool where the program says it is, while the
/// machine warms up, bends and carries geometric errors.
#[derive(Parser)]
#[command(name = "truepos", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job on built-in defaults: the position-dependent thermal model and the prior art
    /// fitted on one day of the thermal twin, compared on another, with a report.
    Demo(demo::Args),
    /// Evaluate a compensation model on a recorded run (CSV of cycles) and write per-axis offsets.
    Eval(eval::Args),
    /// Project a model at one moment of a run onto a control's own compensation form (Siemens
    /// SD43900/43910/43920, HEIDENHAIN 9231 or TEMPCOMP) and write the file that sets it.
    Export(export::Args),
    /// Learn a dynamic compensation model (filtered temperatures and spindle speed, or the
    /// reference-sensor regression) from recorded runs (CSV/XLSX) and validate it honestly.
    Fit(Box<fit::Args>),
    /// The fleet: a service's log to an MQTT broker as Sparkplug B, the store in PostgreSQL,
    /// signed models activated and rolled back, the fleet's status.
    Fleet(fleet::Args),
    /// Kinematics table with error tables: forward/inverse transforms, G-code rewrite.
    Kin(kin::Args),
    /// How often position-dependent terms must be updated: their worst-case error when the axis
    /// moves at full feed and the terms are updated every T ms (the update-period error).
    #[command(alias = "lag")]
    UpdatePeriod(update_period::Args),
    /// Re-identify a model's parameters from probe measurements (the service's log or a run
    /// CSV) and write a new model when the re-estimated parameters are clearly better (exit 3: kept, nothing written).
    Reidentify(reidentify::Args),
    /// Write an HTML report of a model on a run with measured errors (figures, coefficients).
    Report(report::Args),
    /// Show the event log of a running or finished service, or export its cycles as a run CSV.
    Log(run::LogArgs),
    /// Run the cyclic compensation service: sources → validation → model set → envelope → sinks.
    Run(run::RunArgs),
    /// Sign model files with an Ed25519 key (MODEL.sig), or make a new key pair; a service
    /// started with --trusted-keys loads only models signed by a key of its list.
    Sign(sign::Args),
    /// Run the thermal twin on a scenario and write the run as CSV (works with no files).
    Sim(sim::Args),
    /// Show the state of a running or finished service from its log.
    Status(status::StatusArgs),
}

fn main() -> ExitCode {
    // When the reader of our output goes away (`truepos … | head`), stop quietly as a Unix tool
    // does on SIGPIPE, instead of reporting a panic; every other panic is reported as usual.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") {
            std::process::exit(0);
        }
        default_hook(info);
    }));
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => demo::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Export(args) => export::run(args),
        Command::Fit(args) => fit::run(*args),
        Command::Fleet(args) => fleet::run(args),
        Command::Kin(args) => kin::run(args),
        Command::UpdatePeriod(args) => update_period::run(args),
        Command::Reidentify(args) => match reidentify::run(args) {
            Ok(code) => return code,
            Err(e) => Err(e),
        },
        Command::Report(args) => report::run(args),
        Command::Log(args) => run::show_log(args),
        Command::Run(args) => run::run(args),
        Command::Status(args) => status::show_status(args),
        Command::Sign(args) => sign::run(args),
        Command::Sim(args) => sim::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
