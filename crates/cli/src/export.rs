//! `truepos export`: a model's state at one moment of a run, projected onto a control's own
//! compensation form and written as the file that sets it (see docs/controls.md).

use std::path::{Path, PathBuf};

use truepos_controls::fanuc::{macro_axes, write_macro_program};
use truepos_controls::heidenhain::{offset_9231, tempcomp, PlcWord};
use truepos_controls::isg::{write_parameters, IsgTempComp};
use truepos_controls::projection::{project, AxisProjection, Form};
use truepos_controls::siemens::write_program;
use truepos_io::cycles::Cycles;
use truepos_model::{AxisKind, CycleInput, Machine, Model};
use truepos_runtime::config::AxisConfig;

use crate::error::CliError;
use crate::evaluator::{Evaluator, ModelOnRun};

/// The control forms `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum To {
    /// SINUMERIK 840D sl / 828D: a part program setting SD43900/43910/43920 per axis
    /// (K0 + tanβ·(P − P0)); the same numbers serve Beckhoff/ISG's linear form.
    Siemens,
    /// HEIDENHAIN PLC module 9231: a thermal offset per axis in 0.1 µm (CSV).
    Heidenhain9231,
    /// HEIDENHAIN kinematics `TEMPCOMP` formulas over PLC words (static models linear in the
    /// temperatures).
    HeidenhainTempcomp,
    /// Beckhoff/ISG: axis parameter list entries P-AXIS-00271…00274 per axis (the error line
    /// in 0.1 µm and µm/m).
    Isg,
    /// FANUC: the line per axis as custom macro variables (K0 µm, slope µm/m, P0 mm): a macro
    /// program setting them, and the FOCAS `cnc_wrmacro` arguments in `--json`.
    Fanuc,
}

/// Arguments of `truepos export`.
#[derive(clap::Args)]
pub struct Args {
    /// The control form.
    #[arg(long, value_enum)]
    to: To,
    #[command(flatten)]
    on: ModelOnRun,
    /// The moment, s of the run's time (the first row at or after it); default: the last row.
    #[arg(long, value_parser = truepos_io::limits::finite_in(-1e10, 1e10))]
    at_s: Option<f64>,
    /// ISG: the logical axis number of an axis, AXIS=N (default its place in the machine, 1…).
    #[arg(long = "isg-axis", value_delimiter = ',')]
    isg_axes: Vec<String>,
    /// FANUC: the first macro variable (three per axis: K0, slope, P0).
    #[arg(long, default_value_t = 500)]
    fanuc_macro_base: u32,
    /// FANUC: the macro program's number (`O` word).
    #[arg(long, default_value_t = 9500, value_parser = clap::value_parser!(u32).range(1..=9999))]
    fanuc_program: u32,
    /// Reference position P0 of an axis, AXIS=mm (repeat or comma-separate); default 0.
    #[arg(long, value_delimiter = ',')]
    p0: Vec<String>,
    /// A sensor's PLC word for TEMPCOMP, SENSOR=WORD or SENSOR=WORD*SCALE (°C per count,
    /// default 0.1).
    #[arg(long = "plc-word", value_delimiter = ',')]
    plc_words: Vec<String>,
    /// Siemens: the control's name of a machine axis where it differs, AXIS=NAME (`X=X1`,
    /// `Z=AX3`; repeat or separate with commas), as `kin table --siemens-axis` names it. Default:
    /// the machine file's axis names.
    #[arg(long = "siemens-axis", value_delimiter = ',')]
    siemens_axes: Vec<String>,
    /// An axis' nominal transformation length for TEMPCOMP, AXIS=mm; default 0.
    #[arg(long, value_delimiter = ',')]
    nominal: Vec<String>,
    /// Refuse when the form misses the model by more than this anywhere checked, µm.
    #[arg(long, default_value_t = 2.0, value_parser = truepos_io::limits::finite_in(0.0, 1e6))]
    max_error_um: f64,
    /// Write even when the projection error is above --max-error-um (it is still reported).
    #[arg(long)]
    force: bool,
    /// Output file (written whole or not at all).
    #[arg(long)]
    out: PathBuf,
    /// Print the projection as JSON.
    #[arg(long)]
    json: bool,
}

/// `AXIS=value` pairs as a value per machine axis (0 where not given).
fn per_axis(machine: &Machine, specs: &[String], flag: &str) -> Result<Vec<f64>, CliError> {
    let mut out = vec![0.0; machine.axes.len()];
    for s in specs {
        let (axis, v) = s
            .split_once('=')
            .ok_or_else(|| CliError::refused(format!("{flag} `{s}`: expected AXIS=mm")))?;
        let a = machine.axis_index(axis).ok_or_else(|| {
            CliError::refused(format!(
                "{flag} `{s}`: machine `{}` has no axis `{axis}`",
                machine.name
            ))
        })?;
        out[a] = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                CliError::refused(format!("{flag} `{s}`: expected a finite number of mm"))
            })?;
    }
    Ok(out)
}

/// The projections with each axis named as the SINUMERIK knows it (`--siemens-axis X=X1`): a
/// letter or underscore, then letters, digits or underscores, as the control's identifiers.
fn siemens_names(
    machine: &Machine,
    specs: &[String],
    mut proj: Vec<AxisProjection>,
) -> Result<Vec<AxisProjection>, CliError> {
    for s in specs {
        let bad = |why: String| CliError::refused(format!("--siemens-axis `{s}`: {why}"));
        let (axis, name) = s
            .split_once('=')
            .ok_or_else(|| bad("expected AXIS=NAME, e.g. X=X1".into()))?;
        let a = machine
            .axis_index(axis.trim())
            .ok_or_else(|| bad(format!("machine `{}` has no axis `{axis}`", machine.name)))?;
        let name = name.trim();
        let identifier = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !identifier {
            return Err(bad(format!(
                "`{name}` is no SINUMERIK axis name (a letter, then letters, digits or `_`)"
            )));
        }
        for p in proj.iter_mut().filter(|p| p.axis == a) {
            p.name = name.to_string();
        }
    }
    Ok(proj)
}

fn plc_words(machine: &Machine, specs: &[String]) -> Result<Vec<PlcWord>, CliError> {
    specs
        .iter()
        .map(|s| {
            let bad = |why: &str| CliError::refused(format!("--plc-word `{s}`: {why}"));
            let (sensor, rest) = s
                .split_once('=')
                .ok_or_else(|| bad("expected SENSOR=WORD[*SCALE]"))?;
            let sensor = machine
                .temperatures
                .iter()
                .position(|t| t.id == sensor)
                .ok_or_else(|| {
                    bad(&format!(
                        "machine `{}` has no temperature sensor `{sensor}`",
                        machine.name
                    ))
                })?;
            let (word, scale) = match rest.split_once('*') {
                Some((w, k)) => (
                    w,
                    k.trim()
                        .parse()
                        .ok()
                        .filter(|k: &f64| k.is_finite() && *k != 0.0)
                        .ok_or_else(|| bad("expected a finite, non-zero scale in °C per count"))?,
                ),
                None => (rest, 0.1),
            };
            let word = word.trim();
            if word.is_empty()
                || !word
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
            {
                return Err(bad("expected a PLC operand such as W486"));
            }
            Ok(PlcWord {
                sensor,
                word: word.to_string(),
                scale,
            })
        })
        .collect()
}

/// The row exported and the model's error there (a dynamic model stepped through every row
/// before it).
fn moment(
    model: &mut Evaluator,
    run: &Cycles,
    machine: &Machine,
    at_s: Option<f64>,
) -> Result<(usize, Vec<f64>), CliError> {
    let n = run.run.time_s.len();
    let k = match at_s {
        Some(t) => run.run.time_s.iter().position(|&x| x >= t).ok_or_else(|| {
            CliError::refused(format!(
                "--at-s {t}: the run ends at {} s",
                run.run.time_s.last().copied().unwrap_or(0.0)
            ))
        })?,
        None => n
            .checked_sub(1)
            .ok_or_else(|| CliError::refused("the run has no rows".to_string()))?,
    };
    let mut error = Vec::new();
    for i in 0..=k {
        error = model.error_um(run, i, machine)?.to_vec();
    }
    Ok((k, error))
}

/// Axis positions of the row, an axis the run does not give at its travel's middle.
fn positions_now(machine: &Machine, run: &Cycles, k: usize) -> Vec<f64> {
    machine
        .axes
        .iter()
        .enumerate()
        .map(|(a, x)| {
            let p = run.run.positions[k].get(a).copied().unwrap_or(f64::NAN);
            if p.is_finite() {
                p
            } else {
                0.5 * (x.travel_min + x.travel_max)
            }
        })
        .collect()
}

/// The files `truepos export` reads, which its output may not be.
fn inputs(args: &Args) -> [(&'static str, &Path); 3] {
    [
        ("--machine", &args.on.machine),
        ("--model", &args.on.model),
        ("--run", &args.on.run),
    ]
}

pub fn run(args: Args) -> Result<(), CliError> {
    crate::write::check(&args.out, &inputs(&args))?;
    let (config, mut model, mut runs) = args.on.load()?;
    let machine = config.machine;
    if runs.len() != 1 {
        let names: Vec<&str> = runs.iter().map(|r| r.0.as_str()).collect();
        return Err(CliError::refused(format!(
            "{}: export takes one run; the file holds {}: {}",
            args.on.run.display(),
            runs.len(),
            names.join(", ")
        )));
    }
    let cycles = runs.remove(0).1;
    let (k, error_now) = moment(&mut model, &cycles, &machine, args.at_s)?;
    for (a, &e) in error_now.iter().enumerate() {
        within_envelope(&machine, &config.axes, a, "the model's error now", e)?;
    }
    let now = positions_now(&machine, &cycles, k);
    let header = vec![
        format!(
            "truepos export: model `{}` ({}) on machine `{}`",
            model.name(),
            args.on.model.display(),
            machine.name
        ),
        format!(
            "at t = {} s of {} (row {}); {}",
            cycles.run.time_s[k],
            args.on.run.display(),
            k + 1,
            match args.to {
                To::Isg => "the error line (actual − nominal), 0.1 µm and µm/m",
                To::Fanuc => "compensation = −error, µm, µm/m and mm",
                _ => "compensation = −error, mm",
            }
        ),
    ];
    let static_model = model.model().as_static().cloned();
    let row = |i: usize| CycleInput {
        temperatures_c: &cycles.run.temperatures_c[i],
        positions: &cycles.run.positions[i],
        operating: &cycles.run.operating[i],
    };
    let at_positions = |p: &[f64]| -> Result<Vec<f64>, String> {
        match &static_model {
            Some(m) => evaluate(
                m,
                &CycleInput {
                    positions: p,
                    ..row(k)
                },
            ),
            None => Ok(error_now.clone()),
        }
    };
    let (text, axes_json) = match args.to {
        To::Siemens | To::Heidenhain9231 | To::Isg | To::Fanuc => {
            let form = if args.to == To::Heidenhain9231 {
                Form::Constant
            } else {
                Form::Linear
            };
            let p0 = per_axis(&machine, &args.p0, "--p0")?;
            let proj = project(&machine, &at_positions, &now, form, &p0)
                .map_err(|e| CliError::refused(e.to_string()))?;
            line_within_envelope(&machine, &config.axes, &proj)?;
            if args.to == To::Isg {
                isg_file(&args, &machine, &proj, &header)?
            } else if args.to == To::Fanuc {
                fanuc_file(&args, &machine, &proj, &header)?
            } else {
                check_error(&args, &proj, &vec![0.0; proj.len()])?;
                let text = if args.to == To::Siemens {
                    write_program(
                        &siemens_names(&machine, &args.siemens_axes, proj.clone())?,
                        &header,
                    )
                } else {
                    module_9231_csv(&proj)?
                };
                (text, projection_json(&proj))
            }
        }
        To::HeidenhainTempcomp => tempcomp_file(
            &args,
            &machine,
            static_model.as_ref(),
            &row(k),
            &now,
            &header,
        )?,
    };
    crate::write::write_whole(&args.out, &text, &inputs(&args))?;
    if args.json {
        let v = serde_json::json!({"to": format!("{:?}", args.to), "at_s": cycles.run.time_s[k], "axes": axes_json, "out": args.out.display().to_string()});
        println!("{v}");
    } else {
        print!("{}", summary(&axes_json, args.to));
        println!("written: {}", args.out.display());
    }
    Ok(())
}

/// Refuses — whatever `--force` says — a value of axis `a` (µm) beyond the axis' envelope: the
/// service never applies more, so a control must not be handed more either (a model predicting
/// that is implausible, or the machine file's `max_offset_um` is set below what the machine
/// truly drifts).
fn within_envelope(
    machine: &Machine,
    axes: &[AxisConfig],
    a: usize,
    what: &str,
    v: f64,
) -> Result<(), CliError> {
    let (Some(cfg), Some(axis)) = (axes.get(a), machine.axes.get(a)) else {
        return Ok(());
    };
    if v.is_nan() || v.abs() > cfg.max_offset_um {
        return Err(CliError::refused(format!(
            "axis {}: {what} is {v:.3} µm, beyond the axis' envelope ±{} µm (axis.max_offset_um \
             of machine `{}`); nothing written, --force does not pass it",
            axis.name, cfg.max_offset_um, machine.name
        )));
    }
    Ok(())
}

/// The control's line at both ends of each projected axis' travel within the envelope (a line
/// is largest at an end).
fn line_within_envelope(
    machine: &Machine,
    axes: &[AxisConfig],
    proj: &[AxisProjection],
) -> Result<(), CliError> {
    for p in proj {
        let x = &machine.axes[p.axis];
        for pos in [x.travel_min, x.travel_max] {
            let what = format!("the control's compensation at {} = {pos} mm", x.name);
            within_envelope(machine, axes, p.axis, &what, 1000.0 * p.form.at(pos))?;
        }
    }
    Ok(())
}

/// The model's error at `input`, guarded by its training envelope as on the machine (inputs
/// clamped, output capped), so that a control is handed what truepos itself would apply.
fn evaluate(m: &Model, input: &CycleInput<'_>) -> Result<Vec<f64>, String> {
    let Some(env) = m.envelope() else {
        return m
            .evaluate(input)
            .map(|c| c.error_um().to_vec())
            .map_err(|e| e.to_string());
    };
    let mut t = vec![0.0; input.temperatures_c.len()];
    let mut o = vec![0.0; input.operating.len()];
    env.clamp(input, &mut t, &mut o);
    let guarded = CycleInput {
        temperatures_c: &t,
        positions: input.positions,
        operating: &o,
    };
    let mut error = m
        .evaluate(&guarded)
        .map(|c| c.error_um().to_vec())
        .map_err(|e| e.to_string())?;
    env.cap(&mut error);
    Ok(error)
}

/// Refuses (unless `--force`) an axis whose form misses the model by more than
/// `--max-error-um`, `extra` µm per axis added (what the control's units lose).
fn check_error(args: &Args, proj: &[AxisProjection], extra: &[f64]) -> Result<(), CliError> {
    for (p, x) in proj.iter().zip(extra) {
        if p.worst_um() + x > args.max_error_um {
            let what = format!(
                "axis {}: the control's form misses the model by up to {:.3} µm ({:.3} along its travel{}{}), more than --max-error-um {}",
                p.name,
                p.worst_um() + x,
                p.along_error_um,
                p.cross_axis.iter().map(|c| format!(", {:.3} when {} travels", c.change_um, c.axis)).collect::<String>(),
                if *x > 0.0 { format!(", {x:.3} from the parameters' whole units") } else { String::new() },
                args.max_error_um
            );
            if !args.force {
                return Err(CliError::refused(format!(
                    "{what}; --force to write it anyway"
                )));
            }
            eprintln!("warning: --force: {what}");
        }
    }
    Ok(())
}

/// ISG: the parameter blocks per axis, the whole units' loss added to the projection error.
fn isg_file(
    args: &Args,
    machine: &Machine,
    proj: &[AxisProjection],
    header: &[String],
) -> Result<(String, Vec<serde_json::Value>), CliError> {
    let mut numbers: Vec<i64> = (1..=machine.axes.len() as i64).collect();
    for s in &args.isg_axes {
        let bad = || {
            CliError::refused(format!(
                "--isg-axis `{s}`: expected AXIS=N, N ≥ 1 an axis of the machine"
            ))
        };
        let (axis, n) = s.split_once('=').ok_or_else(bad)?;
        let a = machine.axis_index(axis).ok_or_else(bad)?;
        numbers[a] = n
            .trim()
            .parse()
            .ok()
            .filter(|&n: &i64| n >= 1)
            .ok_or_else(bad)?;
    }
    let mut blocks = Vec::new();
    for p in proj {
        let ax = &machine.axes[p.axis];
        let (t, loss) =
            IsgTempComp::from_projection(p, numbers[p.axis], (ax.travel_min, ax.travel_max))
                .map_err(|e| CliError::refused(e.to_string()))?;
        blocks.push((t, p, loss));
    }
    let losses: Vec<f64> = blocks.iter().map(|b| b.2).collect();
    check_error(args, proj, &losses)?;
    let mut json = projection_json(proj);
    for (j, (t, _, loss)) in json.iter_mut().zip(&blocks) {
        j["worst_um"] = serde_json::json!(j["worst_um"].as_f64().unwrap_or(f64::NAN) + loss);
        j["isg"] = serde_json::json!({"axis_nr": t.axis_nr, "position_0_0_1um": t.position_0, "offset_0_0_1um": t.offset_0, "coefficient_um_per_m": t.coefficient, "units_loss_um": loss});
    }
    Ok((write_parameters(&blocks, header), json))
}

/// FANUC: the macro program and, per axis, its variables and `cnc_wrmacro` arguments; the
/// values' decimals are added to the projection error.
fn fanuc_file(
    args: &Args,
    machine: &Machine,
    proj: &[AxisProjection],
    header: &[String],
) -> Result<(String, Vec<serde_json::Value>), CliError> {
    let axes =
        macro_axes(proj, args.fanuc_macro_base).map_err(|e| CliError::refused(e.to_string()))?;
    let losses: Vec<f64> = axes
        .iter()
        .zip(proj)
        .map(|(a, p)| {
            let ax = &machine.axes[p.axis];
            [ax.travel_min, ax.travel_max]
                .iter()
                .map(|&x| (a.quantised().compensation_um(x) - a.compensation_um(x)).abs())
                .fold(0.0, f64::max)
        })
        .collect();
    check_error(args, proj, &losses)?;
    let mut json = projection_json(proj);
    for ((j, a), loss) in json.iter_mut().zip(&axes).zip(&losses) {
        let calls = a.wrmacro().map_err(|e| CliError::refused(e.to_string()))?;
        j["worst_um"] = serde_json::json!(j["worst_um"].as_f64().unwrap_or(f64::NAN) + loss);
        j["fanuc"] = serde_json::json!({
            "k0_um": a.k0_um, "slope_um_per_m": a.slope_um_per_m, "p0_mm": a.p0_mm,
            "cnc_wrmacro": calls.iter().map(|(n, m, d)| serde_json::json!({"number": n, "mcr_val": m, "dec_val": d})).collect::<Vec<_>>(),
        });
    }
    let pairs: Vec<_> = axes.iter().copied().zip(proj).collect();
    Ok((
        write_macro_program(args.fanuc_program, &pairs, header),
        json,
    ))
}

fn module_9231_csv(proj: &[AxisProjection]) -> Result<String, CliError> {
    let mut out = String::from("axis,offset_0_1um,projection_error_um\n");
    for p in proj {
        let v = offset_9231(p).map_err(|e| CliError::refused(e.to_string()))?;
        out += &format!("{},{v},{:.3}\n", p.name, p.worst_um());
    }
    Ok(out)
}

fn projection_json(proj: &[AxisProjection]) -> Vec<serde_json::Value> {
    proj.iter()
        .map(|p| {
            serde_json::json!({
                "axis": p.name, "k0_mm": p.form.k0_mm, "tan_beta": p.form.tan_beta, "p0_mm": p.form.p0_mm,
                "along_error_um": p.along_error_um, "worst_um": p.worst_um(),
                "cross_axis": p.cross_axis.iter().map(|c| serde_json::json!({"axis": c.axis, "change_um": c.change_um})).collect::<Vec<_>>(),
            })
        })
        .collect()
}

/// One line per axis in the control's own words: SINUMERIK's and ISG's K0/tanβ/P0, module
/// 9231's offset in 0.1 µm, FANUC's macro variables, TEMPCOMP's formula.
fn summary(axes: &[serde_json::Value], to: To) -> String {
    let mut out = String::new();
    for a in axes {
        let f = |k: &str| a[k].as_f64().unwrap_or(f64::NAN);
        let name = a["axis"].as_str().unwrap_or("?");
        if to == To::Heidenhain9231 {
            out += &format!(
                "{name}: module 9231 offset {:.0} × 0.1 µm; misses the model by up to {:.3} µm\n",
                f("k0_mm") * 1e4,
                f("worst_um")
            );
            continue;
        }
        if to == To::Fanuc {
            let v = |k: &str| a["fanuc"][k].as_f64().unwrap_or(f64::NAN);
            out += &format!(
                "{name}: macro variables K0 {:.3} µm, slope {:.3} µm/m, P0 {:.3} mm; misses the model by up to {:.3} µm\n",
                v("k0_um"),
                v("slope_um_per_m"),
                v("p0_mm"),
                f("worst_um")
            );
            continue;
        }
        match a.get("formula") {
            Some(formula) => {
                out += &format!(
                    "{}: TEMPCOMP = {} (position error {:.3} µm)\n",
                    a["axis"].as_str().unwrap_or("?"),
                    formula.as_str().unwrap_or(""),
                    f("position_error_um")
                )
            }
            None => {
                out += &format!(
                    "{}: K0 {:.7} mm, tanβ {:.3e}, P0 {} mm; misses the model by up to {:.3} µm\n",
                    a["axis"].as_str().unwrap_or("?"),
                    f("k0_mm"),
                    f("tan_beta"),
                    f("p0_mm"),
                    f("worst_um")
                )
            }
        }
    }
    out
}

/// TEMPCOMP: a static model only; the corners of the linear axes' travel measure what the
/// formula's position independence loses.
fn tempcomp_file(
    args: &Args,
    machine: &Machine,
    model: Option<&Model>,
    row: &CycleInput<'_>,
    now: &[f64],
    header: &[String],
) -> Result<(String, Vec<serde_json::Value>), CliError> {
    let model = model.ok_or_else(|| {
        CliError::refused("TEMPCOMP carries a static model linear in the temperatures; this is a fitted dynamic model (use --to siemens or heidenhain9231)".to_string())
    })?;
    let words = plc_words(machine, &args.plc_words)?;
    let nominal = per_axis(machine, &args.nominal, "--nominal")?;
    let linear: Vec<usize> = (0..machine.axes.len())
        .filter(|&a| machine.axes[a].kind == AxisKind::Linear)
        .collect();
    let corners: Vec<Vec<f64>> = (0..1usize << linear.len())
        .map(|bits| {
            let mut p = now.to_vec();
            for (i, &a) in linear.iter().enumerate() {
                let x = &machine.axes[a];
                p[a] = if bits >> i & 1 == 1 {
                    x.travel_max
                } else {
                    x.travel_min
                };
            }
            p
        })
        .collect();
    let f = |t: &[f64], p: &[f64]| {
        evaluate(
            model,
            &CycleInput {
                temperatures_c: t,
                positions: p,
                ..*row
            },
        )
    };
    let tc = tempcomp(
        machine,
        &f,
        row.temperatures_c,
        now,
        &corners,
        &words,
        &nominal,
    )
    .map_err(|e| CliError::refused(e.to_string()))?;
    let mut text: String = header.iter().map(|h| format!("; {h}\n")).collect();
    let mut json = Vec::new();
    for t in &tc {
        let name = &machine.axes[t.axis].name;
        if t.position_error_um > args.max_error_um {
            let what = format!("axis {name}: the model varies {:.3} µm over the travel, which TEMPCOMP cannot carry (more than --max-error-um {})", t.position_error_um, args.max_error_um);
            if !args.force {
                return Err(CliError::refused(format!(
                    "{what}; --force to write it anyway"
                )));
            }
            eprintln!("warning: --force: {what}");
        }
        text += &format!(
            "; {name}: position error {:.3} µm\n{name} = {}\n",
            t.position_error_um, t.formula
        );
        json.push(serde_json::json!({"axis": name, "formula": t.formula, "position_error_um": t.position_error_um, "at_20c_mm": t.at_20c_mm}));
    }
    Ok((text, json))
}
