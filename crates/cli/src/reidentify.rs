//! `truepos reidentify`: probing re-identification of an existing model from probe
//! measurements — the service's log (`--log`, its `probes` table) or a run CSV with probe
//! columns (`--run`) — and, when the switch rule says so, a new model file whose provenance
//! names its parent and the data window.
//!
//! Exit status: 0 with a new model written (`"status": "switched"`); 3 when the running model
//! stays (`"status": "kept"`, the reason said, nothing written); 1 on an error.

mod plausible;
pub(crate) mod probes_csv;
mod probes_log;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use sha2::{Digest, Sha256};
use truepos_fit::reidentify::{reidentify, Outcome, Settings, Verdict};
use truepos_io::limits::finite_in;
use truepos_io::model_file::position::ModelFile;
use truepos_io::{machine_file, model_file};
use truepos_model::{Machine, Model};

use crate::error::CliError;

/// Exit status when the running model stays and nothing is written.
pub const KEPT: u8 = 3;

/// Arguments of `truepos reidentify`.
#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("probes").required(true).args(["log", "run"])))]
pub struct Args {
    /// Machine description (TOML).
    #[arg(long)]
    machine: PathBuf,
    /// The model running now: a position-dependent thermal model or a reference-sensor
    /// regression (TOML, or JSON by extension). Its structure is kept, its parameters
    /// re-estimated.
    #[arg(long)]
    model: PathBuf,
    /// The service's SQLite log: the accepted events of its `probes` table.
    #[arg(long)]
    log: Option<PathBuf>,
    /// A run CSV whose rows with `probe_d<axis>_um` values are probe events (`probe_<axis>_mm`:
    /// where the probe touched).
    #[arg(long)]
    run: Option<PathBuf>,
    /// Where to write the re-identified model (TOML), only if the re-estimated parameters
    /// are clearly better than the running ones.
    #[arg(long)]
    out: PathBuf,
    /// Forgetting factor of the recursive least squares, 0.5–1. The default 0.999 remembers
    /// about 1000 measurements (days of a probe cycle every few minutes): a shorter memory
    /// lets the parameters that the recent probes do not excite wander (on the twin, 0.98
    /// makes the later error three times worse than the old model's).
    #[arg(long, default_value_t = 0.999, value_parser = finite_in(0.5, 1.0))]
    lambda: f64,
    /// Recent RMS error of the running model (µm) above which a switch is considered, 0–1000.
    #[arg(long, default_value_t = 3.0, value_parser = finite_in(0.0, 1000.0))]
    threshold_um: f64,
    /// Most recent measurements on which the new parameters must beat the old ones, 1–100 000.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    window: u32,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

/// The files `truepos reidentify` reads, which its output may not be.
fn inputs(args: &Args) -> Vec<(&'static str, &Path)> {
    let mut inputs: Vec<(&str, &Path)> =
        vec![("--machine", &args.machine), ("--model", &args.model)];
    inputs.extend(args.log.as_deref().map(|l| ("--log", l)));
    inputs.extend(args.run.as_deref().map(|r| ("--run", r)));
    inputs
}

pub fn run(args: Args) -> Result<ExitCode, CliError> {
    crate::write::check(&args.out, &inputs(&args))?;
    if args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return Err(CliError::refused(format!(
            "--out {}: the re-identified model is written as TOML; give a .toml file",
            args.out.display()
        )));
    }
    let config = machine_file::load(&args.machine)?;
    let machine = config.machine;
    let parent_text = crate::write::read(&args.model, truepos_files::MODEL)?;
    let loaded = model_file::load(&args.model, &machine)?;
    let Some(model) = loaded.model.as_static() else {
        return Err(CliError::refused(format!(
            "{}: a fitted dynamic model cannot be re-identified from probe measurements (its \
             filters need the whole history); refit it with `truepos fit`, or re-identify a \
             position-dependent or reference-sensor model",
            args.model.display()
        )));
    };
    let (events, rejected, source) = match (&args.log, &args.run) {
        (Some(log), _) => {
            let (events, rejected) = probes_log::read(log, &machine)?;
            (events, rejected, log)
        }
        (None, Some(run)) => (
            probes_csv::read(run, &machine, model.used_sensors())?,
            0,
            run,
        ),
        (None, None) => unreachable!("clap requires --log or --run"),
    };
    let (events, implausible) = plausible::within_envelope(events, &machine, &config.axes);
    let settings = Settings {
        lambda: args.lambda,
        threshold_um: args.threshold_um,
        window: args.window as usize,
    };
    let outcome = reidentify(model, &machine, &events, settings);
    let parent = Parent::of(&args.model, &parent_text);
    let mut outcome = outcome;
    if let Some(new) = &mut outcome.model {
        plausible::check_model(new, &events, &machine, &config.axes)?;
        plausible::check_move(model, new, &machine)?;
    }
    let written = match &outcome.model {
        Some(new) => Some(write_model(
            &args,
            &machine,
            new,
            loaded.axis_index.as_deref(),
            &parent,
            source,
            &outcome,
        )?),
        None => None,
    };
    print(
        &args,
        &parent,
        source,
        &outcome,
        (rejected, &implausible),
        written,
    )?;
    Ok(match outcome.verdict {
        Verdict::Switched => ExitCode::SUCCESS,
        Verdict::Kept => ExitCode::from(KEPT),
    })
}

/// The model re-identification starts from: its file, content hash and generation.
struct Parent {
    file: String,
    sha256: String,
    generation: i64,
}

impl Parent {
    fn of(path: &Path, bytes: &[u8]) -> Self {
        let sha256 = Sha256::digest(bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        // A model no re-identification wrote is generation 1.
        let generation = std::str::from_utf8(bytes)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .and_then(|t| t.get("provenance")?.get("generation")?.as_integer())
            .unwrap_or(1);
        Self {
            file: path.display().to_string(),
            sha256,
            generation,
        }
    }
}

/// Writes the new model beside `--out` and renames it into place, so that a reader (the
/// service reloading it) sees the old file or the whole new one, never a part. The text is
/// loaded through the one door before it is renamed: what is written is what loads.
fn write_model(
    args: &Args,
    machine: &Machine,
    model: &Model,
    axis_index: Option<&[u32]>,
    parent: &Parent,
    source: &Path,
    outcome: &Outcome,
) -> Result<i64, CliError> {
    let generation = parent.generation + 1;
    let mut file = ModelFile::from_model(model, machine);
    file.axis_index = axis_index.map(<[u32]>::to_vec);
    file.description = format!(
        "re-identified from {} probe measurements of {}",
        outcome.measurements,
        source.display()
    );
    let mut p = toml::Table::new();
    p.insert("tool".into(), "truepos reidentify".into());
    p.insert("generation".into(), generation.into());
    let mut parent_t = toml::Table::new();
    parent_t.insert("file".into(), parent.file.clone().into());
    parent_t.insert("sha256".into(), parent.sha256.clone().into());
    parent_t.insert("generation".into(), parent.generation.into());
    p.insert("parent".into(), parent_t.into());
    let mut data = toml::Table::new();
    data.insert("source".into(), source.display().to_string().into());
    data.insert("first_time_s".into(), outcome.first_time_s.into());
    data.insert("last_time_s".into(), outcome.last_time_s.into());
    data.insert("events".into(), (outcome.events as i64).into());
    data.insert("measurements".into(), (outcome.measurements as i64).into());
    p.insert("data".into(), data.into());
    let mut method = toml::Table::new();
    method.insert("lambda".into(), args.lambda.into());
    method.insert("threshold_um".into(), args.threshold_um.into());
    method.insert("window".into(), i64::from(args.window).into());
    method.insert("switches".into(), (outcome.switches as i64).into());
    p.insert("method".into(), method.into());
    file.provenance = p;
    let mut v = toml::Table::new();
    v.insert(
        "window_measurements".into(),
        (outcome.window.measurements as i64).into(),
    );
    v.insert(
        "window_old_rmse_um".into(),
        outcome.window.old_rmse_um.into(),
    );
    v.insert(
        "window_new_rmse_um".into(),
        outcome.window.new_rmse_um.into(),
    );
    file.validation = v;
    let text = file.to_toml();
    model_file::parse(&args.out, &text, machine).map_err(CliError::context(
        "the re-identified model does not load back (a bug; nothing written): ",
    ))?;
    crate::write::write_whole(&args.out, text.as_bytes(), &inputs(args))?;
    Ok(generation)
}

fn print(
    args: &Args,
    parent: &Parent,
    source: &Path,
    o: &Outcome,
    (rejected, implausible): (usize, &[String]),
    generation: Option<i64>,
) -> Result<(), CliError> {
    let status = match o.verdict {
        Verdict::Switched => "switched",
        Verdict::Kept => "kept",
    };
    let finite = |v: f64| v.is_finite().then_some(v);
    if args.json {
        let v = serde_json::json!({
            "status": status,
            "reason": o.reason,
            "parent": { "file": parent.file, "sha256": parent.sha256, "generation": parent.generation },
            "out": generation.map(|_| args.out.display().to_string()),
            "generation": generation,
            "data": {
                "source": source.display().to_string(),
                "events": o.events,
                "rejected_by_the_service": rejected,
                "beyond_the_envelope": implausible,
                "measurements": o.measurements,
                "skipped": o.skipped,
                "first_time_s": finite(o.first_time_s),
                "last_time_s": finite(o.last_time_s),
            },
            "switches": o.switches,
            "recent_rms_um": { "running": finite(o.recent_rms_um.0), "candidate": finite(o.recent_rms_um.1) },
            "window": {
                "measurements": o.window.measurements,
                "old_rmse_um": finite(o.window.old_rmse_um),
                "new_rmse_um": finite(o.window.new_rmse_um),
            },
        });
        println!("{v}");
        return Ok(());
    }
    println!(
        "{} probe events ({rejected} more rejected by the service), {} measurements used, {} skipped; time {:.1} … {:.1} s ({})",
        o.events,
        o.measurements,
        o.skipped.len(),
        o.first_time_s,
        o.last_time_s,
        source.display()
    );
    for s in implausible.iter().take(5) {
        println!("  left out: {s}");
    }
    if implausible.len() > 5 {
        println!(
            "  … {} more left out beyond the envelope",
            implausible.len() - 5
        );
    }
    for s in o.skipped.iter().take(5) {
        println!("  skipped: {s} (an input outside the model's valid range)");
    }
    println!(
        "re-estimation: {} switch(es); recent RMS error running {:.2} µm, candidate {:.2} µm (threshold {:.2} µm)",
        o.switches, o.recent_rms_um.0, o.recent_rms_um.1, args.threshold_um
    );
    println!(
        "last {} measurements: old model {:.2} µm RMS, new model {:.2} µm RMS",
        o.window.measurements, o.window.old_rmse_um, o.window.new_rmse_um
    );
    match generation {
        Some(g) => println!(
            "switched: {}; wrote {} (generation {g}, parent {} sha256 {})",
            o.reason,
            args.out.display(),
            parent.file,
            &parent.sha256[..12]
        ),
        None => println!("kept: {}; nothing written", o.reason),
    }
    Ok(())
}
