//! `truepos fit --machine MACHINE.toml`: every family — the dynamic ones and the
//! position-dependent and reference-sensor forms — chosen by the same inner CV, validated by the
//! same outer protocol, and the chosen model written in its own form (`truepos_fit::machine_fit`).

use std::path::Path;
use std::time::Instant;

use super::{load, print_per_run, settings, tables, Args, Progress};
use crate::error::CliError;
use truepos_fit::dataset::{Dataset, Patterns};
use truepos_fit::export::{filtered_model_file, plausible_predictions, predictions_csv_of};
use truepos_fit::family::PositionFamily;
use truepos_fit::features::candidates;
use truepos_fit::machine_fit::{fit_machine, Chosen, MachineData, MachineOutcome};
use truepos_fit::position_model::reference_sensor;
use truepos_io::model_file::filtered::axis_named_like;
use truepos_io::model_file::position::ModelFile;
use truepos_model::Machine;

/// The default inputs of the dynamic families: the machine's measured temperature channels
/// and operating channels that the first run holds.
fn default_inputs(machine: &Machine, columns: &[String]) -> Patterns {
    let ids = machine
        .temperatures
        .iter()
        .filter(|t| t.lag.is_none())
        .map(|t| &t.id)
        .chain(machine.operating.iter().map(|o| &o.id));
    Patterns(ids.filter(|id| columns.contains(id)).cloned().collect())
}

/// The axis of each target: `--axis`, else the axis its name implies.
fn target_axes(args: &Args, ds: &Dataset, machine: &Machine) -> Result<Vec<usize>, CliError> {
    let mut axes = Vec::new();
    for t in &ds.target_names {
        let axis = match args.axes.iter().find(|a| &a.target == t) {
            Some(a) => machine.axis_index(&a.axis).ok_or_else(|| {
                CliError::refused(format!(
                    "--axis {t}={}: machine `{}` has no axis `{}`",
                    a.axis, machine.name, a.axis
                ))
            })?,
            None => axis_named_like(t, machine).ok_or_else(|| {
                CliError::refused(format!(
                    "target `{t}`: no axis of machine `{}` is named like it; give --axis {t}=<axis>",
                    machine.name
                ))
            })?,
        };
        if axes.contains(&axis) {
            return Err(CliError::refused(format!(
                "target `{t}`: axis {} already has a target; one target per axis",
                machine.axes[axis].name
            )));
        }
        axes.push(axis);
    }
    Ok(axes)
}

/// `--difference-axis`: per machine difference, the axis it belongs to.
fn owners(args: &Args, machine: &Machine) -> Result<Vec<Option<usize>>, CliError> {
    let mut owners = vec![None; machine.differences.len()];
    for d in &args.difference_axes {
        let i = machine
            .differences
            .iter()
            .position(|m| m.name == d.target)
            .ok_or_else(|| {
                let names: Vec<&str> = machine.differences.iter().map(|m| m.name.as_str()).collect();
                CliError::refused(format!(
                    "--difference-axis {}={}: machine `{}` has no difference `{}`; its differences are {}",
                    d.target, d.axis, machine.name, d.target, names.join(", ")
                ))
            })?;
        owners[i] = Some(machine.axis_index(&d.axis).ok_or_else(|| {
            CliError::refused(format!(
                "--difference-axis {}={}: machine `{}` has no axis `{}`",
                d.target, d.axis, machine.name, d.axis
            ))
        })?);
    }
    Ok(owners)
}

/// What [`fit_and_write`] fitted: the runs as one dataset, the fit's outcome, its warnings, the
/// machine, and the model file's text when `--model` was given (written there).
pub(crate) struct MachineFit {
    pub(crate) ds: Dataset,
    pub(crate) outcome: MachineOutcome,
    pub(crate) warnings: Vec<String>,
    pub(crate) machine: Machine,
    pub(crate) text: Option<String>,
}

/// Runs `truepos fit --machine MACHINE.toml`.
pub fn run(args: Args, path: &Path) -> Result<(), CliError> {
    let json = args.json;
    let MachineFit {
        ds,
        outcome,
        warnings,
        machine,
        ..
    } = fit_and_write(args, path)?;
    let sel = &outcome.selection;
    if json {
        let report = serde_json::json!({
            "machine": machine.name,
            "runs": ds.runs.iter().map(|r| serde_json::json!({"name": r.name, "samples": r.len()})).collect::<Vec<_>>(),
            "inputs": ds.input_names,
            "targets": ds.target_names,
            "validation": outcome.validation,
            "selection": {
                "form": form(&sel.chosen),
                "chosen": sel.labels,
                "cv_rmse_um": sel.cv_rmse_um,
                "candidates": sel.candidates,
            },
            "folds": outcome.folds,
            "warnings": warnings,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    print_screen(&ds, &outcome);
    Ok(())
}

/// The work of `truepos fit --machine` up to its output on screen: the runs read, every family
/// fitted and validated, the model refused when implausible (without `--force`), the model and
/// the predictions written; the warnings printed. `truepos fleet refit` fits through this too.
pub(crate) fn fit_and_write(mut args: Args, path: &Path) -> Result<MachineFit, CliError> {
    if !path.exists() && path.extension().is_none() {
        return Err(CliError::refused(format!(
            "--machine {}: expected a machine file (TOML); a model fitted without one names \
             its machine with --machine-name",
            path.display()
        )));
    }
    if let Some(out) = &args.model {
        super::model_name(out, &["toml", "json"], "a model of the machine")?;
    }
    let config = truepos_io::machine_file::load(path)?;
    let machine = config.machine.clone();
    // The filtered families of `--family` reach the selection through `settings`.
    let fixed = args
        .family
        .as_ref()
        .map_or(PositionFamily::ALL.to_vec(), |f| f.position.clone());
    let first = tables(&args)?;
    let columns = first.first().map(|t| t.columns.clone()).unwrap_or_default();
    let inputs = match args.inputs.clone() {
        Some(inputs) => inputs,
        None => {
            // The machine says which of its channels are operating state.
            args.operating = Patterns(machine.operating.iter().map(|o| o.id.clone()).collect());
            default_inputs(&machine, &columns)
        }
    };
    let (ds, tables) = load(&args, &inputs)?;
    let mut settings = settings(&args, &ds)?;
    settings.absolute_targets = true;
    let reference = reference_channel(&args, &machine)?;
    let positions = position_columns(&args, &machine)?;
    let axes = target_axes(&args, &ds, &machine)?;
    let data = MachineData::from_tables(
        &machine,
        &tables,
        &ds,
        positions.as_deref(),
        axes,
        reference,
    )?;
    let mut data = data;
    data.owners = owners(&args, &machine)?;
    let cand = candidates(&ds, &settings.taus).map_err(|e| CliError::refused(e.to_string()))?;
    let mut progress = Progress {
        start: Instant::now(),
    };
    let outcome = fit_machine(
        &ds,
        &data,
        Some(&cand),
        args.split,
        &settings,
        &PositionFamily::designs(&fixed),
        &mut |d, t| progress.update(d, t),
    )
    .map_err(CliError::Refused)?;
    let mut warnings = fit_warnings(&args, &ds, &outcome, &data, &config, path)?;
    let mut text = None;
    if let Some(out) = &args.model {
        let t = model_text(out, &ds, &settings, &machine, &outcome, &data)?;
        warnings.extend(refused_at_load(out, &t, &config));
        crate::write::write_whole(out, &t, &super::input_files(&args))?;
        text = Some(t);
    }
    if let Some(p) = &args.predictions {
        let csv = predictions_csv_of(&ds, &outcome.predictions, &outcome.held_out, true);
        crate::write::write_whole(p, csv, &super::input_files(&args))?;
    }
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok(MachineFit {
        ds,
        outcome,
        warnings,
        machine,
        text,
    })
}

/// The reference sensor: `--reference`, which must be one of the machine's temperature
/// channels, else the sensor most of the machine's differences are taken against.
fn reference_channel(args: &Args, machine: &Machine) -> Result<Option<usize>, CliError> {
    Ok(match &args.reference {
        Some(name) => Some(
            machine
                .temperatures
                .iter()
                .position(|t| &t.id == name)
                .ok_or_else(|| {
                    CliError::refused(format!(
                        "--reference {name}: not a temperature channel of machine `{}`",
                        machine.name
                    ))
                })?,
        ),
        None => reference_sensor(machine),
    })
}

/// `--positions`: one column per axis of the machine, in its order.
fn position_columns(args: &Args, machine: &Machine) -> Result<Option<Vec<String>>, CliError> {
    Ok(match &args.positions {
        Some(p) if p.0.len() != machine.axes.len() => {
            return Err(CliError::refused(format!(
            "--positions: expected {} columns (one per axis of machine `{}`, in its order), got {}",
            machine.axes.len(),
            machine.name,
            p.0.len()
        )))
        }
        Some(p) => Some(p.0.clone()),
        None => None,
    })
}

/// The warnings of a machine fit: the validation's own, held-out rows beyond the training
/// range, an implausible model the user forced through (refused unless forced), and the axes
/// where the model would exceed the machine's safety envelope on its training runs.
fn fit_warnings(
    args: &Args,
    ds: &Dataset,
    outcome: &MachineOutcome,
    data: &MachineData,
    config: &truepos_runtime::MachineConfig,
    path: &Path,
) -> Result<Vec<String>, CliError> {
    let mut warnings = outcome.validation.warnings.clone();
    warnings.extend(super::beyond_training(
        outcome.validation.held_out_rows_beyond_training,
    ));
    if let Err(bad) = plausible_predictions(ds, &outcome.fitted, &outcome.training_rows, true) {
        warnings.extend(super::forced(args, &bad)?);
    }
    let beyond = beyond_envelope(ds, outcome, &data.target_axes, config);
    let name = args
        .model
        .as_ref()
        .map_or("fitted".to_string(), |p| p.display().to_string());
    warnings.extend(
        crate::envelope_check::warnings(config, path, &name, "its training runs", &beyond)
            .into_iter()
            .map(|w| w.trim_start_matches("warning: ").to_string()),
    );
    Ok(warnings)
}

/// The axes on which the model written predicts, on its own training rows, more than the
/// machine's safety envelope allows (`max_offset_um`): there the service would hold the axis at
/// the limit and the figures above would not be what the machine gets.
fn beyond_envelope(
    ds: &Dataset,
    outcome: &MachineOutcome,
    target_axes: &[usize],
    config: &truepos_runtime::MachineConfig,
) -> Vec<crate::envelope_check::Beyond> {
    let mut out = Vec::new();
    for (k, &axis) in target_axes.iter().enumerate() {
        let largest = outcome
            .training_rows
            .iter()
            .map(|&(r, i)| (outcome.fitted[r][k][i].abs(), ds.runs[r].time_s[i]))
            .filter(|(e, _)| e.is_finite())
            .fold((0.0, 0.0), |a: (f64, f64), b| if b.0 > a.0 { b } else { a });
        if largest.0 > config.axes[axis].max_offset_um {
            out.push(crate::envelope_check::Beyond {
                axis,
                largest_um: largest.0,
                at_s: largest.1,
            });
        }
    }
    out
}

pub(crate) fn form(chosen: &Chosen) -> &'static str {
    match chosen {
        Chosen::Filtered(_) => "dynamic",
        Chosen::Position(_) => "position-dependent",
    }
}

pub(crate) fn print_screen(ds: &Dataset, outcome: &MachineOutcome) {
    let v = &outcome.validation;
    let sel = &outcome.selection;
    super::print_held_out_head(&v.protocol_text);
    for (k, m) in v.metrics.iter().enumerate() {
        super::print_held_out(
            m,
            &format!("{} (CV {:.2} µm)", sel.labels[k], sel.cv_rmse_um[k]),
        );
    }
    println!(
        "model written: {} form; inner-CV RMSE (µm) of every candidate on its training rows:",
        form(&sel.chosen)
    );
    let mut header = format!("{:<9} {:<24} {:<32}", "form", "family", "inputs");
    for t in &ds.target_names {
        header += &format!(" {t:>10}");
    }
    println!("{header}");
    for c in &sel.candidates {
        let mut line = format!("{:<9} {:<24} {:<32}", c.form, c.family, c.inputs);
        for t in &ds.target_names {
            match c.targets.iter().find(|s| &s.target == t) {
                Some(s) => line += &format!(" {:>10.2}", s.cv_rmse_um),
                None => line += &format!(" {:>10}", "—"),
            }
        }
        println!("{line}");
    }
    if ds.runs.len() > 1 {
        print_per_run(v);
    }
}

/// What `truepos run` and the LinuxCNC component will say of the model written: one they would
/// refuse as implausible for the machine ([`truepos_runtime::admission`]), or could not load at
/// all, is still written — the user may mean to change the envelope — with a warning that
/// names why.
fn refused_at_load(
    out: &Path,
    text: &str,
    config: &truepos_runtime::MachineConfig,
) -> Option<String> {
    let refuse =
        |why: String| format!("`truepos run` and truepos-hal will refuse this model: {why}");
    match truepos_io::model_file::parse(out, text, &config.machine) {
        Err(e) => Some(refuse(e.to_string())),
        Ok(loaded) => truepos_runtime::admission::plausible(&loaded.model, config)
            .err()
            .map(refuse),
    }
}

/// The chosen model in its own form: a position-dependent or reference-sensor model as the
/// model file `eval`, `run` and the LinuxCNC component read (TOML, or JSON when `out` ends in
/// `.json`); a dynamic model as the dynamic model file (JSON, so `out` must end in `.json`).
fn model_text(
    out: &Path,
    ds: &Dataset,
    settings: &truepos_fit::settings::Settings,
    machine: &Machine,
    outcome: &MachineOutcome,
    data: &MachineData,
) -> Result<String, CliError> {
    let axes = &data.target_axes;
    let created_by = format!("truepos fit {}", env!("CARGO_PKG_VERSION"));
    let text = match &outcome.selection.chosen {
        Chosen::Filtered(trained) => {
            super::model_name(
                out,
                &["json"],
                "the fit chose a fitted dynamic model (filtered temperatures)",
            )?;
            // Outputs name their axis explicitly: the machine fit mapped every target to one.
            let axes: Vec<truepos_fit::export::TargetAxis> = ds
                .target_names
                .iter()
                .zip(axes)
                .map(|(t, &a)| truepos_fit::export::TargetAxis {
                    target: t.clone(),
                    axis: machine.axes[a].name.clone(),
                })
                .collect();
            let mut file = filtered_model_file(
                ds,
                settings,
                trained,
                serde_json::to_value(&outcome.validation).unwrap_or_default(),
                &machine.name,
                &axes,
                &created_by,
            )
            .map_err(CliError::context("--axis: "))?;
            file.training_envelope = Some(truepos_fit::export::training_envelope(
                ds,
                &trained.inputs,
                &outcome.fitted,
                &outcome.training_rows,
            ));
            file.to_json() + "\n"
        }
        Chosen::Position(s) => {
            let mut model = s.model.clone();
            model.set_envelope(Some(truepos_fit::export::machine_envelope(
                &model,
                data,
                &outcome.training_rows,
            )));
            let mut file = ModelFile::from_model(&model, machine);
            file.description = format!(
                "fitted by `truepos fit --machine` on {}",
                ds.runs
                    .iter()
                    .map(|r| r.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            file.provenance.insert("tool".into(), created_by.into());
            file.provenance.insert(
                "fitted_on".into(),
                "every row of every run; the validation figures are those of the folds".into(),
            );
            file.provenance.insert(
                "validation".into(),
                outcome.validation.protocol_text.clone().into(),
            );
            for (k, c) in s.choices.iter().enumerate() {
                let t = &ds.target_names[k];
                file.provenance.insert(
                    format!("{t}_family"),
                    format!("{} ({})", c.family, c.family_name).into(),
                );
                file.provenance
                    .insert(format!("{t}_inputs"), c.inputs.into());
                file.provenance
                    .insert(format!("{t}_ridge"), c.fitted.ridge.into());
                file.provenance
                    .insert(format!("{t}_inner_cv_rmse_um"), c.fitted.score_um.into());
            }
            if super::model_name(out, &["json"], "").is_ok() {
                serde_json::to_string_pretty(&file)? + "\n"
            } else {
                file.to_toml()
            }
        }
    };
    Ok(text)
}
