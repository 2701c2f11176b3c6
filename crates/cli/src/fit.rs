//! `truepos fit`: learn a compensation model from recorded runs and validate it honestly. This
//! module reads the options and the runs and fits the filtered (dynamic) families; with a
//! machine file, [`machine`] fits the position-dependent families too; [`report`] writes the
//! validation as a report. Both use this module's readers; nothing here is defined twice.

pub(crate) mod machine;
mod report;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::CliError;
use truepos_fit::dataset::{Columns, Dataset, Patterns};
use truepos_fit::export::{model_file, plausible, predictions_csv, TargetAxis};
use truepos_fit::family::Families;
use truepos_fit::settings::{InnerCv, Ridges, Rule, Selection, Settings};
use truepos_fit::validate::{fit, Metrics, Outcome, Split, Validation};
use truepos_io::limits::int_in;
use truepos_io::run::{read_shaped, RunTable, Time};

use crate::shape::ShapeArgs;

/// The files `truepos fit` reads, which none of its outputs may be.
pub(crate) fn input_files(args: &Args) -> Vec<(&'static str, &Path)> {
    let mut v: Vec<(&'static str, &Path)> =
        args.runs.iter().map(|r| ("--run", r.as_path())).collect();
    if let Some(m) = &args.machine {
        v.push(("--machine", m.as_path()));
    }
    v
}

/// Arguments of `truepos fit`.
#[derive(clap::Args)]
pub struct Args {
    /// A run: CSV, or a workbook (.xlsx; every sheet is a run). Repeat for several runs, which are
    /// fitted together and validated apart.
    #[arg(long = "run", required = true)]
    pub(crate) runs: Vec<PathBuf>,
    /// Only this sheet of each workbook.
    #[arg(long)]
    pub(crate) sheet: Option<String>,
    /// Target columns (measured errors): names or globs, comma-separated. Converted to µm by
    /// the unit in the name (`_mm`, `(µm)`, …; none = µm); an empty cell is a row without a
    /// measurement, which steps the filters but neither trains nor scores. Default: every
    /// column whose name states µm or nm (`dz_um`, `Z-Drift [µm]`, `dz (nm)`).
    #[arg(long)]
    pub(crate) target: Option<Patterns>,
    /// Input columns of the dynamic families (what the control knows): names or globs,
    /// comma-separated. Temperatures are converted to °C by the unit in the name (`_f`, `(K)`,
    /// …; none = °C). Required without a machine file; with one, default: the machine's
    /// measured temperature and operating channels the first run holds.
    #[arg(long)]
    pub(crate) inputs: Option<Patterns>,
    /// With a machine file: the columns of the positions (one per machine axis, in machine
    /// order) at which the targets were measured, e.g. a probe's coordinates. Default: the
    /// machine's own axis position columns (`X_mm`, …).
    #[arg(long)]
    pub(crate) positions: Option<Patterns>,
    /// With a machine file: the axis whose part a difference measures, `<difference>=<axis>`
    /// (repeat; e.g. `dT_y_saddle=Y`): adds the own-axis and serial position-dependent
    /// models, whose terms follow that axis, to the candidates.
    #[arg(long = "difference-axis")]
    pub(crate) difference_axes: Vec<TargetAxis>,
    /// Which inputs are operating state (filtered as is, and squared) rather than temperatures.
    /// With a machine file and no --inputs: the machine's operating channels.
    #[arg(long, default_value = "*rpm*,*speed*,*feed*,*power*,*torque*")]
    pub(crate) operating: Patterns,
    /// The time column: seconds, or ISO 8601 date-times (`2024-03-01T08:00:00`, a space for
    /// the `T`, fractional seconds, `Z` or an offset) counted from the run's first row.
    #[arg(long, default_value = "time_s", conflicts_with = "sample_period")]
    pub(crate) time: String,
    #[command(flatten)]
    pub(crate) shape: ShapeArgs,
    /// Validation: chrono:<train fraction>, runs (leave one run out) or kfold:<k>.
    #[arg(long, default_value = "chrono:0.6")]
    pub(crate) split: Split,
    /// Fix the model family, comma-separated to choose among several: reference (reference-sensor
    /// regression on the rises, needs --reference), static (temperature rises only), operating (+ filtered
    /// spindle speed), dynamic (+ filtered temperatures), dynamic-rates (+ rates of change),
    /// dynamic-running, dynamic-rates-running (+ rises while the spindle runs), transfer (a lag
    /// per sensor at one identified time constant), transfer2 (two: second order; not among
    /// the defaults); with a machine file also the position-dependent ones: prior-art, all-axes,
    /// all-axes-squared, bed-factor, reference-sensor, and with --difference-axis own-axis and
    /// serial; baseline (the simple reference: rises and operating state at a small fixed
    /// ridge, always fitted and reported beside the choice). Default: chosen automatically among
    /// all of them but static and transfer2 (see --selection).
    #[arg(long)]
    pub(crate) family: Option<Families>,
    /// Fix the ridge parameter(s), comma-separated, each 0–10¹². Default: chosen automatically.
    #[arg(long)]
    pub(crate) ridge: Option<Ridges>,
    /// How inner-CV scores choose a family's ridge: simplest (the most regularised candidate
    /// within one standard error of the best) or lowest (the lowest CV error). Default:
    /// simplest, and lowest with --selection paired.
    #[arg(long)]
    pub(crate) rule: Option<Rule>,
    /// How the families are decided between: blend (each family's out-of-fold predictions
    /// combined, the default) or paired (the best family kept only where it beats the baseline
    /// fold by fold, one ridge scale per sensor, a short ridge grid; docs/fitting.md).
    #[arg(long, default_value = "blend")]
    pub(crate) selection: Selection,
    /// Use at most this many temperature sensors (correlation ranking + greedy forward
    /// selection), 1–1000.
    #[arg(long, value_parser = int_in(1usize, 1000))]
    pub(crate) max_sensors: Option<usize>,
    /// The reference sensor of the reference-sensor regression (an input temperature column,
    /// e.g. the ambient or a reference spot on the machine): adds the family reference,
    /// Y = Σ k_i·(t_i − t_r) + c, to the candidates.
    #[arg(long)]
    pub(crate) reference: Option<String>,
    /// Blocks of the inner cross-validation on the training part, 2–100.
    #[arg(long, default_value_t = 8, value_parser = int_in(2usize, 100))]
    pub(crate) folds: usize,
    /// Which blocks train the model scored on a held-out block: blocked (all others) or rolling
    /// (only those before it, as time goes; the first two blocks only train).
    #[arg(long, default_value = "blocked")]
    pub(crate) inner_cv: InnerCv,
    /// A machine description (TOML): the position families are fitted too, from its channels
    /// and axis positions, and targets are taken as measured.
    #[arg(long)]
    pub(crate) machine: Option<PathBuf>,
    /// Without a machine file: the machine name written into the model file.
    #[arg(long, default_value = "unnamed", conflicts_with = "machine")]
    pub(crate) machine_name: String,
    /// Write the model here (JSON): the same selection and fit on every row of every run — the
    /// validation measures that procedure on its folds and the figures are theirs.
    #[arg(long)]
    pub(crate) model: Option<PathBuf>,
    /// The machine axis a target compensates, `<target>=<axis>` (repeat; e.g. `ch5_um=Z`). A
    /// target named `Z`, `Z_um` or `dz_um` needs none; others without one are not applied.
    #[arg(long = "axis")]
    pub(crate) axes: Vec<TargetAxis>,
    /// Write the model even if a target names no axis (by --axis or by its name): that target
    /// is then not applied. Without it such a model is refused, naming the --axis to give.
    #[arg(long)]
    pub(crate) allow_unmapped: bool,
    /// Write measured and predicted values of every run here (CSV), for reports: each row
    /// predicted by the model of the fold that held it out; column `held_out` says which rows
    /// no fold held out (a chronological split's training part, predicted in-sample).
    #[arg(long)]
    pub(crate) predictions: Option<PathBuf>,
    /// Write an HTML report of the validation here (folder): out-of-fold predictions over the
    /// runs, a table per held-out run, temperatures, the protocol.
    #[arg(long)]
    pub(crate) report: Option<PathBuf>,
    /// Write the model even when its predictions on its own training data are non-finite or
    /// more than 10 × the largest measured |error| there.
    #[arg(long)]
    pub(crate) force: bool,
    /// Print the figures as JSON.
    #[arg(long)]
    pub(crate) json: bool,
}

/// The runs named on the command line, as one dataset.
pub(crate) fn load(args: &Args, inputs: &Patterns) -> Result<(Dataset, Vec<RunTable>), CliError> {
    let tables = tables(args)?;
    let columns = Columns {
        time: args
            .shape
            .time(Some(&args.time))
            .unwrap_or(Time::Column(args.time.clone())),
        inputs: inputs.clone(),
        targets: match &args.target {
            Some(t) => t.clone(),
            None => default_targets(tables.first().map_or(&[][..], |t| &t.columns))?,
        },
        operating: args.operating.clone(),
    };
    let ds = Dataset::from_tables(&tables, &columns)?;
    let rows = ds.runs.iter().map(|r| r.time_s.len()).sum();
    truepos_fit::dataset::check_budget(ds.input_names.len(), rows).map_err(CliError::Refused)?;
    Ok((ds, tables))
}

/// The columns a fit takes as targets when `--target` is not given: those whose name states a
/// displacement unit finer than a millimetre (µm, nm), as measured drifts are written —
/// positions in mm are not targets.
fn default_targets(columns: &[String]) -> Result<Patterns, CliError> {
    use truepos_io::units::{unit_of, Unit};
    let found: Vec<String> = columns
        .iter()
        .filter(|c| matches!(unit_of(c), Ok(Some(Unit::Micrometre | Unit::Nanometre))))
        .cloned()
        .collect();
    if found.is_empty() {
        return Err(CliError::refused(format!(
            "no column states µm or nm as its unit (`dz_um`, `Z-Drift [µm]`), so there is no \
             default target; name the measured errors with --target. The columns are: {}",
            columns.join(", ")
        )));
    }
    Ok(Patterns(found))
}

/// The run tables named on the command line.
pub(crate) fn tables(args: &Args) -> Result<Vec<RunTable>, CliError> {
    let mut tables: Vec<RunTable> = Vec::new();
    let shape = args.shape.shape();
    for path in &args.runs {
        tables.extend(read_shaped(path, args.sheet.as_deref(), &shape)?);
    }
    Ok(tables)
}

pub(crate) fn settings(args: &Args, ds: &Dataset) -> Result<Settings, CliError> {
    let defaults = match args.selection {
        Selection::Blend => Settings::default(),
        Selection::Paired => Settings::paired(),
    };
    let families = match &args.family {
        Some(f) => f.filtered.clone(),
        None => defaults.families,
    };
    Ok(Settings {
        families,
        ridges: args.ridge.clone().map_or(defaults.ridges, |r| r.0),
        position_ridges: args.ridge.clone().map_or(defaults.position_ridges, |r| r.0),
        position_rule: args.rule.unwrap_or(defaults.position_rule),
        folds: args.folds,
        inner: args.inner_cv,
        rule: args.rule.unwrap_or(defaults.rule),
        selection: args.selection,
        max_sensors: args.max_sensors,
        reference: match &args.reference {
            Some(name) => Some(
                ds.temperature_input(name)
                    .map_err(CliError::context("--reference "))?,
            ),
            None => None,
        },
        taus: defaults.taus,
        absolute_targets: false,
    })
}

/// A progress bar on stderr for fits that take longer than a second.
pub(crate) struct Progress {
    pub(crate) start: Instant,
}

impl Progress {
    pub(crate) fn update(&mut self, done: usize, total: usize) {
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
pub fn run(args: Args) -> Result<(), CliError> {
    for out in [&args.model, &args.predictions].into_iter().flatten() {
        crate::write::check(out, &input_files(&args))?;
    }
    if let Some(path) = args.machine.clone() {
        return machine::run(args, &path);
    }
    if let Some(f) = args.family.as_ref().and_then(|f| f.position.first()) {
        return Err(CliError::refused(format!(
            "--family {f}: a position family needs a machine file (--machine MACHINE.toml)"
        )));
    }
    let inputs = args.inputs.clone().ok_or_else(|| {
        CliError::refused("--inputs is required without a machine file (--machine MACHINE.toml)")
    })?;
    if let Some(path) = &args.model {
        model_name(
            path,
            &["json"],
            "a model fitted without a machine file is a dynamic model",
        )?;
    }
    let (ds, _) = load(&args, &inputs)?;
    if args.model.is_some() && !args.allow_unmapped {
        unmapped(&ds, &args.axes)?;
    }
    let settings = settings(&args, &ds)?;
    let mut progress = Progress {
        start: Instant::now(),
    };
    let outcome = fit(&ds, args.split, &settings, &mut |d, t| {
        progress.update(d, t)
    })
    // Validation refuses in a sentence of its own (too few rows, a split it cannot make).
    .map_err(CliError::Refused)?;
    let validation = &outcome.validation;
    let warnings = fit_warnings(&args, &ds, &outcome)?;
    let report = serde_json::json!({
        "held_out_rows_beyond_training": validation.held_out_rows_beyond_training,
        "runs": ds.runs.iter().map(|r| serde_json::json!({"name": r.name, "samples": r.len(), "measured": r.measured_rows()})).collect::<Vec<_>>(),
        "inputs": ds.input_names,
        "targets": ds.target_names,
        "validation": validation,
        "warnings": warnings,
    });
    write_outputs(&args, &ds, &settings, &outcome, &warnings)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    print_validation(&ds, &outcome);
    Ok(())
}

/// The warnings a fit prints and records: the validation's own, runs measured late, an
/// implausible model the user forced through, and held-out rows beyond the training range.
/// Refuses an implausible model unless forced.
fn fit_warnings(args: &Args, ds: &Dataset, outcome: &Outcome) -> Result<Vec<String>, CliError> {
    let validation = &outcome.validation;
    let mut warnings = validation.warnings.clone();
    warnings.extend(late_first_measurements(ds));
    if let Err(bad) = plausible(ds, outcome) {
        warnings.extend(forced(args, &bad)?);
    }
    warnings.extend(beyond_training(validation.held_out_rows_beyond_training));
    Ok(warnings)
}

/// Writes what the command line asked for: the model file, the held-out predictions, the
/// report directory; each file whole or not at all.
fn write_outputs(
    args: &Args,
    ds: &Dataset,
    settings: &Settings,
    outcome: &Outcome,
    warnings: &[String],
) -> Result<(), CliError> {
    if let Some(path) = &args.model {
        let created_by = format!("truepos fit {}", env!("CARGO_PKG_VERSION"));
        let file = model_file(
            ds,
            settings,
            outcome,
            &args.machine_name,
            &args.axes,
            &created_by,
        )
        .map_err(CliError::context("--axis: "))?;
        crate::write::write_whole(path, file.to_json() + "\n", &input_files(args))?;
    }
    if let Some(path) = &args.predictions {
        crate::write::write_whole(path, predictions_csv(ds, outcome), &input_files(args))?;
    }
    if let Some(dir) = &args.report {
        report::write(dir, ds, outcome, warnings)?;
    }
    Ok(())
}

/// The protocol and the head of the table [`print_held_out`] writes the rows of.
pub(crate) fn print_held_out_head(protocol_text: &str) {
    println!("validation: {protocol_text}");
    println!(
        "{:<12} {:>10} {:>10} {:>10} {:>10} {:>9}  chosen (inner CV on the training part)",
        "target", "uncomp µm", "RMSE µm", "max|e| µm", "p-p µm", "reduction"
    );
}

/// One target's held-out figures and what the inner cross-validation chose for it.
pub(crate) fn print_held_out(m: &Metrics, chosen: &str) {
    println!(
        "{:<12} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>8.1}%  {chosen}",
        m.target,
        m.uncompensated_rmse_um,
        m.rmse_um,
        m.max_abs_um,
        m.peak_to_peak_um,
        m.rmse_reduction_percent,
    );
}

/// The validation for a person: per target the held-out figures beside what the inner
/// cross-validation chose, the baseline, how far the test error strays from the inner
/// estimate, the sensors used, and per run when there are several.
fn print_validation(ds: &Dataset, outcome: &Outcome) {
    let Outcome {
        validation,
        trained,
        ..
    } = outcome;
    print_held_out_head(&validation.protocol_text);
    for (m, c) in validation.metrics.iter().zip(&trained.choices) {
        let baseline = c
            .baseline_cv_rmse_um
            .map_or(String::new(), |b| format!(", baseline CV {b:.2} µm"));
        print_held_out(
            m,
            &format!("{} (CV {:.2} µm{baseline})", c.describe(), c.cv_rmse_um),
        );
    }
    for c in &trained.choices {
        if let Some(p) = &c.paired {
            println!("{}: {}", c.target, p.describe());
        }
    }
    if let Some(base) = &validation.baseline_metrics {
        let figures: Vec<String> = base
            .iter()
            .map(|m| format!("{} {:.2} µm", m.target, m.rmse_um))
            .collect();
        println!(
            "the baseline on the same held-out rows (the simple reference: rises and operating state): {}",
            figures.join(", ")
        );
    }
    let ratios: Vec<String> = validation
        .inner_vs_test
        .iter()
        .map(|r| {
            format!(
                "{} {:.2}/{:.2} = {:.2}",
                r.target, r.test_rmse_um, r.inner_cv_rmse_um, r.test_to_inner
            )
        })
        .collect();
    println!("test / inner-CV RMSE: {}", ratios.join(", "));
    let sensors = validation.sensors.last().cloned().unwrap_or_default();
    println!("temperature sensors used: {}", sensors.join(", "));
    if ds.runs.iter().any(|r| r.measured_rows() < r.len()) {
        let runs: Vec<String> = ds
            .runs
            .iter()
            .map(|r| format!("{} {} of {}", r.name, r.measured_rows(), r.len()))
            .collect();
        println!(
            "rows with a measurement (the others only step the filters): {}",
            runs.join(", ")
        );
    }
    if ds.runs.len() > 1 {
        print_per_run(validation);
    }
}

/// The figures of each run's held-out rows, one line per run and target: a pooled figure can
/// hide a run the model makes worse.
pub(crate) fn print_per_run(validation: &Validation) {
    let width = validation
        .per_run
        .iter()
        .map(|r| r.run.chars().count())
        .max()
        .unwrap_or(3)
        .max(3);
    println!("per held-out run:");
    println!(
        "{:<width$} {:<12} {:>7} {:>10} {:>10} {:>10} {:>9} {:>11}  chosen",
        "run", "target", "rows", "uncomp µm", "RMSE µm", "max|e| µm", "reduction", "baseline µm"
    );
    for r in &validation.per_run {
        for h in &r.targets {
            let m = &h.metrics;
            let baseline = h
                .baseline_rmse_um
                .map_or("—".to_string(), |b| format!("{b:.2}"));
            println!(
                "{:<width$} {:<12} {:>7} {:>10.2} {:>10.2} {:>10.2} {:>8.1}% {:>11}  {}",
                r.run,
                m.target,
                m.samples,
                m.uncompensated_rmse_um,
                m.rmse_um,
                m.max_abs_um,
                m.rmse_reduction_percent,
                baseline,
                h.family
            );
        }
    }
}

/// A warning for every run whose first measurement is not at its first row: its targets are
/// taken relative to that measurement as if it were the run's start.
fn late_first_measurements(ds: &Dataset) -> Vec<String> {
    ds.runs
        .iter()
        .filter_map(|r| {
            let first = r.first_measured()?;
            (first > 0).then(|| {
                format!(
                    "run {}: the first row with every target measured is row {} (t = {} s): its errors are taken relative to that row as if it were the run's start; measure at the start of a run",
                    r.name, first + 1, r.time_s[first] - r.time_s[0]
                )
            })
        })
        .collect()
}

/// Refuses a model file name whose extension is not one of `forms` (`json`, `toml`): a loader
/// tells the forms apart by the name, so a JSON model named `.toml` could not be read back.
pub(crate) fn model_name(path: &Path, forms: &[&str], why: &str) -> Result<(), CliError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref().is_some_and(|e| forms.contains(&e)) {
        return Ok(());
    }
    let stem = path.with_extension(forms[0]);
    Err(CliError::refused(format!(
        "--model {}: {why}, written as {}: name it {}",
        path.display(),
        forms
            .iter()
            .map(|f| f.to_uppercase())
            .collect::<Vec<_>>()
            .join(" or "),
        stem.display()
    )))
}

/// Whether a target serves an axis by its name alone, as the model file's loader reads it
/// (`Z`, `Z_um`, `dz_um`), for any of the axis letters a machine file uses.
fn names_an_axis(target: &str) -> bool {
    ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"]
        .iter()
        .any(|a| truepos_io::model_file::filtered::names_axis(target, a))
}

/// Refuses a fit whose model would leave a target unapplied: one named by no --axis and by no
/// axis name, with the exact option to give.
fn unmapped(ds: &Dataset, axes: &[TargetAxis]) -> Result<(), CliError> {
    let missing: Vec<&String> = ds
        .target_names
        .iter()
        .filter(|t| !names_an_axis(t) && !axes.iter().any(|a| &a.target == *t))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let options: Vec<String> = missing
        .iter()
        .map(|t| format!("--axis '{t}=<axis>'"))
        .collect();
    Err(CliError::refused(format!(
        "the model would compensate no axis for {}: its name names none; give {} (e.g. \
         --axis '{}=Z'), or --allow-unmapped to write it with that target not applied",
        missing
            .iter()
            .map(|t| format!("target `{t}`"))
            .collect::<Vec<_>>()
            .join(", "),
        options.join(" "),
        missing[0]
    )))
}

/// The warning for held-out rows with an input beyond their fold's training range, if any.
/// A model whose predictions on its own training data are implausible is refused, naming each
/// figure, unless the person typed `--force`; then the figures become warnings.
fn forced(args: &Args, bad: &[impl ToString]) -> Result<Vec<String>, CliError> {
    let what: Vec<String> = bad.iter().map(ToString::to_string).collect();
    if !args.force {
        let out = args.model.as_ref().map_or("the model".into(), |p| {
            format!("refusing to write {}", p.display())
        });
        return Err(CliError::refused(format!(
            "{out}: {}; check the targets, or --force to write it anyway",
            what.join("; ")
        )));
    }
    Ok(what.into_iter().map(|w| format!("--force: {w}")).collect())
}

pub(crate) fn beyond_training(rows: usize) -> Option<String> {
    (rows > 0).then(|| {
        format!(
            "{rows} held-out rows have an input beyond the range their fold's model was trained on \
             (widened by its margin): the figures above extrapolate there, while on the machine \
             the model is clamped to that range and capped (docs/fitting.md, \"Where a model was \
             trained\")"
        )
    })
}
