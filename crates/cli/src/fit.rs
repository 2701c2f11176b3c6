//! `truepos fit`: learn a dynamic compensation model from recorded runs and validate it honestly.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use truepos_fit::dataset::{Dataset, InputKind, Run};
use truepos_fit::features::{candidates, Family};
use truepos_fit::train::{InnerCv, Rule, Settings};
use truepos_fit::validate::{validate, Split};
use truepos_io::dynamic_model_file::{DynamicModelFile, InputEntry};
use truepos_io::limits::{finite_in, int_in};
use truepos_io::run::{glob_match, read, Table};

/// Arguments of `truepos fit`.
#[derive(clap::Args)]
pub struct Args {
    /// A run: CSV, or a workbook (.xlsx; every sheet is a run). Repeat for several runs, which are
    /// fitted together and validated apart.
    #[arg(long = "run", required = true)]
    runs: Vec<PathBuf>,
    /// Only this sheet of each workbook.
    #[arg(long)]
    sheet: Option<String>,
    /// Target columns (measured errors in µm): names or globs, comma-separated.
    #[arg(long, default_value = "*_um")]
    target: String,
    /// Input columns (what the control knows): names or globs, comma-separated.
    #[arg(long)]
    inputs: String,
    /// Which inputs are operating state (filtered as is, and squared) rather than temperatures.
    #[arg(long, default_value = "*rpm*,*speed*,*feed*,*power*,*torque*")]
    operating: String,
    /// The time column, in seconds.
    #[arg(long, default_value = "time_s")]
    time: String,
    /// Validation: chrono:<train fraction>, runs (leave one run out) or kfold:<k>.
    #[arg(long, default_value = "chrono:0.6")]
    split: String,
    /// Fix the model family (static, operating, dynamic, dynamic-rates, dynamic-running,
    /// dynamic-rates-running, seed-c; comma-separated to choose among several). Default: chosen
    /// automatically.
    #[arg(long)]
    family: Option<String>,
    /// Fix the ridge parameter(s), comma-separated, each 0–10¹². Default: chosen automatically.
    #[arg(long)]
    ridge: Option<String>,
    /// How inner-CV scores choose: 1se (the most regularised candidate within one standard error
    /// of the best) or min (the lowest CV error).
    #[arg(long, default_value = "1se")]
    rule: String,
    /// Use at most this many temperature sensors (correlation ranking + greedy forward
    /// selection), 1–1000.
    #[arg(long, value_parser = int_in(1usize, 1000))]
    max_sensors: Option<usize>,
    /// Seed C's reference sensor (an input temperature column, e.g. the ambient or a reference
    /// spot on the machine): adds the seed-c family, Y = Σ k_i·(t_i − t_r) + c, to the candidates.
    #[arg(long)]
    reference: Option<String>,
    /// Blocks of the inner cross-validation on the training part, 2–100.
    #[arg(long, default_value_t = 8, value_parser = int_in(2usize, 100))]
    folds: usize,
    /// Which blocks train the model scored on a held-out block: blocked (all others) or rolling
    /// (only those before it, rolling origin; the first two blocks only train).
    #[arg(long, default_value = "blocked")]
    inner_cv: String,
    /// Machine name written into the model file.
    #[arg(long, default_value = "unnamed")]
    machine: String,
    /// Write the model fitted on the (last) training part here (JSON).
    #[arg(long)]
    model: Option<PathBuf>,
    /// The machine axis a target compensates, `<target>=<axis>` (repeat; e.g. `ch5_um=Z`). A
    /// target named `Z`, `Z_um` or `dz_um` needs none; others without one are not applied.
    #[arg(long = "axis")]
    axes: Vec<String>,
    /// Write measured and predicted values of every run here (CSV), for reports.
    #[arg(long)]
    predictions: Option<PathBuf>,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

fn patterns(s: &str) -> Vec<&str> {
    s.split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .collect()
}

fn load(args: &Args) -> Result<Dataset, String> {
    let mut tables: Vec<Table> = Vec::new();
    for path in &args.runs {
        tables.extend(read(path, args.sheet.as_deref()).map_err(|e| e.to_string())?);
    }
    let first = &tables[0];
    let input_cols = first
        .select(&patterns(&args.inputs))
        .map_err(|e| e.to_string())?;
    let target_cols = first
        .select(&patterns(&args.target))
        .map_err(|e| e.to_string())?;
    let input_names: Vec<String> = input_cols
        .iter()
        .map(|&c| first.columns[c].clone())
        .collect();
    let target_names: Vec<String> = target_cols
        .iter()
        .map(|&c| first.columns[c].clone())
        .collect();
    if let Some(both) = input_names.iter().find(|n| target_names.contains(n)) {
        return Err(format!(
            "column `{both}` is both an input and a target: a model must never read the measured error"
        ));
    }
    let ops = patterns(&args.operating);
    let input_kinds = input_names
        .iter()
        .map(|n| {
            if ops.iter().any(|p| glob_match(p, n)) {
                InputKind::Operating
            } else {
                InputKind::Temperature
            }
        })
        .collect();
    let mut runs = Vec::new();
    for t in &tables {
        let col = |name: &String| t.select(&[name.as_str()]).map(|v| v[0]);
        let numbers = |names: &[String]| -> Result<Vec<Vec<f64>>, String> {
            names
                .iter()
                .map(|n| col(n).and_then(|c| t.numbers(c)).map_err(|e| e.to_string()))
                .collect()
        };
        let time_col = col(&args.time).map_err(|e| e.to_string())?;
        runs.push(Run {
            name: t.name(),
            time_s: t.time(time_col).map_err(|e| e.to_string())?,
            inputs: numbers(&input_names)?,
            targets: numbers(&target_names)?,
        });
    }
    let ds = Dataset {
        input_names,
        input_kinds,
        target_names,
        runs,
    };
    ds.check().map_err(|e| e.to_string())?;
    Ok(ds)
}

fn settings(args: &Args, ds: &Dataset) -> Result<Settings, String> {
    let reference = match &args.reference {
        None => None,
        Some(name) => Some(
            (0..ds.input_names.len())
                .find(|&i| ds.input_names[i] == *name && ds.input_kinds[i] == InputKind::Temperature)
                .ok_or_else(|| {
                    format!(
                        "--reference `{name}`: not a temperature input; the temperature inputs are {}",
                        (0..ds.input_names.len())
                            .filter(|&i| ds.input_kinds[i] == InputKind::Temperature)
                            .map(|i| ds.input_names[i].as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })?,
        ),
    };
    let mut s = Settings {
        folds: args.folds,
        max_sensors: args.max_sensors,
        reference,
        ..Settings::default()
    };
    s.rule = match args.rule.as_str() {
        "1se" => Rule::OneStandardError,
        "min" => Rule::MinimumCv,
        other => return Err(format!("--rule `{other}`: expected 1se or min")),
    };
    s.inner = InnerCv::parse(&args.inner_cv).ok_or_else(|| {
        format!(
            "--inner-cv `{}`: expected blocked or rolling",
            args.inner_cv
        )
    })?;
    if let Some(f) = &args.family {
        s.families = patterns(f)
            .into_iter()
            .map(|name| {
                Family::parse(name).ok_or_else(|| {
                    format!(
                        "--family `{name}`: expected seed-c, static, operating, dynamic, dynamic-rates, dynamic-running or dynamic-rates-running"
                    )
                })
            })
            .collect::<Result<_, _>>()?;
    }
    if let Some(r) = &args.ridge {
        s.ridges = patterns(r)
            .into_iter()
            .map(|v| finite_in(0.0, 1e12)(v).map_err(|e| format!("--ridge: {e}")))
            .collect::<Result<_, _>>()?;
    }
    Ok(s)
}

/// A progress bar on stderr for fits that take longer than a second.
struct Progress {
    start: Instant,
}

impl Progress {
    fn update(&mut self, done: usize, total: usize) {
        let secs = self.start.elapsed().as_secs_f64();
        if secs < 1.0 || !std::io::stderr().is_terminal() {
            return;
        }
        let width = 30;
        let filled = (done * width)
            .checked_div(total)
            .unwrap_or(width)
            .min(width);
        eprint!(
            "\r[{}{}] fold {done}/{total}  {secs:.1} s",
            "#".repeat(filled),
            "-".repeat(width - filled)
        );
        if done == total {
            eprintln!();
        }
    }
}

/// Runs `truepos fit`.
pub fn run(args: Args) -> Result<(), String> {
    let ds = load(&args)?;
    let split = Split::parse(&args.split)?;
    let settings = settings(&args, &ds)?;
    let cand = candidates(&ds, &settings.taus).map_err(|e| e.to_string())?;
    let mut progress = Progress {
        start: Instant::now(),
    };
    let (validation, trained, pred) = validate(&ds, &cand, split, &settings, &mut |d, t| {
        progress.update(d, t)
    })?;
    let report = serde_json::json!({
        "runs": ds.runs.iter().map(|r| serde_json::json!({"name": r.name, "samples": r.len()})).collect::<Vec<_>>(),
        "inputs": ds.input_names,
        "targets": ds.target_names,
        "validation": validation,
    });
    if let Some(path) = &args.model {
        let inputs = trained
            .inputs
            .iter()
            .map(|&i| InputEntry {
                name: ds.input_names[i].clone(),
                kind: ds.input_kinds[i],
            })
            .collect();
        let file = DynamicModelFile::new(
            &args.machine,
            &trained.model,
            inputs,
            &ds.target_names,
            serde_json::json!({
                "created_by": format!("truepos fit {}", env!("CARGO_PKG_VERSION")),
                "runs": ds.runs.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
                "fitted_on": "the training part of the (last) validation fold",
                "settings": settings,
                "choices": trained.choices,
            }),
            serde_json::to_value(&validation).unwrap_or_default(),
        );
        let mut file = file;
        for spec in &args.axes {
            let (target, axis) = spec.split_once('=').ok_or_else(|| {
                format!("--axis `{spec}`: expected <target>=<axis>, e.g. ch5_um=Z")
            })?;
            let output = file
                .outputs
                .iter_mut()
                .find(|o| o.name == target.trim())
                .ok_or_else(|| {
                    format!(
                        "--axis `{spec}`: no target `{}`; the targets are {}",
                        target.trim(),
                        ds.target_names.join(", ")
                    )
                })?;
            output.axis = Some(axis.trim().to_string());
        }
        std::fs::write(path, file.to_json() + "\n")
            .map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    }
    if let Some(path) = &args.predictions {
        write_predictions(path, &ds, &pred)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
        );
        return Ok(());
    }
    println!("validation: {}", validation.protocol_text);
    println!(
        "{:<12} {:>10} {:>10} {:>10} {:>10} {:>9}  chosen (inner CV on the training part)",
        "target", "uncomp µm", "RMSE µm", "max|e| µm", "p-p µm", "reduction"
    );
    for (m, c) in validation.metrics.iter().zip(&trained.choices) {
        println!(
            "{:<12} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>8.1}%  {} λ={:e} (CV {:.2} µm)",
            m.target,
            m.uncompensated_rmse_um,
            m.rmse_um,
            m.max_abs_um,
            m.peak_to_peak_um,
            m.rmse_reduction_percent,
            c.family.name(),
            c.ridge,
            c.cv_rmse_um
        );
    }
    let sensors = validation.sensors.last().cloned().unwrap_or_default();
    println!("temperature sensors used: {}", sensors.join(", "));
    for w in &validation.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn write_predictions(
    path: &std::path::Path,
    ds: &Dataset,
    pred: &truepos_fit::validate::Predictions,
) -> Result<(), String> {
    let mut out = String::from("run,time_s");
    for t in &ds.target_names {
        out += &format!(",{t},{t}_predicted");
    }
    out.push('\n');
    for (r, run) in ds.runs.iter().enumerate() {
        let rel: Vec<Vec<f64>> = (0..ds.target_names.len())
            .map(|k| run.relative_target(k))
            .collect();
        for i in 0..run.len() {
            out += &format!("{r},{}", run.time_s[i]);
            for k in 0..ds.target_names.len() {
                out += &format!(",{},{}", rel[k][i], pred[r][k][i]);
            }
            out.push('\n');
        }
    }
    std::fs::write(path, out).map_err(|e| format!("{}: cannot write: {e}", path.display()))
}
