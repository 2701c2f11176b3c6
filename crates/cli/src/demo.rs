//! `truepos demo`: the main job on the built-in defaults. The thermal twin runs a training day
//! and a different test day on the reference machine; truepos fits the prior-art
//! (position-independent) and the position-dependent model on the training day only,
//! evaluates both on the test day — at the tool's path and over the whole working volume — prints
//! a before/after table, and writes the model file and the report.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use crate::error::CliError;
use truepos_fit::dataset::{Dataset, Run};
use truepos_fit::family::PositionFamily;
use truepos_fit::machine_fit::{select, Chosen, MachineData, StaticModel};
use truepos_fit::position_model::reference_sensor;
use truepos_fit::settings::Settings;
use truepos_io::{machine_file, model_file::position::ModelFile};
use truepos_model::{CycleInput, Machine, Model, RecordedRun};
use truepos_report::{write_report, Channel, ReportData, VolumeMap};
use truepos_sim::{Scenario, SimRun, Twin};

/// The twin's machine description, built into the binary so the demo needs no files.
const TWIN_MACHINE: &str = include_str!("../../../examples/twin/machine.toml");

/// Arguments of `truepos demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Scenario of the training day (built-in name or TOML file).
    #[arg(long, default_value = "mixed-shift")]
    train: String,
    /// Scenario of the test day, never seen by the fit.
    #[arg(long, default_value = "mixed-shift-b")]
    test: String,
    /// Folder for the model files and the report.
    #[arg(long, default_value = "demo")]
    out: PathBuf,
    /// Grid points per axis for the working-volume check (n × n × n positions), 1–10.
    #[arg(long, default_value_t = 3, value_parser = truepos_io::limits::int_in(1usize, 10))]
    grid: usize,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
}

fn scenario(name: &str) -> Result<Scenario, CliError> {
    match Scenario::builtin(name) {
        Some(s) => Ok(s),
        None => {
            let text = truepos_files::read::read_text(Path::new(name), truepos_files::CONFIG)
                .map_err(CliError::context(format!(
                    "scenario `{name}`: not a built-in ({}) and not a readable file: ",
                    truepos_sim::BUILTIN.join(", ")
                )))?;
            Ok(Scenario::parse(&text, name, None)?)
        }
    }
}

/// A twin run, and the same day as the control saw it (machine-ordered inputs).
struct Day {
    run: SimRun,
    seen: RecordedRun,
}

fn day(twin: &Twin, machine: &Machine, name: &str, seed: u64) -> Result<Day, CliError> {
    let sc = scenario(name)?;
    let run = twin.run(&sc, seed)?;
    let positions = run.rows.iter().map(|r| r.position_mm.to_vec()).collect();
    // What the control knows of its operating state, by the machine's channel ids.
    let operating: Vec<Vec<f64>> = run
        .rows
        .iter()
        .map(|r| {
            machine
                .operating
                .iter()
                .map(|o| match o.id.as_str() {
                    "spindle_rpm" => r.spindle_rpm,
                    "X_speed_mm_min" => r.speed_mm_min[0],
                    "Y_speed_mm_min" => r.speed_mm_min[1],
                    "Z_speed_mm_min" => r.speed_mm_min[2],
                    "coolant_on" => f64::from(u8::from(r.coolant_on)),
                    _ => f64::NAN,
                })
                .collect()
        })
        .collect();
    let time_s: Vec<f64> = run.rows.iter().map(|r| r.time_s).collect();
    let temperatures_c = truepos_io::cycles::machine_temperatures(
        machine,
        &run.sensor_ids,
        &time_s,
        run.rows.iter().map(|r| r.temperatures_c.as_slice()),
        &operating,
    );
    let seen = RecordedRun {
        time_s,
        temperatures_c,
        positions,
        operating,
    };
    Ok(Day { run, seen })
}

fn input(d: &Day, i: usize) -> CycleInput<'_> {
    d.seen.row(i)
}

/// Figures of one model on the test day.
#[derive(Debug, Clone, serde::Serialize)]
struct Figures {
    /// RMS of the residual at the tool's path per direction, µm.
    path_rmse_um: [f64; 3],
    /// Largest |error vector| over the working volume and the day, µm.
    volume_max_um: f64,
}

/// Error vectors of the twin (truth) and of a model over the working volume at every
/// `stride`-th row of the test day; returns the largest |truth − prediction| (or |truth| when
/// `model` is `None`).
fn volume_max(twin: &Twin, d: &Day, model: Option<&Model>, grid: usize, stride: usize) -> f64 {
    let travel = twin.travel_mm;
    let at = |a: usize, k: usize| {
        let [lo, hi] = travel[a];
        if grid <= 1 {
            0.5 * (lo + hi)
        } else {
            lo + (hi - lo) * k as f64 / (grid - 1) as f64
        }
    };
    let mut worst = 0.0_f64;
    for i in (0..d.run.rows.len()).step_by(stride.max(1)) {
        let state = d.run.state(i);
        for kx in 0..grid {
            for ky in 0..grid {
                for kz in 0..grid {
                    let pos = [at(0, kx), at(1, ky), at(2, kz)];
                    let truth = twin.error_um(state, pos);
                    let pred = match model {
                        Some(m) => {
                            let c = m.evaluate(&CycleInput {
                                temperatures_c: &d.seen.temperatures_c[i],
                                positions: &pos,
                                operating: &d.seen.operating[i],
                            });
                            match c {
                                Ok(c) => [c.error_um()[0], c.error_um()[1], c.error_um()[2]],
                                Err(_) => [f64::NAN; 3],
                            }
                        }
                        None => [0.0; 3],
                    };
                    let r: f64 = (0..3).map(|a| (truth[a] - pred[a]).powi(2)).sum::<f64>();
                    if r.is_finite() {
                        worst = worst.max(r.sqrt());
                    }
                }
            }
        }
    }
    worst
}

fn path_rmse(d: &Day, model: Option<&Model>) -> [f64; 3] {
    let mut se = [0.0; 3];
    let mut n = 0usize;
    for (i, row) in d.run.rows.iter().enumerate() {
        let pred = match model {
            Some(m) => match m.evaluate(&input(d, i)) {
                Ok(c) => [c.error_um()[0], c.error_um()[1], c.error_um()[2]],
                Err(_) => continue,
            },
            None => [0.0; 3],
        };
        for a in 0..3 {
            se[a] += (row.error_um[a] - pred[a]).powi(2);
        }
        n += 1;
    }
    se.map(|s| (s / n.max(1) as f64).sqrt())
}

/// The training day as `truepos fit --machine` sees a run: the error at the tool's path per
/// direction (targets as measured) at the axis positions, with the machine's channels.
fn training_data(machine: &Machine, train: &Day) -> (Dataset, MachineData) {
    let run = &train.run;
    let ds = Dataset {
        input_names: Vec::new(),
        input_kinds: Vec::new(),
        target_names: vec!["dx_um".into(), "dy_um".into(), "dz_um".into()],
        runs: vec![Run {
            name: "training day".into(),
            time_s: run.rows.iter().map(|r| r.time_s).collect(),
            inputs: Vec::new(),
            targets: (0..3)
                .map(|a| run.rows.iter().map(|r| r.error_um[a]).collect())
                .collect(),
        }],
    };
    let data = MachineData {
        machine: machine.clone(),
        runs: vec![train.seen.clone()],
        target_axes: vec![0, 1, 2],
        reference: reference_sensor(machine),
        differences: (0..machine.differences.len()).collect(),
        owners: Vec::new(),
    };
    (ds, data)
}

/// The prior art and the position-dependent model, each chosen on the training day only by
/// `truepos fit --machine`'s selection (`truepos_fit::machine_fit::select`: per axis, family,
/// input set and ridge by blocked inner CV over the day): the prior art among the input sets,
/// the position-dependent model among the position-dependent families too.
fn fit_both(
    machine: &Machine,
    train: &Day,
    say: &dyn Fn(&str),
) -> Result<(Selected, Selected), CliError> {
    let (ds, data) = training_data(machine, train);
    let rows: Vec<(usize, usize)> = (0..ds.runs[0].len()).map(|i| (0, i)).collect();
    let settings = Settings {
        families: Vec::new(),
        absolute_targets: true,
        ..Settings::default()
    };
    let fit = |families: &[PositionFamily]| -> Result<Selected, CliError> {
        let sel = select(
            &ds,
            &data,
            None,
            &rows,
            &settings,
            &PositionFamily::designs(families),
        )
        .map_err(CliError::Refused)?;
        for c in &sel.candidates {
            let cv: Vec<String> = c
                .targets
                .iter()
                .map(|t| format!("{} {:.2}", t.target, t.cv_rmse_um))
                .collect();
            say(&format!(
                "  {}, inputs {}: cross-validated RMSE (µm) {}",
                c.family,
                c.inputs,
                cv.join(", ")
            ));
        }
        match sel.chosen {
            Chosen::Position(model) => Ok(Selected {
                model,
                labels: sel.labels,
            }),
            Chosen::Filtered(_) => Err(CliError::refused("internal: a dynamic model was chosen")),
        }
    };
    let prior = fit(&[PositionFamily::PositionIndependent])?;
    let posdep = fit(&[
        PositionFamily::AllAxes,
        PositionFamily::AllAxesSquared,
        PositionFamily::BedFactor,
    ])?;
    Ok((prior, posdep))
}

/// A model the selection chose, and per axis what it chose.
struct Selected {
    model: StaticModel,
    labels: Vec<String>,
}

impl Selected {
    fn chosen(&self, machine: &Machine) -> String {
        self.labels
            .iter()
            .zip(&machine.axes)
            .map(|(l, a)| format!("{}: {l}", a.name))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

fn save(
    selected: &Selected,
    machine: &Machine,
    path: &Path,
    what: &str,
    train: &str,
) -> Result<(), CliError> {
    let mut file = ModelFile::from_model(&selected.model.model, machine);
    file.description = format!("{what} fitted by `truepos demo` on the twin's `{train}` day");
    file.provenance.insert("tool".into(), "truepos demo".into());
    file.provenance
        .insert("training_scenario".into(), train.into());
    file.provenance
        .insert("chosen".into(), selected.chosen(machine).into());
    let observations: usize = selected
        .model
        .choices
        .iter()
        .map(|c| c.fitted.observations)
        .sum();
    file.provenance
        .insert("observations".into(), (observations as i64).into());
    crate::write::write_whole(path, file.to_toml(), &[])
}

/// The test day's figures: uncompensated, prior art, position-dependent.
struct Results {
    none: Figures,
    prior: Figures,
    posdep: Figures,
    /// Every how many rows of the test day the working volume is checked.
    stride: usize,
}

impl Results {
    fn new(twin: &Twin, test: &Day, prior: &Model, posdep: &Model, grid: usize) -> Self {
        let stride = (test.run.rows.len() / 200).max(1);
        let fig = |m: Option<&Model>| Figures {
            path_rmse_um: path_rmse(test, m),
            volume_max_um: volume_max(twin, test, m, grid, stride),
        };
        Self {
            none: fig(None),
            prior: fig(Some(prior)),
            posdep: fig(Some(posdep)),
            stride,
        }
    }

    /// The fraction of the uncompensated working-volume maximum a model removes.
    fn reduction(&self, f: &Figures) -> f64 {
        1.0 - f.volume_max_um / self.none.volume_max_um
    }
}

pub fn run(args: Args) -> Result<(), CliError> {
    let config = machine_file::parse(Path::new("examples/twin/machine.toml"), TWIN_MACHINE)?;
    let machine = config.machine.clone();
    let twin = Twin::reference();
    let chatty = !args.json && std::io::stderr().is_terminal();
    let say = |m: &str| {
        if chatty || !args.json {
            eprintln!("{m}");
        }
    };
    say(&format!(
        "twin: simulating the training day `{}` …",
        args.train
    ));
    let train = day(&twin, &machine, &args.train, 1)?;
    say(&format!("twin: simulating the test day `{}` …", args.test));
    let test = day(&twin, &machine, &args.test, 2)?;
    say("fit: prior-art and position-dependent models on the training day only …");
    let (prior, posdep) = fit_both(&machine, &train, &say)?;

    std::fs::create_dir_all(&args.out).map_err(CliError::file(&args.out, Some("cannot create")))?;
    save(
        &prior,
        &machine,
        &args.out.join("prior-art.model.toml"),
        "the prior art (position-independent)",
        &args.train,
    )?;
    save(
        &posdep,
        &machine,
        &args.out.join("position-dependent.model.toml"),
        "the position-dependent model",
        &args.train,
    )?;

    for (selected, name) in [(&prior, "prior art"), (&posdep, "position-dependent")] {
        for w in envelope_warnings(&config, &selected.model.model, name, &[&train, &test]) {
            eprintln!("{w}");
        }
    }
    say("evaluate: test day, at the tool's path and over the working volume …");
    let results = Results::new(
        &twin,
        &test,
        &prior.model.model,
        &posdep.model.model,
        args.grid,
    );
    let volume = volume(&twin, &machine, &test, &posdep.model.model, results.stride);
    let html = report(&args, &machine, &test, &posdep, &results, volume)?;
    print(&args, &machine, &results, &prior, &posdep, &html);
    Ok(())
}

/// What `truepos run` would say at start when replaying the training or the test day: a model
/// whose predictions at the tool's path go beyond the twin's envelope (its machine file's
/// `max_offset_um`) would be held at the limit, and the figures printed here would not be the
/// machine's.
fn envelope_warnings(
    config: &truepos_runtime::MachineConfig,
    model: &Model,
    name: &str,
    days: &[&Day],
) -> Vec<String> {
    let model = truepos_model::CompensationModel::from(model.clone());
    let mut out = Vec::new();
    for (d, which) in days.iter().zip(["training day", "test day"]) {
        let beyond = crate::envelope_check::beyond(config, &model, &d.seen);
        out.extend(crate::envelope_check::warnings(
            config,
            Path::new("examples/twin/machine.toml"),
            name,
            &format!("the twin's {which}"),
            &beyond,
        ));
    }
    out
}

/// The twin's error over the working volume before and after the position-dependent model, at
/// the sample of the test day where the uncompensated error at the travel's corners is largest.
fn volume(twin: &Twin, machine: &Machine, test: &Day, model: &Model, stride: usize) -> VolumeMap {
    let corners = |i: usize| {
        let state = test.run.state(i);
        let [x, y, z] = twin.travel_mm;
        let mut worst = 0.0_f64;
        for p in [x[0], x[1]]
            .iter()
            .flat_map(|&a| [y[0], y[1]].map(|b| (a, b)))
        {
            for c in z {
                let e = twin.error_um(state, [p.0, p.1, c]);
                worst = worst.max(e.iter().map(|v| v * v).sum::<f64>().sqrt());
            }
        }
        worst
    };
    let rows = test.run.rows.len();
    let worst = (0..rows)
        .step_by(stride.max(1))
        .max_by(|&a, &b| corners(a).total_cmp(&corners(b)))
        .unwrap_or(0);
    let moment = format!(
        "test day at {:.2} h, the largest uncompensated error at the travel's corners",
        test.run.rows[worst].time_s / 3600.0
    );
    let state = test.run.state(worst);
    crate::volume_map::before_after(
        machine,
        moment,
        |p| twin.error_um(state, p),
        model,
        &input(test, worst),
    )
}

/// The figures the demo is judged by, for the top of the report.
fn headline(r: &Results) -> Vec<(String, String)> {
    let v = |f: &Figures| format!("{:.1} µm", f.volume_max_um);
    let path = |f: &Figures| {
        let [x, y, z] = f.path_rmse_um;
        format!("{x:.2} / {y:.2} / {z:.2} µm")
    };
    vec![
        (
            "largest error over the volume, uncompensated".into(),
            v(&r.none),
        ),
        (
            format!(
                "… position-dependent, −{:.0} %",
                100.0 * r.reduction(&r.posdep)
            ),
            v(&r.posdep),
        ),
        (
            format!("… prior art, −{:.0} %", 100.0 * r.reduction(&r.prior)),
            v(&r.prior),
        ),
        (
            "RMS at the tool's path dx / dy / dz, uncompensated".into(),
            path(&r.none),
        ),
        ("… position-dependent".into(), path(&r.posdep)),
    ]
}

/// The report: the position-dependent model on the test day at the tool's path.
fn report(
    args: &Args,
    machine: &Machine,
    test: &Day,
    selected: &Selected,
    results: &Results,
    volume: VolumeMap,
) -> Result<PathBuf, CliError> {
    let stride = results.stride;
    let posdep = &selected.model;
    let mut channels = Vec::new();
    for (a, name) in ["dx", "dy", "dz"].iter().enumerate() {
        let measured: Vec<f64> = test.run.rows.iter().map(|r| r.error_um[a]).collect();
        let predicted: Vec<f64> = (0..test.run.rows.len())
            .map(|i| {
                posdep
                    .model
                    .evaluate(&input(test, i))
                    .map_or(f64::NAN, |c| c.error_um()[a])
            })
            .collect();
        channels.push(Channel {
            name: format!("{name} ({})", machine.axes[a].name),
            unit: "µm".into(),
            measured,
            predicted,
        });
    }
    let data = ReportData {
        title: "truepos demo: position-dependent model of the twin, on a test day it never saw".into(),
        time_s: test.run.rows.iter().map(|r| r.time_s).collect(),
        test_from: Some(0),
        channels,
        temperatures: machine
            .temperatures
            .iter()
            .enumerate()
            .map(|(i, t)| (t.id.clone(), test.seen.temperatures_c.iter().map(|r| r[i]).collect()))
            .collect(),
        coefficients: crate::report::coefficients::of_model(&posdep.model, machine)
            .into_iter()
            .filter(|c| c.value != 0.0)
            .collect(),
        protocol: vec![
            ("machine".into(), format!("{} (the built-in thermal twin)", machine.name)),
            ("training".into(), format!("twin scenario `{}`, seed 1: the only data the fit saw", args.train)),
            ("test".into(), format!("twin scenario `{}`, seed 2: a different day, held out entirely", args.test)),
            ("family".into(), format!("per axis {} — family, inputs and ridge λ chosen over the alternatives by blocked 8-fold time-series cross-validation inside the training day (`truepos fit --machine`'s selection)", selected.chosen(machine))),
            ("solver".into(), posdep.choices.iter().zip(&machine.axes).map(|(c, a)| format!("{}: rank {} of {}, condition {:.3e}", a.name, c.fitted.solution.rank, c.fitted.model.parameter_count(), c.fitted.solution.condition)).collect::<Vec<_>>().join("; ")),
            ("working volume".into(), format!("{0}×{0}×{0} grid over the travel, every {stride}-th sample of the test day", args.grid)),
        ],
        volume: Some(volume),
        headline: headline(results),
        ..Default::default()
    };
    Ok(write_report(&args.out.join("report"), &data)?)
}

/// The figures of the test day, the choices and where the files are: JSON with `--json`, else
/// a table.
fn print(
    args: &Args,
    machine: &Machine,
    r: &Results,
    prior: &Selected,
    posdep: &Selected,
    html: &Path,
) {
    if args.json {
        let v = serde_json::json!({
            "train": args.train, "test": args.test,
            "uncompensated": r.none,
            "prior_art": { "chosen": prior.chosen(machine), "figures": r.prior, "volume_reduction": r.reduction(&r.prior) },
            "position_dependent": { "chosen": posdep.chosen(machine), "figures": r.posdep, "volume_reduction": r.reduction(&r.posdep) },
            "report": html.display().to_string(),
        });
        println!("{v}");
        return;
    }
    println!(
        "test day `{}` (never seen by the fit), errors of the tool relative to the workpiece:",
        args.test
    );
    println!(
        "{:<34} {:>9} {:>9} {:>9} {:>14} {:>10}",
        "", "RMS dx", "RMS dy", "RMS dz", "max |e| volume", "reduction"
    );
    for (name, f) in [
        ("uncompensated", &r.none),
        ("prior art (position-independent)", &r.prior),
        ("position-dependent", &r.posdep),
    ] {
        println!(
            "{:<34} {:>6.2} µm {:>6.2} µm {:>6.2} µm {:>11.2} µm {:>9.0} %",
            name,
            f.path_rmse_um[0],
            f.path_rmse_um[1],
            f.path_rmse_um[2],
            f.volume_max_um,
            100.0 * r.reduction(f)
        );
    }
    println!("chosen by cross-validation on the training day:");
    println!("  prior art: {}", prior.chosen(machine));
    println!("  position-dependent: {}", posdep.chosen(machine));
    println!(
        "models: {}/prior-art.model.toml, {}/position-dependent.model.toml",
        args.out.display(),
        args.out.display()
    );
    println!("report: {}", html.display());
}
