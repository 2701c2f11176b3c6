//! What the integration tests share: the repository's examples, rs274 (required: a missing
//! interpreter fails the test and names the install script), and an independent reading of a
//! program's machine-coordinate points.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use truepos_gcode::canon::Pos6;
use truepos_gcode::motion::{Block, Motion};
use truepos_gcode::Interpreter;
use truepos_io::kinematics_file::{self, KinematicsFile};

pub const SAMPLES: &str = "/usr/share/linuxcnc/ncfiles";

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn example(machine: &str) -> KinematicsFile {
    let p = repo().join(format!("examples/kinematics/{machine}/kinematics.ktab"));
    kinematics_file::load(&p, None).unwrap_or_else(|e| panic!("{e}"))
}

pub fn tool_table() -> PathBuf {
    repo().join("examples/kinematics/sample-mill/tool.tbl")
}

/// rs274 must be installed: the suite fails (never skips) without it.
pub fn require_rs274() {
    let ok = std::process::Command::new("rs274")
        .arg("-h")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok();
    assert!(
        ok,
        "rs274 (LinuxCNC's standalone interpreter) is not installed: run scripts/install_linuxcnc.sh"
    );
}

pub fn interpreter() -> Interpreter {
    Interpreter {
        tool_table: Some(tool_table()),
        ..Interpreter::default()
    }
}

/// One move as rs274 and the state machine see it.
#[derive(Debug, Clone)]
pub struct Point {
    pub line: Option<u64>,
    pub machine: Pos6,
    pub tool_offset_z: f64,
    pub end: bool,
    /// mm per program unit when it was printed (rs274 prints four decimals of that unit).
    pub unit_mm: f64,
    /// Whether an XY rotation (G10 L2 R) was in force.
    pub rotated: bool,
}

/// The machine-coordinate points of a program, through rs274 and the state machine.
pub fn points(program: &Path, chord_mm: f64) -> Vec<Point> {
    let dir = tempfile::tempdir().unwrap();
    let mut m = Motion::new(chord_mm);
    let mut v = Vec::new();
    interpreter()
        .run(program, dir.path(), |line, place| {
            let unit_mm = m.units().mm();
            let rotated = m.rotation_deg() != 0.0;
            m.step(&line.command, &mut |b| {
                let (machine, tool_offset_z, end) = match b {
                    Block::Move {
                        machine,
                        tool_offset_z,
                        end,
                        ..
                    } => (machine, tool_offset_z, end),
                    Block::Tap {
                        machine,
                        tool_offset_z,
                        ..
                    } => (machine, tool_offset_z, true),
                    _ => return,
                };
                v.push(Point {
                    line: place.line,
                    machine,
                    tool_offset_z,
                    end,
                    unit_mm,
                    rotated,
                });
            })
            .unwrap_or_else(|e| panic!("{}: {e}", program.display()));
            Ok(truepos_gcode::rs274::Flow::Continue)
        })
        .unwrap_or_else(|e| panic!("{e}"));
    v
}

/// The moves of a compensated program as written (full precision), in mm and degrees, with
/// their N words: `letters` the axis words to read. A rigid tap (`G91 G33.1`, an increment
/// from the last point) is the point it taps to.
pub fn written(output: &Path, letters: &[char]) -> Vec<(Option<u64>, Vec<f64>)> {
    let text = std::fs::read_to_string(output).unwrap();
    let mut per = 1.0;
    let mut v: Vec<(Option<u64>, Vec<f64>)> = Vec::new();
    let mut at: Vec<f64> = Vec::new();
    for l in text.lines() {
        let words: Vec<&str> = l.split_whitespace().collect();
        let n = words
            .first()
            .and_then(|w| w.strip_prefix('N'))
            .and_then(|d| d.parse().ok());
        if words.contains(&"G20") {
            per = 25.4;
        }
        if words.contains(&"G21") {
            per = 1.0;
        }
        let tap = words.contains(&"G33.1");
        if !words.contains(&"G53") && !tap {
            continue;
        }
        let q = letters
            .iter()
            .map(|c| {
                let w = words
                    .iter()
                    .find(|w| w.starts_with(*c))
                    .unwrap_or_else(|| panic!("{c} in `{l}`"));
                let x: f64 = w[1..].parse().unwrap();
                if "XYZ".contains(*c) {
                    x * per
                } else {
                    x
                }
            })
            .collect();
        if tap {
            let to: Vec<f64> = at
                .iter()
                .zip(&q)
                .map(|(a, d): (&f64, &f64)| a + d)
                .collect();
            v.push((n, to));
        } else {
            at.clone_from(&q);
            v.push((n, q));
        }
    }
    v
}
