//! `truepos kin gcode`: compensates a G-code program through LinuxCNC's own interpreter
//! (`truepos_gcode`: rs274 → canonical commands → machine coordinates → kinematics table →
//! G53 blocks). The output is written to a temporary file beside it and renamed only when the
//! whole program was compensated; without `--output` the program goes to standard output,
//! and only once it is complete.

use std::path::PathBuf;
use std::time::Duration;

use super::{geometry, load, tool_length, Common};
use crate::error::CliError;

/// Arguments of `kin gcode`.
#[derive(clap::Args)]
pub(super) struct GcodeArgs {
    #[command(flatten)]
    common: Common,
    /// LinuxCNC's tool table for the interpreter (`rs274 -t`), e.g. the machine's `tool.tbl`.
    #[arg(long)]
    tool_table: Option<PathBuf>,
    /// LinuxCNC's parameter file for the interpreter (`rs274 -v`), e.g. `linuxcnc.var` with
    /// the machine's work offsets; it is copied, never changed.
    #[arg(long)]
    var_file: Option<PathBuf>,
    /// Largest distance of a chord from the arc it replaces, mm (1e-6–10).
    #[arg(long, default_value_t = 0.001, value_parser = truepos_io::limits::finite_in(1e-6, 10.0))]
    chord_tolerance: f64,
    /// rs274 is stopped after this many seconds (1–86 400).
    #[arg(long, default_value_t = 3600.0, value_parser = truepos_io::limits::finite_in(1.0, 86_400.0))]
    time_limit: f64,
    /// An axis the kinematics table does not have, written unchanged (repeatable; A, B or C:
    /// a rotary table on the machine's base whose own errors are not modelled); without it a
    /// program that moves such an axis is refused.
    #[arg(long = "pass-axis")]
    pass_axes: Vec<char>,
    /// Scale each feed move's F by its compensated over its programmed length, so that every
    /// move takes the time the program gave it.
    #[arg(long)]
    correct_feed: bool,
    /// The interpreter executable.
    #[arg(long, default_value = "rs274")]
    rs274: PathBuf,
}

pub(super) fn gcode(a: &GcodeArgs) -> Result<(), CliError> {
    let c = &a.common;
    let k = load(&c.kinematics, c.machine.as_deref())?;
    let tool = tool_length(c, &k)?;
    let mut opts = truepos_gcode::Options::new(tool);
    opts.interpreter = truepos_gcode::Interpreter {
        rs274: a.rs274.clone(),
        tool_table: a.tool_table.clone(),
        var_file: a.var_file.clone(),
        time_limit: Duration::from_secs_f64(a.time_limit),
    };
    opts.chord_tolerance_mm = a.chord_tolerance;
    opts.geometry = geometry(c);
    opts.pass_axes = a.pass_axes.clone();
    opts.correct_feed = a.correct_feed;
    opts.header = vec![
        format!(
            "compensated by truepos kin gcode from {} through {}{}",
            c.input.display(),
            c.kinematics.display(),
            if c.nominal { " (nominal chain)" } else { "" }
        ),
        format!(
            "machine coordinates: every move is G53; N = its line in the original; tool length {tool} mm; chords within {} mm",
            a.chord_tolerance
        ),
    ];
    let gcode_err = |e: truepos_gcode::Error| CliError::refused(e.to_string());
    let s = match &c.output {
        Some(out) => {
            truepos_gcode::rewrite_file(&c.input, &k.chain, &opts, out).map_err(gcode_err)?
        }
        None => {
            let (s, body) =
                truepos_gcode::rewrite(&c.input, &k.chain, &opts, Vec::new()).map_err(gcode_err)?;
            use std::io::Write as _;
            std::io::stdout()
                .write_all(&body)
                .map_err(CliError::Stdout)?;
            s
        }
    };
    // The project's units of a compensation: µm on linear axes, µrad on rotary axes.
    let rotary: Vec<bool> = k
        .chain
        .axes()
        .iter()
        .map(|x| x.kind == truepos_model::AxisKind::Rotary)
        .collect();
    let largest: Vec<f64> = s
        .largest
        .iter()
        .zip(&rotary)
        .map(|(v, r)| if *r { v.to_radians() * 1e6 } else { v * 1e3 })
        .collect();
    let largest_map: serde_json::Map<String, serde_json::Value> = s
        .axes
        .iter()
        .zip(&largest)
        .map(|(l, v)| (l.to_string(), serde_json::json!(v)))
        .collect();
    let axes: String = s.axes.iter().collect();
    let summary = serde_json::json!({
        "canonical_commands": s.commands, "moves": s.moves, "arcs_linearised": s.arcs,
        "axes": axes, "largest_compensation_um_or_urad": largest_map,
        "direction_misses": s.direction_misses,
        "largest_direction_miss_rad": s.largest_direction_miss_rad,
        "seconds": s.seconds,
    });
    let mut text = format!(
        "{} moves written ({} canonical commands, {} arcs linearised) in {:.3} s; largest compensation {}",
        s.moves,
        s.commands,
        s.arcs,
        s.seconds,
        s.axes
            .iter()
            .zip(&largest)
            .map(|(l, v)| format!("{l} {v:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    text.push_str(" (µm on linear axes, µrad on rotary axes)");
    if s.direction_misses > 0 {
        text.push_str(&format!(
            "\n{} point(s) where the real tool direction stays up to {:.1} µrad off (not reachable with these errors); TCP exact",
            s.direction_misses,
            s.largest_direction_miss_rad * 1e6
        ));
    }
    let summary = if c.json { summary.to_string() } else { text };
    if c.output.is_some() {
        println!("{summary}");
    } else {
        eprintln!("{summary}");
    }
    Ok(())
}
