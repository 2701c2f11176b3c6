//! `truepos report`: a model on a recorded run with measured errors, as one HTML file with
//! figures for the shop floor — the conclusion per axis first, the figures of merit, the drift
//! plot per axis over the run's clock time, residual histogram, temperatures, correlation heat
//! map, the coefficients grouped by input with their units ([`coefficients`]) and the
//! protocol; printable to A4 PDF from the browser.

use std::path::PathBuf;

use truepos_model::CompensationModel;

use crate::error::CliError;
use crate::evaluator::{Evaluator, ModelOnRun};
use truepos_report::{channel_metrics, write_report, Channel, ReportData};

pub(crate) mod coefficients;
mod runs;

/// Arguments of `truepos report`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    on: ModelOnRun,
    /// The run to report when the file holds several (`--run-column`, workbook sheets): its
    /// name. Default: the only run.
    #[arg(long)]
    select_run: Option<String>,
    /// Report every run of the file, one after the other on the time axis — on the clock when
    /// every run has one, else end to end — with each run's start marked in the drift plots;
    /// a fitted dynamic model starts afresh at each run, as on the machine after a restart.
    #[arg(long, conflicts_with_all = ["select_run", "test_from_s"])]
    all_runs: bool,
    /// Which column holds the measured error of which axis, as AXIS=COLUMN (error = actual −
    /// nominal; converted to µm by the unit in the name, none = µm; an empty cell is a row
    /// without a measurement, left out of the figures), e.g. `X=dx_um,Y=dy_um,Z=dz_um`.
    #[arg(long, value_delimiter = ',', required = true)]
    measured: Vec<String>,
    /// Time (s) from which the run is held out (was not used to make the model); the figures of
    /// merit are computed from there on, −10¹⁰–10¹⁰ (epoch seconds fit). Default: the whole run.
    #[arg(long, value_parser = truepos_io::limits::finite_in(-1e10, 1e10))]
    test_from_s: Option<f64>,
    /// Take the measured errors as measured. Default: as the model was fitted — a fitted
    /// dynamic model learnt the drift from each run's first sample (`truepos fit` without a
    /// machine file), so its measured errors are taken relative to each channel's first sample
    /// with a measurement; a position-dependent or reference-sensor model predicts the error as
    /// measured.
    #[arg(long)]
    absolute: bool,
    /// Output folder.
    #[arg(long, default_value = "report")]
    out: PathBuf,
    /// Print the figures of merit as JSON.
    #[arg(long)]
    json: bool,
}

/// `values` relative to their first finite value, the reference point `truepos fit` uses.
fn relative_to_first(values: &mut [f64]) {
    if let Some(first) = values.iter().copied().find(|v| v.is_finite()) {
        for v in values.iter_mut() {
            *v -= first;
        }
    }
}

/// The clock time (s since 1970-01-01 UTC) of a run's first row when its time column holds
/// date-times — the column `--time` names, else `time_s`, the one the cycles are timed by —, so
/// that the drift plots read the shop's clock; `None` for seconds, row numbers or a period.
fn clock_start(args: &Args, table: &truepos_io::run::RunTable) -> Option<f64> {
    let period = matches!(
        args.on.shape.time(None),
        Some(truepos_io::run::Time::Period(_))
    );
    if period || table.table.is_empty() {
        return None;
    }
    let name = args.on.time.as_deref().unwrap_or("time_s");
    let col = table.columns.iter().position(|h| h == name)?;
    let ns = match table.table.row(0).cell(col)?.value {
        truepos_io::table::Value::Text(text) => match &table.time_format {
            Some(format) => truepos_io::timestamp::parse_with(format, text),
            None => truepos_io::timestamp::parse(text),
        },
        _ => return None,
    };
    ns.ok().map(|ns| ns as f64 / 1e9)
}

/// What is read of the run to report beside its cycles.
struct Measured {
    /// The run's name.
    name: String,
    /// The measured-error columns in µm, NaN where a row has no measurement.
    columns: Vec<Vec<f64>>,
    /// The clock time of its first row, if its time column is a clock.
    clock_start_s: Option<f64>,
}

/// The runs to report (`--select-run`'s, the only one, or with `--all-runs` every one), and
/// their measured-error columns by name (in µm, NaN where a row has no measurement), read by
/// io's one run reader with the file's shape.
fn read_measured(args: &Args, names: &[String]) -> Result<Vec<Measured>, CliError> {
    let tables = truepos_io::run::read_shaped(&args.on.run, None, &args.on.shape.shape())?;
    let listed = || {
        tables
            .iter()
            .map(truepos_io::run::RunTable::name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let selected: Vec<&truepos_io::run::RunTable> = match &args.select_run {
        Some(name) => vec![tables.iter().find(|t| t.name() == *name).ok_or_else(|| {
            CliError::refused(format!(
                "--select-run `{name}`: no such run in {}; the runs are: {}",
                args.on.run.display(),
                listed()
            ))
        })?],
        None if tables.len() == 1 || args.all_runs => tables.iter().collect(),
        None => {
            return Err(CliError::refused(format!(
                "{} holds {} runs; choose one with --select-run: {}",
                args.on.run.display(),
                tables.len(),
                listed()
            )))
        }
    };
    selected
        .into_iter()
        .map(|table| {
            let columns = names
                .iter()
                .map(|n| {
                    let c = table.table.column(n).ok_or_else(|| {
                        CliError::refused(format!(
                            "{}:{}:1: `{n}`: missing column; the header has: {}",
                            args.on.run.display(),
                            table.table.header_line,
                            table.columns.join(", ")
                        ))
                    })?;
                    Ok(table.measured(c)?)
                })
                .collect::<Result<_, CliError>>()?;
            Ok(Measured {
                name: table.name(),
                columns,
                clock_start_s: clock_start(args, table),
            })
        })
        .collect()
}

/// The model's prediction of each `--measured` axis at every row of every run, in order (a
/// row whose cycle fails validation has none), and how many rows failed. The model starts
/// afresh at each run.
fn predict(
    model: &mut Evaluator,
    runs: &[&truepos_io::cycles::Cycles],
    pairs: &[(usize, String)],
    machine: &truepos_model::Machine,
) -> (Vec<Vec<f64>>, usize) {
    let mut predicted = vec![Vec::new(); pairs.len()];
    let mut failed = 0usize;
    for (r, run) in runs.iter().enumerate() {
        if r > 0 {
            model.restart();
        }
        for i in 0..run.run.time_s.len() {
            let e = model.error_um(run, i, machine);
            for (k, &(a, _)) in pairs.iter().enumerate() {
                predicted[k].push(e.as_ref().map_or(f64::NAN, |e| e[a]));
            }
            failed += usize::from(e.is_err());
        }
    }
    (predicted, failed)
}

/// The volume map of a position-dependent model over the run's states.
fn volume(
    machine: &truepos_model::Machine,
    model: &CompensationModel,
    run: &truepos_io::cycles::Cycles,
) -> Option<truepos_report::VolumeMap> {
    let rows: Vec<truepos_model::CycleInput<'_>> = (0..run.run.time_s.len())
        .map(|i| truepos_model::CycleInput {
            temperatures_c: &run.run.temperatures_c[i],
            positions: &run.run.positions[i],
            operating: &run.run.operating[i],
        })
        .collect();
    crate::volume_map::of_model(machine, model.as_static()?, &rows, &run.run.time_s)
}

/// What the report describes and how, first what a shop files with it: the machine, the model
/// file and its SHA-256, the run file, when and by which truepos it was made.
fn protocol(
    args: &Args,
    machine: &str,
    model: &str,
    run_name: &str,
    relative: bool,
    failed: usize,
    cycles: usize,
) -> Vec<(String, String)> {
    let sha = truepos_files::read::read(&args.on.model, truepos_files::MODEL).map_or_else(
        |e| format!("cannot be read again: {e}"),
        |b| truepos_io::model_file::position::sha256_hex(&b),
    );
    let made = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()
        .and_then(|d| truepos_io::timestamp::format_utc(d.as_secs_f64()))
        .unwrap_or_default();
    vec![
        ("machine".to_string(), machine.to_string()),
        (
            "model".to_string(),
            format!("`{model}`, file {} (sha256 {sha})", args.on.model.display()),
        ),
        (
            "run".to_string(),
            format!("{run_name}, file {}", args.on.run.display()),
        ),
        (
            "made".to_string(),
            format!("{made} by truepos {}", env!("CARGO_PKG_VERSION")),
        ),
        (
            "evaluation".to_string(),
            format!(
                "the model file evaluated cycle by cycle as the control would ({failed} of \
                 {cycles} cycles failed validation and show no prediction)"
            ),
        ),
        (
            "sign".to_string(),
            format!(
                "error = actual − nominal; residual = measured − predicted; measured {}; \
                 uncompensated = measured, taken the same way",
                if relative {
                    "relative to each channel's first sample with a measurement, as the fit took it"
                } else {
                    "as in the file"
                }
            ),
        ),
        (
            "held-out part".to_string(),
            match args.test_from_s {
                Some(t) => format!("from t = {t} s on; the figures of merit cover only this part"),
                None => "none given: the figures of merit cover the whole run".to_string(),
            },
        ),
    ]
}

/// The conclusion first, in plain words, one card per axis: how much of the error the model
/// removes on this run (or that it makes it worse).
fn conclusions(channels: &[Channel], range: std::ops::Range<usize>) -> Vec<(String, String)> {
    channels
        .iter()
        .map(|c| {
            let m = channel_metrics(c, range.clone());
            let what = if m.reduction >= 0.0 {
                format!(
                    "{}: the model removes {:.0} % of the error",
                    c.name,
                    100.0 * m.reduction
                )
            } else {
                format!("{}: the model makes the error worse", c.name)
            };
            (
                what,
                format!("{:.2} → {:.2} µm RMS", m.uncompensated_rmse_um, m.rmse_um),
            )
        })
        .collect()
}

/// Runs `truepos report`.
pub fn run(args: Args) -> Result<(), CliError> {
    let (config, mut model, mut runs) = args.on.load()?;
    let machine = config.machine;
    let pairs = measured_axes(&args, &machine)?;
    let columns: Vec<String> = pairs.iter().map(|p| p.1.clone()).collect();
    let relative = !args.absolute && model.model().as_dynamic().is_some();
    let mut measured = vec![Vec::new(); pairs.len()];
    let mut selected = Vec::new();
    for mut m in read_measured(&args, &columns)? {
        let k = runs
            .iter()
            .position(|(name, _)| *name == m.name)
            .ok_or_else(|| CliError::refused(format!("run `{}`: not found", m.name)))?;
        for (all, mut column) in measured.iter_mut().zip(std::mem::take(&mut m.columns)) {
            // Each run from its own first measurement: the reference point the fit took.
            if relative {
                relative_to_first(&mut column);
            }
            all.extend(column);
        }
        selected.push((m.name, m.clock_start_s, runs.swap_remove(k).1));
    }
    let run_names: Vec<String> = selected.iter().map(|r| r.0.clone()).collect();
    let cycles: Vec<_> = selected.iter().map(|r| &r.2).collect();
    let (predicted, failed) = predict(&mut model, &cycles, &pairs, &machine);
    let combined = runs::combine(selected);
    let run = combined.cycles;
    let channels: Vec<Channel> = pairs
        .iter()
        .zip(measured)
        .zip(predicted)
        .map(|(((a, col), m), p)| Channel {
            name: format!("{} ({col})", machine.axes[*a].name),
            unit: "µm".into(),
            measured: m,
            predicted: p,
        })
        .collect();
    let test_from = args.test_from_s.map(|t| {
        run.run
            .time_s
            .iter()
            .position(|&x| x >= t)
            .unwrap_or(run.run.time_s.len())
    });
    let temperatures = logged_temperatures(&machine, &run.run.temperatures_c);
    let run_name = match run_names.as_slice() {
        [one] => one.clone(),
        all => format!("{} runs ({})", all.len(), all.join(", ")),
    };
    let protocol = protocol(
        &args,
        &machine.name,
        model.name(),
        &run_name,
        relative,
        failed,
        run.run.time_s.len(),
    );
    let range = test_from.unwrap_or(0)..run.run.time_s.len();
    let headline = conclusions(&channels, range.clone());
    let data = ReportData {
        title: format!("truepos report: model `{}` on {}", model.name(), run_name),
        time_s: run.run.time_s.clone(),
        clock_start_s: combined.clock_start_s,
        run_starts: combined.starts,
        test_from,
        channels,
        temperatures,
        coefficients: match model.model() {
            CompensationModel::Position(m) => coefficients::of_model(m, &machine),
            CompensationModel::Filtered(d) => coefficients::of_dynamic(d, &machine),
        },
        protocol,
        volume: volume(&machine, model.model(), &run),
        headline,
        runs: Vec::new(),
    };
    let html = write_report(&args.out, &data)?;
    let metrics: Vec<_> = data
        .channels
        .iter()
        .map(|c| (c.name.clone(), channel_metrics(c, range.clone())))
        .collect();
    print_metrics(args.json, &html, &metrics);
    Ok(())
}

/// `--measured`'s AXIS=COLUMN pairs as (axis index, column), each axis one of the machine's.
fn measured_axes(
    args: &Args,
    machine: &truepos_model::Machine,
) -> Result<Vec<(usize, String)>, CliError> {
    let mut pairs = Vec::new();
    for spec in &args.measured {
        let (axis, column) = spec.split_once('=').ok_or_else(|| {
            CliError::refused(format!("--measured `{spec}`: expected AXIS=COLUMN"))
        })?;
        let a = machine.axis_index(axis).ok_or_else(|| {
            CliError::refused(format!(
                "--measured `{spec}`: machine `{}` has no axis `{axis}`",
                machine.name
            ))
        })?;
        pairs.push((a, column.to_string()));
    }
    Ok(pairs)
}

/// Each temperature channel with a value somewhere in the run, by its id: a channel the run
/// never logged would only be an empty line in the plot.
fn logged_temperatures(
    machine: &truepos_model::Machine,
    temperatures_c: &[Vec<f64>],
) -> Vec<(String, Vec<f64>)> {
    machine
        .temperatures
        .iter()
        .enumerate()
        .filter(|(i, _)| temperatures_c.iter().any(|row| row[*i].is_finite()))
        .map(|(i, t)| (t.id.clone(), temperatures_c.iter().map(|r| r[i]).collect()))
        .collect()
}

/// Where the report is and each channel's figures of merit: as JSON on standard output with
/// `--json`, else for a person on standard error.
fn print_metrics(
    json: bool,
    html: &std::path::Path,
    metrics: &[(String, truepos_report::Metrics)],
) {
    if json {
        let v = serde_json::json!({
            "report": html.display().to_string(),
            "channels": metrics.iter().map(|(n, m)| serde_json::json!({"channel": n, "metrics": m})).collect::<Vec<_>>(),
        });
        println!("{v}");
    } else {
        eprintln!("report written to {}", html.display());
        for (n, m) in metrics {
            eprintln!(
                "  {n}: RMSE {:.2} µm (uncompensated {:.2} µm), max {:.2} µm",
                m.rmse_um, m.uncompensated_rmse_um, m.max_abs_um
            );
        }
    }
}
