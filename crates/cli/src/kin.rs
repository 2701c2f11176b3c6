//! `truepos kin`: the kinematics table with error tables from the command line.
//!
//! * `kin fwd`: axis positions (CSV with one column per axis, named as in the kinematics file)
//!   → TCP `X,Y,Z` (mm) and tool direction `I,J,K` in workpiece coordinates.
//! * `kin inv`: `X,Y,Z,I,J,K` → axis set-points, through the error tables (or nominal with
//!   `--nominal`); each row starts from the previous row's set-points.
//! * `kin gcode`: compensates a G-code program through LinuxCNC's interpreter (`truepos_gcode`):
//!   the real tool lands where the nominal machine would put it; a refused program leaves no
//!   output.
//! * `kin table`: converts a compensation table between formats and evaluates it
//!   (`kin/table.rs`).
//! * `kin chain`: the resolved chain as JSON (used by `scripts/kdl_compare.py`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::CliError;
use truepos_files::InputError;
use truepos_io::kinematics_file::{self, KinematicsFile};
use truepos_kinematics::{Directions, Geometry, KinAxis, KinError, Pose, Row};
use truepos_model::AxisKind;

mod gcode;
mod table;

/// Arguments of `truepos kin`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: KinCommand,
}

#[derive(clap::Args)]
struct Common {
    /// The kinematics table file (`*.ktab`).
    #[arg(long)]
    kinematics: PathBuf,
    /// The machine description (TOML); axis travels are taken from it.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Tool length in mm, −10 000–10 000 (default: `tool_length` of the kinematics file).
    #[arg(long, value_parser = truepos_io::limits::finite_in(-10_000.0, 10_000.0))]
    tool_length: Option<f64>,
    /// Use the nominal chain (ignore the error tables).
    #[arg(long)]
    nominal: bool,
    /// Input file (CSV for fwd/inv, a G-code program for gcode).
    #[arg(long)]
    input: PathBuf,
    /// Output file; without it the result goes to standard output and the summary to
    /// standard error.
    #[arg(long)]
    output: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Subcommand)]
enum KinCommand {
    /// Axis positions → TCP and tool direction.
    Fwd(Common),
    /// TCP and tool direction → axis set-points.
    Inv(Common),
    /// Compensate a G-code program through LinuxCNC's interpreter (rs274) into G53 blocks.
    Gcode(gcode::GcodeArgs),
    /// Convert a compensation table between formats (CSV, LinuxCNC COMP_FILE 0/1, Siemens
    /// $AA_ENC_COMP/$AN_CEC) and evaluate it at given positions.
    Table(table::TableArgs),
    /// Print the resolved chain (rows, axes) as JSON.
    Chain {
        /// The kinematics table file.
        #[arg(long)]
        kinematics: PathBuf,
        /// The machine description (TOML).
        #[arg(long)]
        machine: Option<PathBuf>,
    },
}

pub fn run(args: Args) -> Result<(), CliError> {
    match args.command {
        KinCommand::Fwd(c) => fwd(&c),
        KinCommand::Inv(c) => inv(&c),
        KinCommand::Gcode(a) => gcode::gcode(&a),
        KinCommand::Table(a) => table::table(&a),
        KinCommand::Chain {
            kinematics,
            machine,
        } => chain(&kinematics, machine.as_deref()),
    }
}

fn load(kinematics: &Path, machine: Option<&Path>) -> Result<KinematicsFile, CliError> {
    let machine = match machine {
        Some(m) => Some(truepos_io::machine_file::load(m)?.machine),
        None => None,
    };
    Ok(kinematics_file::load(kinematics, machine.as_ref())?)
}

fn tool_length(c: &Common, k: &KinematicsFile) -> Result<f64, CliError> {
    let t = c.tool_length.unwrap_or(k.tool_length_mm);
    if t.is_finite() {
        Ok(t)
    } else {
        Err(CliError::refused(format!(
            "--tool-length must be a finite number, got {t}"
        )))
    }
}

/// A numeric CSV: header names and rows with their line numbers.
struct PointList {
    header: Vec<String>,
    rows: Vec<(usize, Vec<f64>)>,
}

/// Reads a point list: `#` comments and blank lines skipped, every cell a finite number (an
/// error names its line and character column), every row as wide as the header.
fn read_csv(path: &Path) -> Result<PointList, CliError> {
    use truepos_io::table::{self, Number};
    let t = table::load_csv(
        path,
        table::CsvOptions {
            comments: true,
            ..Default::default()
        },
    )?;
    if t.columns.is_empty() {
        return Err(InputError::file(path, "empty file; expected a header and rows").into());
    }
    let mut rows = Vec::with_capacity(t.len());
    for (r, row) in t.rows().enumerate() {
        let mut values = Vec::with_capacity(row.len());
        for (c, cell) in row.cells().enumerate() {
            let v = match cell.value.number() {
                Number::Value(v) if v.is_finite() => v,
                _ => {
                    let text = match cell.value {
                        table::Value::Text(x) => x.to_string(),
                        table::Value::Number(v) => v.to_string(),
                        table::Value::Empty => String::new(),
                    };
                    return Err(t
                        .at_character(r, c, format!("expected a finite number, got `{text}`"))
                        .into());
                }
            };
            values.push(v);
        }
        if values.len() != t.columns.len() {
            return Err(InputError::at(
                path,
                row.line(),
                1,
                "",
                format!(
                    "expected {} values as in the header, got {}",
                    t.columns.len(),
                    values.len()
                ),
            )
            .into());
        }
        rows.push((row.line(), values));
    }
    Ok(PointList {
        header: t.columns,
        rows,
    })
}

/// Column index of each of `names` in the header.
fn columns(path: &Path, t: &PointList, names: &[&str]) -> Result<Vec<usize>, CliError> {
    for (c, h) in t.header.iter().enumerate() {
        if !names.contains(&h.as_str()) {
            return Err(InputError::at(
                path,
                1,
                c + 1,
                h.clone(),
                format!("unknown column; expected the columns {}", names.join(",")),
            )
            .into());
        }
    }
    names
        .iter()
        .map(|n| {
            t.header.iter().position(|h| h == n).ok_or_else(|| {
                InputError::at(
                    path,
                    1,
                    1,
                    *n,
                    format!("missing column; expected the columns {}", names.join(",")),
                )
                .into()
            })
        })
        .collect()
}

fn emit(c: &Common, body: &str, summary: serde_json::Value, text: String) -> Result<(), CliError> {
    let summary = if c.json { summary.to_string() } else { text };
    match &c.output {
        Some(p) => {
            let mut inputs: Vec<(&str, &Path)> =
                vec![("--kinematics", &c.kinematics), ("--input", &c.input)];
            inputs.extend(c.machine.as_deref().map(|m| ("--machine", m)));
            crate::write::write_whole(p, body, &inputs)?;
            println!("{summary}");
        }
        None => {
            print!("{body}");
            eprintln!("{summary}");
        }
    }
    Ok(())
}

fn geometry(c: &Common) -> Geometry {
    if c.nominal {
        Geometry::Nominal
    } else {
        Geometry::Actual
    }
}

fn fwd(c: &Common) -> Result<(), CliError> {
    let k = load(&c.kinematics, c.machine.as_deref())?;
    let tool = tool_length(c, &k)?;
    let chain = &k.chain;
    let names: Vec<&str> = chain.axes().iter().map(|a| a.name.as_str()).collect();
    let t = read_csv(&c.input)?;
    let cols = columns(&c.input, &t, &names)?;
    let n = names.len();
    let qs: Vec<Vec<f64>> = t
        .rows
        .iter()
        .map(|(_, r)| cols.iter().map(|&i| r[i]).collect())
        .collect();
    // Written before the clock starts: the first write to a fresh page of a growing buffer
    // costs a page fault, the kernel's time rather than the transform's (see `inv`).
    let mut poses = vec![Err(KinError::NonFinite); qs.len()];
    let start = Instant::now();
    for (q, slot) in qs.iter().zip(&mut poses) {
        *slot = chain.forward(q, tool, Directions(0), geometry(c));
    }
    let seconds = start.elapsed().as_secs_f64();
    let mut body = String::from("X,Y,Z,I,J,K\n");
    for ((line, _), p) in t.rows.iter().zip(&poses) {
        let p = p
            .as_ref()
            .map_err(|e| CliError::context(format!("{}:{line}: ", c.input.display()))(*e))?;
        let [x, y, z] = p.position;
        let [i, j, kk] = p.direction;
        let _ = writeln!(body, "{x},{y},{z},{i},{j},{kk}");
    }
    let summary = serde_json::json!({
        "points": qs.len(), "axes": n, "geometry": if c.nominal { "nominal" } else { "actual" },
        "transform_seconds": seconds,
        "points_per_second": qs.len() as f64 / seconds.max(1e-12),
    });
    let text = format!(
        "{} points forward ({}) in {:.3} ms",
        qs.len(),
        if c.nominal { "nominal" } else { "with errors" },
        seconds * 1e3
    );
    emit(c, &body, summary, text)
}

fn inv(c: &Common) -> Result<(), CliError> {
    let k = load(&c.kinematics, c.machine.as_deref())?;
    let tool = tool_length(c, &k)?;
    let chain = &k.chain;
    let t = read_csv(&c.input)?;
    let cols = columns(&c.input, &t, &["X", "Y", "Z", "I", "J", "K"])?;
    let targets: Vec<Pose> = t
        .rows
        .iter()
        .map(|(_, r)| Pose {
            position: [r[cols[0]], r[cols[1]], r[cols[2]]],
            direction: [r[cols[3]], r[cols[4]], r[cols[5]]],
        })
        .collect();
    let n = chain.axes().len();
    let mut prev: Vec<f64> = chain.axes().iter().map(KinAxis::start_position).collect();
    let mut dirs = Directions(0);
    // Both output buffers are written before the clock starts: the first write to a fresh
    // page costs a page fault, which inside the timed loop added ~60 ns per point on vmc-21
    // (13 % of a solve; measured side by side), the kernel's time rather than the solver's
    // (KDL's loop in scripts/kdl_compare.py reuses one output array).
    let mut out = vec![f64::NAN; n * targets.len()];
    let mut results = vec![Err(KinError::NonFinite); targets.len()];
    // Throughput per chunk of 1000 points as well as in total: the median chunk is robust to
    // other processes taking the core for a while (used by scripts/kdl_compare.py).
    let mut chunk_rates: Vec<f64> = Vec::new();
    let mut chunk_start = Instant::now();
    let start = Instant::now();
    for (i, target) in targets.iter().enumerate() {
        if i > 0 && i % 1000 == 0 {
            chunk_rates.push(1000.0 / chunk_start.elapsed().as_secs_f64().max(1e-12));
            chunk_start = Instant::now();
        }
        let slot = &mut out[i * n..(i + 1) * n];
        let r = chain.inverse(target, tool, &prev, dirs, geometry(c), slot);
        if let Ok(rep) = &r {
            prev.copy_from_slice(slot);
            dirs = rep.directions;
        }
        results[i] = r;
    }
    let seconds = start.elapsed().as_secs_f64();
    chunk_rates.sort_by(f64::total_cmp);
    let median_rate = if chunk_rates.is_empty() {
        targets.len() as f64 / seconds.max(1e-12)
    } else {
        chunk_rates[chunk_rates.len() / 2]
    };
    let names: Vec<&str> = chain.axes().iter().map(|a| a.name.as_str()).collect();
    let mut body = names.join(",") + ",status\n";
    let (mut ok, mut max_p, mut max_d, mut max_it) = (0usize, 0.0_f64, 0.0_f64, 0u32);
    let mut sum_it = 0u64;
    let mut failures = Vec::new();
    for (i, r) in results.iter().enumerate() {
        match r {
            Ok(rep) => {
                ok += 1;
                max_p = max_p.max(rep.position_residual_mm);
                max_d = max_d.max(rep.direction_residual_rad);
                max_it = max_it.max(rep.iterations);
                sum_it += u64::from(rep.iterations);
                for v in &out[i * n..(i + 1) * n] {
                    let _ = write!(body, "{v},");
                }
                body.push_str("ok\n");
            }
            Err(e) => {
                body.push_str(&",".repeat(n));
                let _ = writeln!(body, "\"{e}\"");
                failures.push(format!("{}:{}: {e}", c.input.display(), t.rows[i].0));
            }
        }
    }
    let total = targets.len();
    let summary = serde_json::json!({
        "points": total, "converged": ok, "failed": total - ok,
        "geometry": if c.nominal { "nominal" } else { "actual" },
        "layout": chain.layout_name(),
        "max_position_residual_mm": max_p, "max_direction_residual_rad": max_d,
        "max_newton_iterations": max_it,
        "mean_newton_iterations": sum_it as f64 / ok.max(1) as f64,
        "solve_seconds": seconds,
        "points_per_second": total as f64 / seconds.max(1e-12),
        "median_chunk_points_per_second": median_rate,
        "failures": failures.iter().take(20).collect::<Vec<_>>(),
    });
    let mut text = format!(
        "{ok} of {total} points converged ({} inverse, {}); largest residual {max_p:.2e} mm, {max_d:.2e} rad; {:.3} ms",
        chain.layout_name(),
        if c.nominal { "nominal" } else { "through the error tables" },
        seconds * 1e3
    );
    for f in failures.iter().take(20) {
        text.push('\n');
        text.push_str(f);
    }
    emit(c, &body, summary, text)?;
    if ok == total {
        Ok(())
    } else {
        Err(CliError::refused(format!(
            "{} of {total} points failed",
            total - ok
        )))
    }
}

fn chain(kinematics: &Path, machine: Option<&Path>) -> Result<(), CliError> {
    let k = load(kinematics, machine)?;
    let axes: Vec<_> = k
        .chain
        .axes()
        .iter()
        .map(|a| {
            serde_json::json!({
                "name": a.name,
                "kind": if a.kind == AxisKind::Linear { "linear" } else { "rotary" },
                "travel": [a.travel_min, a.travel_max],
            })
        })
        .collect();
    let rows: Vec<_> = k
        .chain
        .rows()
        .iter()
        .map(|r| match *r {
            Row::Fixed { dof, value } => {
                serde_json::json!({"key": "fixed", "dof": dof.name(), "value": value})
            }
            Row::Tool { dof, sign, offset } => {
                serde_json::json!({"key": "tool", "dof": dof.name(), "sign": sign, "offset": offset})
            }
            Row::Error { dof, offset, table } => serde_json::json!({
                "key": "error", "dof": dof.name(), "value": offset,
                "table": k.chain.tables()[table].name,
            }),
            Row::Axis { dof, axis, sign } => {
                serde_json::json!({"key": "axis", "dof": dof.name(), "axis": axis, "sign": sign})
            }
        })
        .collect();
    let v = serde_json::json!({
        "name": k.name, "tool_length_mm": k.tool_length_mm, "axes": axes, "rows": rows,
        "layout": k.chain.layout_name(),
    });
    println!("{v}");
    Ok(())
}
