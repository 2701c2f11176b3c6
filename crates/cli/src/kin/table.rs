//! `truepos kin table`: converts a compensation table between truepos' CSV, LinuxCNC
//! `COMP_FILE` types 0 and 1, Siemens `$AA_ENC_COMP` / `$AN_CEC` part programs, HEIDENHAIN
//! `.COM` + `.CMA` tables, FANUC pitch error compensation tapes and ISG leadscrew error
//! compensation lists, and
//! evaluates it at given positions and directions of travel (what the check against LinuxCNC,
//! `scripts/linuxcnc_comp.sh`, compares with the running control).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::CliError;
use truepos_controls::fanuc::{parse_fanuc, FanucGrid, FanucPitch};
use truepos_controls::heidenhain::{parse_com, read_heidenhain, HeidenhainCma, HeidenhainCom};
use truepos_controls::isg::{parse_isg, IsgSsfk};
use truepos_controls::linuxcnc::{parse_linuxcnc, LinuxCncComp, LinuxCncType};
use truepos_controls::siemens::{
    parse_siemens, select_siemens, write_siemens, SiemensKind, SiemensTable,
};
use truepos_controls::table::{parse_csv, write_csv};
use truepos_files::InputError;
use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

/// Formats a table is read from.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum From {
    /// truepos' CSV (`position,value` or `position,forward,reverse`, µm).
    Csv,
    /// LinuxCNC `COMP_FILE_TYPE = 0` (actual positions, mm).
    Linuxcnc0,
    /// LinuxCNC `COMP_FILE_TYPE = 1` (trims = nominal − actual, mm).
    Linuxcnc1,
    /// Siemens INI part program (`$AA_ENC_COMP`, `$AN_CEC`, mm).
    Siemens,
    /// HEIDENHAIN: a `.CMA` assignment table (its active line's `.COM` for
    /// `--heidenhain-axis`) or a `.COM` table itself (mm).
    Heidenhain,
    /// FANUC pitch error compensation tape (parameters 3620–3624 and the point data of
    /// `--fanuc-axis`, detection units of `--fanuc-detection-unit`).
    Fanuc,
    /// ISG (Beckhoff TwinCAT CNC) leadscrew error compensation list `kw.ssfk.*` (0.1 µm).
    Isg,
}

/// Formats a table is written in.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum To {
    /// truepos' CSV.
    Csv,
    /// LinuxCNC `COMP_FILE_TYPE = 0`.
    Linuxcnc0,
    /// LinuxCNC `COMP_FILE_TYPE = 1`.
    Linuxcnc1,
    /// Siemens leadscrew table `$AA_ENC_COMP` (one direction only).
    SiemensEnc,
    /// Siemens sag/cross table(s) `$AN_CEC` (a directional table as two, `_DIRECTION` 1/−1).
    SiemensCec,
    /// HEIDENHAIN `.COM` table (`--out`) and the `.CMA` that activates it (`--cma`).
    HeidenhainCom,
    /// FANUC pitch error compensation tape (needs `--fanuc-ref-point`).
    Fanuc,
    /// ISG leadscrew error compensation list (`--isg-axis`, a directional table bilateral).
    Isg,
}

/// Arguments of `truepos kin table`.
#[derive(clap::Args)]
pub struct TableArgs {
    /// The table file.
    #[arg(long)]
    input: PathBuf,
    /// Its format.
    #[arg(long, value_enum)]
    from: From,
    /// A CSV or HEIDENHAIN table of a rotary axis (periodic over 360°); other formats say it
    /// themselves.
    #[arg(long)]
    rotary: bool,
    /// Interpolate with a monotone cubic instead of linearly (LinuxCNC and Siemens interpolate
    /// linearly).
    #[arg(long)]
    monotone: bool,
    /// Siemens: the control's name of the axis (`AX1`, `X1`). Reading: the table must read this
    /// axis (`_INPUT_AXIS` of a CEC table); writing: the axis of the table (required).
    #[arg(long)]
    siemens_axis: Option<String>,
    /// Siemens CEC: the axis the values correct (`_OUTPUT_AXIS`; default `--siemens-axis`).
    /// Reading, a CEC table correcting another axis is refused.
    #[arg(long)]
    siemens_output_axis: Option<String>,
    /// Siemens: reading, the number of the `$AN_CEC` table to use; writing, the (first) table
    /// number (default 1) or the encoder (default 0) of `$AA_ENC_COMP`.
    #[arg(long)]
    siemens_table: Option<u32>,
    /// HEIDENHAIN: the axis whose position reads the table (the `.CMA` column; `AXISPOS` is
    /// its position). Reading a `.CMA` and writing: required.
    #[arg(long)]
    heidenhain_axis: Option<String>,
    /// HEIDENHAIN: the axis the values correct (the `.COM` column; default `--heidenhain-axis`).
    #[arg(long)]
    heidenhain_output_axis: Option<String>,
    /// HEIDENHAIN writing: the `.CMA` to write beside the `.COM` (default: `--out` with the
    /// extension `.CMA`). Both files are written, or neither.
    #[arg(long)]
    cma: Option<PathBuf>,
    /// ISG writing: the logical axis number (`kopf.achs_nr`).
    #[arg(long, default_value_t = 1)]
    isg_axis: i64,
    /// ISG writing: the axis name (`kopf.log_achs_name`).
    #[arg(long)]
    isg_axis_name: Option<String>,
    /// FANUC: the axis number (`A` on the tape).
    #[arg(long, default_value_t = 1)]
    fanuc_axis: u32,
    /// FANUC writing: the point number of the reference position (3620); the table's points
    /// are numbered around it and must stay within 0–1023.
    #[arg(long)]
    fanuc_ref_point: Option<u32>,
    /// FANUC writing: the interval between points in mm (3624); default the table's own step.
    #[arg(long)]
    fanuc_interval: Option<f64>,
    /// FANUC writing: the magnification (3623); default the smallest that keeps every point
    /// within `--fanuc-max-step`.
    #[arg(long)]
    fanuc_magnification: Option<u32>,
    /// FANUC: the axis' detection unit in mm (0.001 for IS-B).
    #[arg(long, default_value_t = 0.001)]
    fanuc_detection_unit: f64,
    /// FANUC writing: the largest value of one point (the parameter manual's ±7).
    #[arg(long, default_value_t = 7)]
    fanuc_max_step: i32,
    /// FANUC writing: refuse (no file) when the quantisation loses more than this at a point.
    #[arg(long, default_value_t = 1.0)]
    max_error_um: f64,
    /// Write even when the quantisation exceeds `--max-error-um` (repeated as a warning).
    #[arg(long)]
    force: bool,
    /// The format to write (with `--out`).
    #[arg(long, value_enum, requires = "out")]
    to: Option<To>,
    /// The file to write: written whole or not at all.
    #[arg(long, requires = "to")]
    out: Option<PathBuf>,
    /// Evaluate the table at the rows of this CSV (`position,direction`, direction 1 forward
    /// or −1 reverse): prints `position,direction,error_um,compensation_um` (compensation =
    /// −error, what a control adds to the command).
    #[arg(long)]
    eval: Option<PathBuf>,
}

pub fn table(a: &TableArgs) -> Result<(), CliError> {
    if a.to.is_none() && a.eval.is_none() {
        return Err(CliError::refused(
            "nothing to do: give --to FORMAT --out FILE, --eval POSITIONS.csv or both",
        ));
    }
    let t = read(a)?;
    if let (Some(to), Some(out)) = (a.to, &a.out) {
        let mut files = vec![(out.clone(), String::new())];
        files[0].1 = write(a, &t, to, &mut files).map_err(CliError::context(format!(
            "{}: cannot write the table in this format: ",
            out.display()
        )))?;
        let whole: Vec<(&Path, &[u8])> = files
            .iter()
            .map(|(p, text)| (p.as_path(), text.as_bytes()))
            .collect();
        let mut inputs: Vec<(&str, &Path)> = vec![("--input", &a.input)];
        inputs.extend(a.cma.as_deref().map(|c| ("--cma", c)));
        crate::write::write_all_whole(&whole, &inputs)?;
        eprintln!(
            "wrote {} support points ({}) to {}",
            t.positions().len(),
            if t.reverse().is_some() {
                "directional"
            } else {
                "one direction"
            },
            out.display()
        );
    }
    if let Some(eval) = &a.eval {
        print!("{}", evaluate(&t, eval)?);
    }
    Ok(())
}

fn read(a: &TableArgs) -> Result<CompTable, CliError> {
    let path = &a.input;
    let text = crate::write::read_text(path, truepos_files::TABLE)?;
    let interp = if a.monotone {
        Interpolation::MonotoneCubic
    } else {
        Interpolation::Linear
    };
    let heidenhain_only = a.heidenhain_axis.is_some() || a.heidenhain_output_axis.is_some();
    if a.from != From::Heidenhain && heidenhain_only && a.to != Some(To::HeidenhainCom) {
        return Err(CliError::refused(
            "--heidenhain-axis and --heidenhain-output-axis are for HEIDENHAIN tables (--from heidenhain or --to heidenhain-com)",
        ));
    }
    if a.cma.is_some() && a.to != Some(To::HeidenhainCom) {
        return Err(CliError::refused("--cma goes with --to heidenhain-com"));
    }
    let siemens_only =
        a.siemens_table.is_some() || a.siemens_axis.is_some() || a.siemens_output_axis.is_some();
    if a.from != From::Siemens
        && siemens_only
        && a.to
            .is_none_or(|t| !matches!(t, To::SiemensCec | To::SiemensEnc))
    {
        return Err(CliError::refused(
            "--siemens-axis, --siemens-output-axis and --siemens-table are for Siemens tables (--from siemens or --to siemens-…)",
        ));
    }
    Ok(match a.from {
        From::Csv => {
            let wrap = if a.rotary { Wrap::Rotary } else { Wrap::Hold };
            parse_csv(path, &text, wrap, interp)?
        }
        From::Linuxcnc0 | From::Linuxcnc1 => {
            let ty = if a.from == From::Linuxcnc0 {
                LinuxCncType::Positions
            } else {
                LinuxCncType::Trims
            };
            parse_linuxcnc(path, &text, ty)?.to_table(interp)?
        }
        From::Isg => parse_isg(path, &text)?.to_table(interp)?,
        From::Fanuc => parse_fanuc(path, &text)?.to_table(
            path,
            a.fanuc_axis,
            a.fanuc_detection_unit,
            interp,
        )?,
        From::Heidenhain => {
            let wrap = if a.rotary { Wrap::Rotary } else { Wrap::Hold };
            let is_com = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("com"));
            if is_com {
                let com = parse_com(path, &text)?;
                let column = match (&a.heidenhain_output_axis, com.columns.as_slice()) {
                    (Some(c), _) => c.clone(),
                    (None, [(only, _)]) => only.clone(),
                    (None, _) => {
                        return Err(CliError::refused(format!(
                            "{}: the table has several columns; say which with --heidenhain-output-axis",
                            path.display()
                        )))
                    }
                };
                com.to_table(&column, wrap, interp)?
            } else {
                let axis = a.heidenhain_axis.as_deref().ok_or_else(|| {
                    CliError::refused(
                        "reading a .CMA needs --heidenhain-axis (the axis whose table to use)",
                    )
                })?;
                let output = a.heidenhain_output_axis.as_deref().unwrap_or(axis);
                read_heidenhain(path, axis, output, wrap, interp)?
            }
        }
        From::Siemens => {
            let all = parse_siemens(path, &text, None)?;
            let output = a
                .siemens_output_axis
                .as_deref()
                .or(a.siemens_axis.as_deref());
            select_siemens(
                path,
                &all,
                a.siemens_axis.as_deref(),
                output,
                a.siemens_table,
                interp,
            )?
        }
    })
}

/// The text of `--out` in format `to`; a format of several files (HEIDENHAIN's `.COM` and
/// `.CMA`) appends the others to `files`.
fn write(
    a: &TableArgs,
    t: &CompTable,
    to: To,
    files: &mut Vec<(PathBuf, String)>,
) -> Result<String, CliError> {
    let axis = || {
        a.siemens_axis
            .clone()
            .ok_or_else(|| CliError::refused("a Siemens table needs --siemens-axis"))
    };
    Ok(match to {
        To::Csv => write_csv(t),
        To::Linuxcnc0 | To::Linuxcnc1 => {
            let ty = if to == To::Linuxcnc0 {
                LinuxCncType::Positions
            } else {
                LinuxCncType::Trims
            };
            LinuxCncComp::from_table(t, ty)
                .map_err(|e| CliError::refused(e.to_string()))?
                .write()
        }
        To::SiemensEnc => {
            let kind = SiemensKind::Encoder {
                encoder: a.siemens_table.unwrap_or(0),
                axis: axis()?,
            };
            let s =
                SiemensTable::from_table(t, kind).map_err(|e| CliError::refused(e.to_string()))?;
            write_siemens(&[s])
        }
        To::SiemensCec => {
            let input = axis()?;
            let output = a
                .siemens_output_axis
                .clone()
                .unwrap_or_else(|| input.clone());
            let first = a.siemens_table.unwrap_or(1);
            let tables = if t.reverse().is_some() {
                SiemensTable::directional_pair(t, first, &input, &output)
                    .map_err(|e| CliError::refused(e.to_string()))?
                    .to_vec()
            } else {
                let mut s = SiemensTable::from_table(t, SiemensKind::Cec { table: first })
                    .map_err(|e| CliError::refused(e.to_string()))?;
                s.input_axis = Some(input);
                s.output_axis = Some(output);
                vec![s]
            };
            write_siemens(&tables)
        }
        To::Fanuc => fanuc_tape(a, t)?,
        To::Isg => IsgSsfk::from_table(t, a.isg_axis, a.isg_axis_name.as_deref())
            .map_err(|e| CliError::refused(e.to_string()))?
            .write(),
        To::HeidenhainCom => {
            let axis = a.heidenhain_axis.as_deref().ok_or_else(|| {
                CliError::refused(
                    "a HEIDENHAIN table needs --heidenhain-axis (the axis that reads it)",
                )
            })?;
            let output = a.heidenhain_output_axis.as_deref().unwrap_or(axis);
            let out = &files[0].0;
            let com_name = out
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let cma = a.cma.clone().unwrap_or_else(|| out.with_extension("CMA"));
            let cma_name = cma
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let com = HeidenhainCom::from_table(t, &com_name, output)
                .map_err(|e| CliError::refused(e.to_string()))?;
            let assign = HeidenhainCma::single(&cma_name, axis, &com_name)
                .map_err(|e| CliError::refused(e.to_string()))?;
            files.push((cma, assign.write()));
            com.write()
        }
    })
}

/// The FANUC tape of `t`, refused above `--max-error-um` of quantisation unless `--force`;
/// what the grid loses is printed either way.
fn fanuc_tape(a: &TableArgs, t: &CompTable) -> Result<String, CliError> {
    let reference = a.fanuc_ref_point.ok_or_else(|| {
        CliError::refused("a FANUC tape needs --fanuc-ref-point (parameter 3620)")
    })?;
    let grid = FanucGrid {
        axis: a.fanuc_axis,
        reference,
        interval: a.fanuc_interval,
        magnification: a.fanuc_magnification,
        detection_unit: a.fanuc_detection_unit,
        max_step: a.fanuc_max_step,
    };
    let (tape, loss) =
        FanucPitch::from_table(t, &grid).map_err(|e| CliError::refused(e.to_string()))?;
    eprintln!(
        "FANUC A{}: magnification {}, quantisation {:.3} µm at most; the table's error at the reference position ({:.3} µm) is not carried (the control's compensation is zero there)",
        a.fanuc_axis, loss.magnification, loss.quantisation_um, loss.at_reference_um
    );
    if loss.quantisation_um > a.max_error_um {
        let msg = format!(
            "the quantisation loses {:.3} µm at a point, more than --max-error-um {}; use a finer detection unit or magnification, or --force",
            loss.quantisation_um, a.max_error_um
        );
        if !a.force {
            return Err(CliError::refused(msg));
        }
        eprintln!("warning: {msg}");
    }
    Ok(tape.write())
}

/// `position,direction,error_um,compensation_um` at each row of `path`.
fn evaluate(t: &CompTable, path: &Path) -> Result<String, CliError> {
    let rows = super::read_csv(path)?;
    let cols = super::columns(path, &rows, &["position", "direction"])?;
    let mut out = String::from("position,direction,error_um,compensation_um\n");
    for (line, r) in &rows.rows {
        let (p, d) = (r[cols[0]], r[cols[1]]);
        let direction = match d {
            1.0 => Direction::Forward,
            -1.0 => Direction::Reverse,
            _ => {
                return Err(InputError::at(
                    path,
                    *line,
                    1,
                    "direction",
                    format!("expected 1 (forward) or -1 (reverse), got {d}"),
                )
                .into())
            }
        };
        let e = t.value(p, direction);
        let _ = writeln!(out, "{p},{d},{e},{}", -e);
    }
    Ok(out)
}
