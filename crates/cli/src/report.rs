//! `truepos report`: a model on a recorded run with measured errors, as one HTML file with
//! figures — measured, predicted and residual per axis, residual histogram, temperatures,
//! correlation heat map, coefficients and the validation protocol.

use std::path::{Path, PathBuf};

use truepos_io::machine_file;
use truepos_model::{CompensationModel, Model, PartForm};

use crate::error::CliError;
use crate::evaluator::Evaluator;
use truepos_report::{channel_metrics, write_report, Channel, Coefficient, ReportData};

/// Arguments of `truepos report`.
#[derive(clap::Args)]
pub struct Args {
    /// Machine description (TOML).
    #[arg(long)]
    machine: PathBuf,
    /// Model file: a position-dependent thermal model or a reference-sensor regression
    /// (TOML/JSON), or a fitted dynamic model (JSON).
    #[arg(long)]
    model: PathBuf,
    /// Run CSV with the inputs and the measured errors.
    #[arg(long)]
    run: PathBuf,
    /// Which column holds the measured error of which axis, as AXIS=COLUMN (µm, error =
    /// actual − nominal), e.g. `X=dx_um,Y=dy_um,Z=dz_um`.
    #[arg(long, value_delimiter = ',', required = true)]
    measured: Vec<String>,
    /// Time (s) from which the run is held out (was not used to make the model); the figures of
    /// merit are computed from there on, −10¹⁰–10¹⁰ (epoch seconds fit). Default: the whole run.
    #[arg(long, value_parser = truepos_io::limits::finite_in(-1e10, 1e10))]
    test_from_s: Option<f64>,
    /// Output folder.
    #[arg(long, default_value = "report")]
    out: PathBuf,
    /// Print the figures of merit as JSON.
    #[arg(long)]
    json: bool,
}

/// Reads named numeric columns of a CSV (an empty cell reads as NaN; unparsable text is not
/// accepted: a bad cell is an error naming line and column).
fn read_columns(path: &Path, names: &[String]) -> Result<Vec<Vec<f64>>, CliError> {
    use truepos_io::table::{self, Number};
    let t = table::load_csv(path, table::CsvOptions::default())?;
    let cols: Vec<usize> = names
        .iter()
        .map(|n| {
            t.column(n).ok_or_else(|| {
                CliError::refused(format!(
                    "{}:1:1: `{n}`: missing column; the header has: {}",
                    path.display(),
                    t.columns.join(", ")
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let mut out = vec![Vec::new(); names.len()];
    for (r, row) in t.rows.iter().enumerate() {
        if let Some(e) = t.width_error(r) {
            return Err(e.into());
        }
        for (k, &c) in cols.iter().enumerate() {
            let v = match row.cells[c].value.number() {
                Number::Value(v) => v,
                Number::Empty => f64::NAN,
                Number::Text(text) => {
                    return Err(t
                        .at(r, c, format!("expected a number, got `{text}`"))
                        .into())
                }
            };
            out[k].push(v);
        }
    }
    Ok(out)
}

/// A dynamic model's coefficients: per applied output, the intercept and every non-zero feature.
fn dynamic_coefficients(
    bound: &truepos_model::BoundDynamicModel,
    machine: &truepos_model::Machine,
) -> Vec<Coefficient> {
    use truepos_model::MachineInput;
    let features = bound.model().bank().features();
    let n = features.len();
    let input_name = |k: usize| match bound.inputs()[k] {
        MachineInput::Temperature(c) => machine.temperatures[c].id.as_str(),
        MachineInput::Operating(c) => machine.operating[c].id.as_str(),
    };
    let mut out = Vec::new();
    for (k, axis) in bound.axes().iter().enumerate() {
        let Some(a) = axis else { continue };
        let channel = machine.axes[*a].name.clone();
        out.push(Coefficient {
            channel: channel.clone(),
            feature: "intercept (µm)".into(),
            value: bound.model().intercepts()[k],
        });
        for (j, f) in features.iter().enumerate() {
            let value = bound.model().coefficients()[k * n + j];
            if value != 0.0 {
                out.push(Coefficient {
                    channel: channel.clone(),
                    feature: f.name(input_name),
                    value,
                });
            }
        }
    }
    out
}

/// The model's coefficients as (channel, feature, value) for the table.
fn coefficients(model: &Model, machine: &truepos_model::Machine) -> Vec<Coefficient> {
    let mut out = Vec::new();
    for p in model.parts() {
        for s in &p.summands {
            let channel = machine.axes[s.axis].name.clone();
            let dt = &machine.differences[s.difference].name;
            let mult = s
                .bed_multiplier
                .map(|b| format!(" · KFA({})", machine.axes[b].name))
                .unwrap_or_default();
            let form = match p.form {
                PartForm::Regression => "regression",
                PartForm::PositionDependent => "position-dependent",
            };
            out.push(Coefficient {
                channel: channel.clone(),
                feature: format!("[{}/{form}] {dt}{mult}", p.name),
                value: s.k0_um_per_k,
            });
            for t in &s.position_terms {
                out.push(Coefficient {
                    channel: channel.clone(),
                    feature: format!(
                        "[{}] {dt} · {}({}){mult}",
                        p.name,
                        t.factor.name(),
                        machine.axes[t.axis].name
                    ),
                    value: t.k_um_per_k,
                });
            }
        }
        for &(a, v) in &p.constants_um {
            out.push(Coefficient {
                channel: machine.axes[a].name.clone(),
                feature: format!("[{}] constant (µm)", p.name),
                value: v,
            });
        }
    }
    out
}

/// The volume map of a position-dependent model over the run's states.
fn volume(
    machine: &truepos_model::Machine,
    model: &CompensationModel,
    run: &truepos_io::cycles::Cycles,
) -> Option<truepos_report::VolumeMap> {
    let rows: Vec<truepos_model::CycleInput<'_>> = (0..run.time_s.len())
        .map(|i| truepos_model::CycleInput {
            temperatures_c: &run.temperatures_c[i],
            positions: &run.positions[i],
            operating: &run.operating[i],
        })
        .collect();
    crate::volume_map::of_model(machine, model.as_static()?, &rows, &run.time_s)
}

pub fn run(args: Args) -> Result<(), CliError> {
    let machine = machine_file::load(&args.machine)?.machine;
    let mut model = Evaluator::load(&args.model, &machine)?;
    let run = model.load_run(&args.run, &machine)?;
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
    let columns: Vec<String> = pairs.iter().map(|p| p.1.clone()).collect();
    let measured = read_columns(&args.run, &columns)?;

    let mut predicted = vec![Vec::with_capacity(run.time_s.len()); pairs.len()];
    let mut failed = 0usize;
    for i in 0..run.time_s.len() {
        let r = model.error_um(&run, i, &machine);
        for (k, &(a, _)) in pairs.iter().enumerate() {
            predicted[k].push(match &r {
                Ok(e) => e[a],
                Err(_) => f64::NAN,
            });
        }
        failed += usize::from(r.is_err());
    }
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
        run.time_s
            .iter()
            .position(|&x| x >= t)
            .unwrap_or(run.time_s.len())
    });
    let temperatures = machine
        .temperatures
        .iter()
        .enumerate()
        .filter(|(i, _)| run.temperatures_c.iter().any(|row| row[*i].is_finite()))
        .map(|(i, t)| {
            (
                t.id.clone(),
                run.temperatures_c.iter().map(|r| r[i]).collect(),
            )
        })
        .collect();
    let mut protocol = vec![
        ("machine".to_string(), machine.name.clone()),
        ("model".to_string(), model.name().to_string()),
        ("run".to_string(), args.run.display().to_string()),
        (
            "evaluation".to_string(),
            format!(
                "the model file evaluated cycle by cycle as the control would ({} of {} cycles failed validation and show no prediction)",
                failed,
                run.time_s.len()
            ),
        ),
        (
            "sign".to_string(),
            "error = actual − nominal; residual = measured − predicted; uncompensated = measured relative to the first sample".to_string(),
        ),
    ];
    protocol.push((
        "held-out part".to_string(),
        match args.test_from_s {
            Some(t) => format!("from t = {t} s on; the figures of merit cover only this part"),
            None => "none given: the figures of merit cover the whole run".to_string(),
        },
    ));
    let data = ReportData {
        title: format!(
            "truepos report: model `{}` on {}",
            model.name(),
            args.run.display()
        ),
        time_s: run.time_s.clone(),
        test_from,
        channels,
        temperatures,
        coefficients: match model.model() {
            CompensationModel::Static(m) => coefficients(m, &machine),
            CompensationModel::Dynamic(d) => dynamic_coefficients(d, &machine),
        },
        protocol,
        volume: volume(&machine, model.model(), &run),
        headline: Vec::new(),
        runs: Vec::new(),
    };
    let html = write_report(&args.out, &data)?;
    let range = test_from.unwrap_or(0)..run.time_s.len();
    let metrics: Vec<_> = data
        .channels
        .iter()
        .map(|c| (c.name.clone(), channel_metrics(c, range.clone())))
        .collect();
    if args.json {
        let v = serde_json::json!({
            "report": html.display().to_string(),
            "channels": metrics.iter().map(|(n, m)| serde_json::json!({"channel": n, "metrics": m})).collect::<Vec<_>>(),
        });
        println!("{v}");
    } else {
        eprintln!("report written to {}", html.display());
        for (n, m) in &metrics {
            eprintln!(
                "  {n}: RMSE {:.2} µm (uncompensated {:.2} µm), max {:.2} µm",
                m.rmse_um, m.uncompensated_rmse_um, m.max_abs_um
            );
        }
    }
    Ok(())
}
