//! The recording the judge reads: LinuxCNC's `sampler` component records, every servo cycle,
//! what the control actually did; `halsampler -t` writes it as text lines. Two samplers run on
//! the same enable signal:
//!
//! - **motion** (`sampler.0`): `tag`, then per axis `axis.L.pos-cmd` (nominal, mm), per axis
//!   `axis.L.eoffset` (applied external offset, mm), per joint `joint.N.pos-fb` (mm), per axis
//!   `truepos.axis.L.offset-um` (sent, µm), then `truepos.status`, `truepos.model-select`,
//!   `truepos.path.1.model` (the model in effect), per axis `truepos.axis.L.path` (the
//!   control's axis configuration) and `motion.servo.last-period` (the servo cycle's real
//!   length, in CPU clocks of unknown rate: the check scales it by its median to the period).
//! - **temperatures** (`sampler.1`): `tag`, then every `truepos.temp.<id>` pin in machine order.

use std::fmt;
use std::path::Path;

use truepos_model::Machine;

/// One servo cycle as the samplers recorded it.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Nominal axis positions (`axis.L.pos-cmd`), mm.
    pub nominal: Vec<f64>,
    /// Applied external offsets (`axis.L.eoffset`), mm.
    pub applied_mm: Vec<f64>,
    /// Joint feedback (`joint.N.pos-fb`), mm; trivial kinematics: joint N = axis N.
    pub joint: Vec<f64>,
    /// What truepos sent (`truepos.axis.L.offset-um`), µm.
    pub sent_um: Vec<f64>,
    /// `truepos.status`.
    pub status: i32,
    /// `truepos.model-select`.
    pub select: i32,
    /// `truepos.path.1.model`: the model the component used on path 1 (−1: none).
    pub model: i32,
    /// `truepos.axis.L.path` per axis: the path each axis belonged to (0: none).
    pub axis_paths: Vec<i32>,
    /// `motion.servo.last-period`: the time since the previous servo cycle, in CPU clocks.
    pub servo_clocks: f64,
    /// Temperatures on the `truepos.temp.*` pins, °C.
    pub temperatures_c: Vec<f64>,
}

/// A malformed sampler file.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleError {
    /// The file.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// What was expected.
    pub message: String,
}

impl fmt::Display for SampleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.message)
    }
}

impl std::error::Error for SampleError {}

fn parse_lines(
    file: &str,
    text: &str,
    columns: usize,
) -> Result<Vec<(u64, Vec<f64>)>, SampleError> {
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let err = |message: String| SampleError {
            file: file.to_string(),
            line: i + 1,
            message,
        };
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != columns + 1 {
            return Err(err(format!(
                "expected a sample tag and {columns} values, found {} fields",
                fields.len()
            )));
        }
        let tag: u64 = fields[0]
            .parse()
            .map_err(|_| err(format!("sample tag {:?} is not an integer", fields[0])))?;
        let values = fields[1..]
            .iter()
            .enumerate()
            .map(|(c, f)| {
                // halsampler prints a NaN as `nan` or `-nan` (printf).
                f.parse::<f64>()
                    .or_else(|e| match f.trim_start_matches(['-', '+']) {
                        "nan" | "NaN" => Ok(f64::NAN),
                        _ => Err(e),
                    })
                    .map_err(|_| err(format!("column {}: {f:?} is not a number", c + 2)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        rows.push((tag, values));
    }
    Ok(rows)
}

/// Joins the motion and temperature sampler texts (by sample tag) into samples for a machine
/// with `axes` axes and `temperatures` temperature channels.
pub fn parse_samples(
    motion_file: &str,
    motion: &str,
    temperature_file: &str,
    temperatures: &str,
    axes: usize,
    temperature_count: usize,
) -> Result<Vec<Sample>, SampleError> {
    let m = parse_lines(motion_file, motion, 5 * axes + 4)?;
    let t = parse_lines(temperature_file, temperatures, temperature_count)?;
    let mut out = Vec::with_capacity(m.len().min(t.len()));
    let mut j = 0;
    for (tag, v) in m {
        while j < t.len() && t[j].0 < tag {
            j += 1;
        }
        if j < t.len() && t[j].0 == tag {
            out.push(Sample {
                nominal: v[..axes].to_vec(),
                applied_mm: v[axes..2 * axes].to_vec(),
                joint: v[2 * axes..3 * axes].to_vec(),
                sent_um: v[3 * axes..4 * axes].to_vec(),
                status: v[4 * axes] as i32,
                select: v[4 * axes + 1] as i32,
                model: v[4 * axes + 2] as i32,
                axis_paths: v[4 * axes + 3..5 * axes + 3]
                    .iter()
                    .map(|&p| p as i32)
                    .collect(),
                servo_clocks: v[5 * axes + 3],
                temperatures_c: t[j].1.clone(),
            });
        }
    }
    Ok(out)
}

/// Reads and joins two `halsampler -t` files.
pub fn load_samples(
    motion: &Path,
    temperatures: &Path,
    machine: &Machine,
) -> Result<Vec<Sample>, SampleError> {
    let read = |p: &Path| {
        std::fs::read_to_string(p).map_err(|e| SampleError {
            file: p.display().to_string(),
            line: 0,
            message: format!("cannot read: {e}"),
        })
    };
    parse_samples(
        &motion.display().to_string(),
        &read(motion)?,
        &temperatures.display().to_string(),
        &read(temperatures)?,
        machine.axes.len(),
        machine.temperatures.len(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joins_by_tag_and_names_bad_lines() {
        // One axis, one temperature: motion has tag + 5·1 + 4 = 10 fields.
        let motion = "0 1.0 0.001 1.001 1.0 1 0 0 1 999\n1 2.0 0.002 2.002 2.0 1 0 0 1 1001\n\
                      2 3 0 3 0 1 0 0 1 1000\n";
        let temps = "1 20.5\n2 -nan\n";
        let s = parse_samples("m", motion, "t", temps, 1, 1).unwrap();
        assert_eq!(s.len(), 2); // tag 0 has no temperature line
        assert_eq!(s[0].nominal, vec![2.0]);
        assert_eq!(s[0].temperatures_c, vec![20.5]);
        assert_eq!(s[1].select, 0);
        assert_eq!((s[1].model, s[1].axis_paths.clone()), (0, vec![1]));
        assert_eq!(s[1].servo_clocks, 1000.0);
        assert!(s[1].temperatures_c[0].is_nan());
        let bad = parse_samples("m.txt", "0 1 2\n", "t", temps, 1, 1).unwrap_err();
        assert_eq!(
            bad.to_string(),
            "m.txt:1: expected a sample tag and 9 values, found 3 fields"
        );
        let bad = parse_samples("m.txt", motion, "t.txt", "1 x\n", 1, 1).unwrap_err();
        assert_eq!(bad.to_string(), "t.txt:1: column 2: \"x\" is not a number");
    }
}
