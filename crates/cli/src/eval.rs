//! `truepos eval`: a model on a recorded run, as a user checks a model before trusting it.

use std::io::Write;
use std::path::PathBuf;

use truepos_io::machine_file;

use crate::error::CliError;
use crate::evaluator::Evaluator;
use crate::shape::ShapeArgs;

/// Arguments of `truepos eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Machine description (TOML). The defaults of --machine, --model and --run are the
    /// example VMC's, found from any directory.
    #[arg(long, default_value = "examples/vmc3/machine.toml")]
    machine: PathBuf,
    /// Model file: a position-dependent thermal model or a reference-sensor regression (TOML, or
    /// JSON by extension), or a fitted dynamic model (JSON with
    /// `"form": "filtered"`).
    #[arg(long, default_value = "examples/vmc3/model.toml")]
    model: PathBuf,
    /// Run CSV (or workbook) of cycles: time_s, <axis>_mm / <axis>_deg, temperatures,
    /// operating state; units in column names are converted (`X_in`, `t1 (°F)`).
    #[arg(long, default_value = "examples/vmc3/run.csv")]
    run: PathBuf,
    /// The time column: seconds or ISO 8601 date-times. Default: `time_s` if there is one,
    /// else the row number.
    #[arg(long, conflicts_with = "sample_period")]
    time: Option<String>,
    #[command(flatten)]
    shape: ShapeArgs,
    /// Where to write per-axis offsets (CSV); `-` for standard output.
    #[arg(long, short, default_value = "-")]
    out: PathBuf,
    /// Print a summary as JSON (and write the CSV only if --out names a file).
    #[arg(long)]
    json: bool,
}

/// Says first, as `run` does, where the model predicts beyond an axis' envelope: on the machine
/// the envelope would hold the axis at its limit, so the figures promise more than it would get.
fn warn_beyond_envelope(
    config: &truepos_runtime::MachineConfig,
    machine_file: &std::path::Path,
    model: &Evaluator,
    runs: &[(String, truepos_io::cycles::Cycles)],
) {
    for (name, cycles) in runs {
        let beyond = crate::envelope_check::beyond(config, model.model(), &cycles.run);
        let what = format!("run {name}");
        for w in crate::envelope_check::warnings(config, machine_file, model.name(), &what, &beyond)
        {
            eprintln!("{w}");
        }
    }
}

/// Per-axis figures over the run.
struct AxisSummary {
    name: String,
    min_um: f64,
    max_um: f64,
    max_abs_um: f64,
}

pub fn run(mut args: Args) -> Result<(), CliError> {
    for p in [&mut args.machine, &mut args.model, &mut args.run] {
        *p = crate::examples::find(std::mem::take(p));
    }
    let inputs: [(&str, &std::path::Path); 3] = [
        ("--machine", &args.machine),
        ("--model", &args.model),
        ("--run", &args.run),
    ];
    if args.out.as_os_str() != "-" {
        crate::write::check(&args.out, &inputs)?;
    }
    let config = machine_file::load(&args.machine)?;
    let machine = config.machine.clone();
    let mut model = Evaluator::load(&args.model, &machine)?;
    let runs = model.load_runs(&args.run, &machine, &args.shape, args.time.as_deref())?;
    warn_beyond_envelope(&config, &args.machine, &model, &runs);
    // Rows say their run when the file holds several or a run column named one.
    let named = runs.len() > 1 || runs[0].0 != args.run.display().to_string();

    let to_stdout = args.out.as_os_str() == "-";
    // A file is written through the one door and renamed into place once complete.
    let mut pending = if to_stdout {
        None
    } else {
        Some(crate::write::create(&args.out, &inputs)?)
    };
    let mut writer: Option<csv::Writer<Box<dyn Write + '_>>> = if to_stdout && args.json {
        None
    } else if to_stdout {
        Some(csv::Writer::from_writer(Box::new(std::io::stdout().lock())))
    } else {
        pending.as_mut().map(|f| {
            csv::Writer::from_writer(Box::new(std::io::BufWriter::new(f)) as Box<dyn Write + '_>)
        })
    };
    let io_err = |e: csv::Error| CliError::file(&args.out, Some("cannot write"))(e);
    let n_axes = model.axis_count();
    if let Some(w) = writer.as_mut() {
        w.write_record(header(named, &machine.axes[..n_axes]))
            .map_err(io_err)?;
    }

    let mut summary: Vec<AxisSummary> = machine.axes[..n_axes]
        .iter()
        .map(|a| AxisSummary {
            name: a.name.clone(),
            min_um: f64::INFINITY,
            max_um: f64::NEG_INFINITY,
            max_abs_um: 0.0,
        })
        .collect();
    let (failed, first_failure, per_run) = match evaluate(
        &args,
        &machine,
        &mut model,
        &runs,
        named,
        &mut summary,
        writer.as_mut(),
    )? {
        Some(figures) => figures,
        None => return Ok(()), // the reader (`head`, a pager) has seen enough
    };
    if let Some(w) = writer.as_mut() {
        w.flush()
            .map_err(CliError::file(&args.out, Some("cannot write")))?;
    }
    drop(writer);
    if let Some(p) = pending {
        p.commit()?;
    }

    let rows: usize = runs.iter().map(|(_, c)| c.run.time_s.len()).sum();
    let evaluated = (failed, first_failure, per_run);
    if args.json {
        print_json(&args, &machine, &model, rows, &summary, evaluated);
    } else {
        print_summary(&args, &model, rows, &summary, evaluated, named);
    }
    Ok(())
}

/// The CSV's header: the run's name when rows must say it, the time, and per axis the
/// predicted error and the compensation that cancels it, then the cycle's status.
fn header(named: bool, axes: &[truepos_model::Axis]) -> Vec<String> {
    let mut header = Vec::new();
    if named {
        header.push("run".to_string());
    }
    header.push("time_s".to_string());
    for a in axes {
        header.push(format!("{}_error_um", a.name));
        header.push(format!("{}_comp_um", a.name));
    }
    header.push("status".into());
    header
}

/// The summary as one JSON object on standard output, for scripts: per axis the range of
/// the predicted error (null where no cycle was evaluated), and per run its cycles.
fn print_json(
    args: &Args,
    machine: &truepos_model::Machine,
    model: &Evaluator,
    rows: usize,
    summary: &[AxisSummary],
    (failed, first_failure, per_run): Evaluated,
) {
    let axes: Vec<serde_json::Value> = summary
        .iter()
        .map(|s| {
            let finite = |v: f64| if v.is_finite() { Some(v) } else { None };
            serde_json::json!({
                "axis": s.name,
                "min_error_um": finite(s.min_um),
                "max_error_um": finite(s.max_um),
                "max_abs_error_um": s.max_abs_um,
            })
        })
        .collect();
    let v = serde_json::json!({
        "machine": machine.name,
        "model": model.name(),
        "run": args.run.display().to_string(),
        "cycles": rows,
        "failed_cycles": failed,
        "first_failure": first_failure,
        "rows_beyond_training": model.rows_beyond(),
        "axes": axes,
        "runs": per_run,
    });
    println!("{v}");
}

/// The summary for a person, on standard error so that it does not mix with the CSV on
/// standard output.
fn print_summary(
    args: &Args,
    model: &Evaluator,
    rows: usize,
    summary: &[AxisSummary],
    (failed, first_failure, per_run): Evaluated,
    named: bool,
) {
    eprintln!(
        "{} cycles of {} evaluated with model `{}` ({} failed)",
        rows,
        args.run.display(),
        model.name(),
        failed
    );
    if named {
        for r in &per_run {
            eprintln!(
                "  run {}: {} cycles ({} failed)",
                r["name"].as_str().unwrap_or(""),
                r["cycles"],
                r["failed_cycles"]
            );
        }
    }
    for s in summary {
        if s.min_um.is_finite() {
            eprintln!(
                "  {:>4}: predicted error {:+9.3} … {:+9.3} µm",
                s.name, s.min_um, s.max_um
            );
        }
    }
    if let Some(f) = &first_failure {
        eprintln!("  first failed cycle: {f}");
    }
    if model.rows_beyond() > 0 {
        eprintln!(
            "  {} cycles with an input beyond the model's training range (widened): clamped, the output capped at 1.5 × the largest in training, as on the machine",
            model.rows_beyond()
        );
    }
}

/// What evaluating the runs found: failed cycles, the first failure, and per run its name,
/// cycles and failed cycles.
type Evaluated = (usize, Option<String>, Vec<serde_json::Value>);

/// Steps the model through every run from its start, writing a CSV record per cycle and
/// widening the per-axis summary; `None` when the CSV's reader closed the pipe.
fn evaluate(
    args: &Args,
    machine: &truepos_model::Machine,
    model: &mut Evaluator,
    runs: &[(String, truepos_io::cycles::Cycles)],
    named: bool,
    summary: &mut [AxisSummary],
    mut writer: Option<&mut csv::Writer<Box<dyn Write + '_>>>,
) -> Result<Option<Evaluated>, CliError> {
    let n_axes = summary.len();
    let io_err = |e: csv::Error| CliError::file(&args.out, Some("cannot write"))(e);
    let mut failed = 0usize;
    let mut first_failure: Option<String> = None;
    let mut per_run = Vec::new();
    for (name, cycles) in runs {
        model.restart();
        let failed_before = failed;
        for i in 0..cycles.run.time_s.len() {
            let mut record = Vec::with_capacity(2 + 2 * n_axes);
            if named {
                record.push(name.clone());
            }
            record.push(format!("{}", cycles.run.time_s[i]));
            match model.error_um(cycles, i, machine) {
                Ok(errors) => {
                    for (a, s) in summary.iter_mut().enumerate() {
                        let e = errors[a];
                        s.min_um = s.min_um.min(e);
                        s.max_um = s.max_um.max(e);
                        s.max_abs_um = s.max_abs_um.max(e.abs());
                        record.push(format!("{e:.6}"));
                        // 0 − e, not −e: no "-0.000000" for a zero compensation.
                        record.push(format!("{:.6}", 0.0 - e));
                    }
                    record.push("ok".into());
                }
                Err(reason) => {
                    // A failed cycle writes no number at all: a blank cell can never be taken
                    // for a compensation, a NaN might.
                    failed += 1;
                    if first_failure.is_none() {
                        first_failure = Some(format!(
                            "{}:{}: {reason}",
                            args.run.display(),
                            cycles.line[i]
                        ));
                    }
                    record.extend(std::iter::repeat_n(String::new(), 2 * n_axes));
                    record.push(format!("error: {reason}"));
                }
            }
            if let Some(w) = writer.as_mut() {
                if let Err(e) = w.write_record(&record) {
                    if is_broken_pipe(&e) {
                        return Ok(None);
                    }
                    return Err(io_err(e));
                }
            }
        }
        per_run.push(serde_json::json!({
            "name": name,
            "cycles": cycles.run.time_s.len(),
            "failed_cycles": failed - failed_before,
        }));
    }
    Ok(Some((failed, first_failure, per_run)))
}

fn is_broken_pipe(e: &csv::Error) -> bool {
    matches!(e.kind(), csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::BrokenPipe)
}
