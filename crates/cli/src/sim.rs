//! `truepos sim`: run the thermal twin on a scenario and write the run as CSV.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use crate::error::CliError;
use truepos_sim::{Scenario, SimRun, Summary, Twin, TwinParams, AXES, BUILTIN};

/// Rounds to 3 decimals for printing (µm, °C, mm).
fn r3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0 + 0.0
}

/// Arguments of `truepos sim`.
#[derive(clap::Args)]
pub struct Args {
    /// A built-in scenario (spindle-warmup, linear-axis, environment, mixed-shift,
    /// mixed-shift-b) or a scenario TOML file.
    #[arg(long, default_value = "mixed-shift")]
    scenario: String,
    /// A twin description (TOML) overriding the reference machine's physical parameters, e.g.
    /// examples/twin/twin-chilled.toml. Default: the built-in reference machine.
    #[arg(long)]
    twin: Option<PathBuf>,
    /// Output CSV (`-` for standard output). Default: `sim-<scenario>.csv`.
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Seed of the random draws (noise, random motion); the same seed gives the same run.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sampling period of the CSV rows in s, 0.01–86 400 and a whole multiple of the scenario's
    /// step (overrides the scenario's `sample_s`; at most 300 000 rows in all).
    #[arg(long, value_parser = truepos_io::limits::finite_in(0.01, 86_400.0))]
    sample_s: Option<f64>,
    /// Also write the true ambient and every thermal node's temperature (`node:<name>`).
    #[arg(long)]
    nodes: bool,
    /// Print a built-in scenario's TOML (to copy and edit) and exit.
    #[arg(long, value_name = "NAME")]
    print_scenario: Option<String>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> Result<(), CliError> {
    if let Some(name) = &args.print_scenario {
        let text = Scenario::builtin_toml(name).ok_or_else(|| {
            CliError::refused(format!(
                "no built-in scenario \"{name}\"; built-ins: {}",
                BUILTIN.join(", ")
            ))
        })?;
        print!("{text}");
        return Ok(());
    }
    if let Some(out) = args.out.as_deref().filter(|o| o.as_os_str() != "-") {
        let mut inputs: Vec<(&str, &Path)> = vec![("--scenario", Path::new(&args.scenario))];
        inputs.extend(args.twin.as_deref().map(|t| ("--twin", t)));
        crate::write::check(out, &inputs)?;
    }
    let twin = load_twin(&args)?;
    let scenario = load_scenario(&args, &twin)?;
    let run = simulate(&twin, &scenario, args.seed)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("sim-{}.csv", scenario.name)));
    let scenario_file = Path::new(&args.scenario);
    let scenario_file = scenario_file.is_file().then_some(scenario_file);
    write_run(&run, &out, args.nodes, args.twin.as_deref(), scenario_file)?;
    let s = run.summary();
    if args.json {
        println!("{}", summary_json(&run, &s, &out));
    } else if out.as_os_str() != "-" {
        print_summary(&run, &s, &out);
    }
    Ok(())
}

/// The reference machine, or the twin description `--twin` names.
fn load_twin(args: &Args) -> Result<Twin, CliError> {
    Ok(match &args.twin {
        None => Twin::reference(),
        Some(path) => {
            let text = truepos_files::read::read_text(path, truepos_files::CONFIG)
                .map_err(CliError::context(format!("--twin {}: ", path.display())))?;
            let params = TwinParams::parse(&text, &path.display().to_string())?;
            Twin::from_params(&params)
        }
    })
}

/// The built-in scenario or scenario file `--scenario` names, with `--sample-s` applied.
fn load_scenario(args: &Args, twin: &Twin) -> Result<Scenario, CliError> {
    let mut scenario = match Scenario::builtin(&args.scenario) {
        Some(s) => s,
        None => {
            let path = PathBuf::from(&args.scenario);
            let src = truepos_files::read::read_text(&path, truepos_files::CONFIG).map_err(
                CliError::context(format!(
                    "--scenario {}: neither a built-in scenario ({}) nor a readable file: ",
                    args.scenario,
                    BUILTIN.join(", ")
                )),
            )?;
            Scenario::parse(&src, &path.display().to_string(), Some(twin.travel_mm))?
        }
    };
    if let Some(s) = args.sample_s {
        let ratio = s / scenario.step_s;
        if !(s.is_finite() && s >= scenario.step_s && (ratio - ratio.round()).abs() < 1e-9) {
            return Err(CliError::refused(format!(
                "--sample-s must be a whole multiple of the scenario's step ({} s), got {s}",
                scenario.step_s
            )));
        }
        scenario.sample_s = s;
        scenario
            .check_size()
            .map_err(CliError::context(format!("--sample-s {s}: ")))?;
    }
    Ok(scenario)
}

/// Runs the twin, with a progress bar on a terminal (not under CI).
fn simulate(twin: &Twin, scenario: &Scenario, seed: u64) -> Result<SimRun, CliError> {
    let show_bar = std::io::stderr().is_terminal() && std::env::var_os("CI").is_none();
    let bar = show_bar.then(|| {
        let b = indicatif::ProgressBar::new(1000);
        b.set_style(
            indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({elapsed})")
                .expect("valid template")
                .progress_chars("=> "),
        );
        b.set_message(format!("simulating {} h", fmt_h(scenario.duration_s())));
        b
    });
    let run = twin.run_with_progress(scenario, seed, &mut |f| {
        if let Some(b) = &bar {
            b.set_position((f * 1000.0) as u64);
        }
    })?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    Ok(run)
}

/// Writes the run's CSV to `out` (`-`: standard output).
fn write_run(
    run: &SimRun,
    out: &Path,
    nodes: bool,
    twin: Option<&Path>,
    scenario: Option<&Path>,
) -> Result<(), CliError> {
    if out.as_os_str() == "-" {
        run.write_csv(std::io::stdout().lock(), nodes)
            .map_err(CliError::context("writing CSV: "))?;
    } else {
        let mut inputs: Vec<(&str, &Path)> = Vec::new();
        inputs.extend(twin.map(|t| ("--twin", t)));
        inputs.extend(scenario.map(|s| ("--scenario", s)));
        let mut f = crate::write::create(out, &inputs)?;
        run.write_csv(std::io::BufWriter::new(&mut f), nodes)
            .map_err(CliError::file(out, None))?;
        f.commit()?;
    }
    Ok(())
}

/// The summary as JSON (`--json`).
fn summary_json(run: &SimRun, s: &Summary, out: &Path) -> serde_json::Value {
    let dirs = ["dx_um", "dy_um", "dz_um"];
    let peak: serde_json::Map<String, serde_json::Value> = dirs
        .iter()
        .zip(&s.peak_error)
        .map(|(d, (v, t, p))| {
            let pos: serde_json::Map<String, serde_json::Value> = AXES
                .iter()
                .zip(p)
                .map(|(a, v)| (format!("{a}_mm"), serde_json::json!(r3(*v))))
                .collect();
            (
                d.to_string(),
                serde_json::json!({ "value_um": r3(*v), "time_s": t, "position": pos }),
            )
        })
        .collect();
    let pos_json = |p: &[f64; 3]| -> serde_json::Value {
        AXES.iter()
            .zip(p)
            .map(|(a, v)| (format!("{a}_mm"), serde_json::json!(r3(*v))))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    let t63: serde_json::Map<String, serde_json::Value> = dirs
        .iter()
        .zip(&s.t63_s)
        .map(|(d, t)| (d.to_string(), serde_json::json!(t)))
        .collect();
    let spread: serde_json::Map<String, serde_json::Value> = dirs
        .iter()
        .zip(&s.probe_spread)
        .map(|(d, sp)| {
            let v = match sp {
                Some((t, (lo, plo), (hi, phi))) => serde_json::json!({
                    "time_s": t,
                    "min": { "value_um": r3(*lo), "position": pos_json(plo) },
                    "max": { "value_um": r3(*hi), "position": pos_json(phi) },
                    "spread_um": r3(hi - lo),
                }),
                None => serde_json::Value::Null,
            };
            (d.to_string(), v)
        })
        .collect();
    let temps: serde_json::Map<String, serde_json::Value> = s
        .peak_sensor_c
        .iter()
        .map(|(id, v)| (id.clone(), serde_json::json!(r3(*v))))
        .collect();
    serde_json::json!({
        "machine": run.machine,
        "scenario": run.scenario,
        "seed": run.seed,
        "csv": if out.as_os_str() == "-" { serde_json::Value::Null } else { serde_json::json!(out.display().to_string()) },
        "duration_s": s.duration_s,
        "rows": s.rows,
        "probe_points": s.probe_points,
        "thermal_nodes": s.nodes,
        "peak_error": peak,
        "t63_s": t63,
        "probe_spread": spread,
        "peak_sensor_c": temps,
        "peak_node": { "name": s.peak_node.0, "temperature_c": r3(s.peak_node.1) },
    })
}

/// The summary for a person.
fn print_summary(run: &SimRun, s: &Summary, out: &Path) {
    println!(
        "{} on {}: {} h, {} rows, {} probe points, {} thermal nodes → {}",
        run.scenario,
        run.machine,
        fmt_h(s.duration_s),
        s.rows,
        s.probe_points,
        s.nodes,
        out.display()
    );
    for (d, (v, t, p)) in ["dx", "dy", "dz"].iter().zip(&s.peak_error) {
        println!(
            "  peak {d} {v:+8.1} µm at {:.2} h, X {:.0} Y {:.0} Z {:.0} mm",
            t / 3600.0,
            p[0],
            p[1],
            p[2]
        );
    }
    for (d, t) in ["dx", "dy", "dz"].iter().zip(&s.t63_s) {
        if let Some((ts, (lo, plo), (hi, phi))) =
            s.probe_spread[["dx", "dy", "dz"].iter().position(|x| x == d).unwrap_or(0)]
        {
            println!(
                "  {d}: 63 % of its peak after {:.2} h; largest spread over one probing cycle (at {:.2} h): {lo:+.1} µm at X {:.0} Y {:.0} Z {:.0} → {hi:+.1} µm at X {:.0} Y {:.0} Z {:.0}",
                t / 3600.0,
                ts / 3600.0,
                plo[0], plo[1], plo[2], phi[0], phi[1], phi[2]
            );
        } else {
            println!("  {d}: 63 % of its peak after {:.2} h", t / 3600.0);
        }
    }
    let hottest: Vec<String> = s
        .peak_sensor_c
        .iter()
        .map(|(id, v)| format!("{id} {v:.1}"))
        .collect();
    println!("  peak sensor readings (°C): {}", hottest.join(", "));
}

fn fmt_h(s: f64) -> String {
    format!("{:.1}", s / 3600.0)
}
