//! ISG kernel (Beckhoff TwinCAT CNC) temperature compensation as axis parameter list entries
//! (ISG axis parameters P-AXIS-00271 … 00274, "temperature compensation" in the axis
//! compensation documentation): per axis a line over its position, defined by
//! `lr_param.temp_comp_position_0` (P-AXIS-00272, basic position, 0.1 µm),
//! `lr_param.temp_comp_offset_0` (P-AXIS-00273, offset at that position, 0.1 µm) and
//! `lr_param.temp_comp_coefficient` (P-AXIS-00274, geometrical pitch, µm/m), switched on by
//! `lr_param.temp_comp 1` (P-AXIS-00271); all signed 32-bit integers. The parameters are
//! "taken from the measuring curve" of the axis' deviations, as the leadscrew compensation's
//! values are actual − set-point: truepos writes the error line (the negative of the
//! SINUMERIK compensation line). Said so in docs/controls.md as not verified on a control.
//!
//! [`write_parameters`] writes one block per axis, each starting with `kopf.achs_nr` (the
//! block belongs in that axis' parameter list); [`read_parameters`] reads them back.

use crate::projection::AxisProjection;
use crate::ControlError;
use std::path::Path;
use truepos_files::InputError;

/// One axis' temperature compensation parameters as the list states them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IsgTempComp {
    /// `kopf.achs_nr`: the logical axis number.
    pub axis_nr: i64,
    /// P-AXIS-00272, 0.1 µm.
    pub position_0: i64,
    /// P-AXIS-00273, 0.1 µm.
    pub offset_0: i64,
    /// P-AXIS-00274, µm/m.
    pub coefficient: i64,
}

impl IsgTempComp {
    /// The error the control's line stands for at position `p_mm`, µm.
    pub fn error_um(&self, p_mm: f64) -> f64 {
        self.offset_0 as f64 / 10.0
            + self.coefficient as f64 * (p_mm - self.position_0 as f64 / 1e4) / 1000.0
    }

    /// The compensation it applies at `p_mm` (−error), mm.
    pub fn compensation_mm(&self, p_mm: f64) -> f64 {
        -self.error_um(p_mm) / 1000.0
    }

    /// The parameters of a projected axis (`axis_nr` its logical number) and the largest
    /// difference their whole units make against the projected line over `travel` (mm), µm.
    /// A value beyond a signed 32-bit integer is refused.
    pub fn from_projection(
        p: &AxisProjection,
        axis_nr: i64,
        travel: (f64, f64),
    ) -> Result<(Self, f64), ControlError> {
        let whole = |v: f64, what: &str| -> Result<i64, ControlError> {
            let r = v.round();
            if r.is_finite() && r.abs() <= f64::from(i32::MAX) {
                Ok(r as i64)
            } else {
                Err(ControlError::Range(format!(
                    "axis {}: {what} {v} does not fit the parameter's 32-bit integer",
                    p.name
                )))
            }
        };
        let t = Self {
            axis_nr,
            position_0: whole(p.form.p0_mm * 1e4, "P-AXIS-00272 (0.1 µm)")?,
            offset_0: whole(-p.form.k0_mm * 1e4, "P-AXIS-00273 (0.1 µm)")?,
            coefficient: whole(-p.form.tan_beta * 1e6, "P-AXIS-00274 (µm/m)")?,
        };
        // Both lines are straight: the largest difference is at an end of the travel.
        let loss = [travel.0, travel.1]
            .iter()
            .map(|&x| (t.compensation_mm(x) - p.form.at(x)).abs() * 1000.0)
            .fold(0.0, f64::max);
        Ok((t, loss))
    }
}

/// The parameter list blocks of every axis; `header` lines and each axis' projection error
/// become `#` comments.
pub fn write_parameters(axes: &[(IsgTempComp, &AxisProjection, f64)], header: &[String]) -> String {
    let mut out = String::new();
    for h in header {
        for line in h.lines() {
            out += &format!("# {line}\n");
        }
    }
    for (t, p, loss) in axes {
        out += &format!(
            "#\n# {}: error line {} + {}·(P − {}) [0.1 µm, µm/m]; misses the model by up to {:.3} µm, whole units {:.3} µm more\n",
            p.name, t.offset_0, t.coefficient, t.position_0, p.worst_um(), loss
        );
        out += &format!("{:<36} {}\n", "kopf.achs_nr", t.axis_nr);
        out += &format!("{:<36} 1\n", "lr_param.temp_comp");
        out += &format!("{:<36} {}\n", "lr_param.temp_comp_position_0", t.position_0);
        out += &format!("{:<36} {}\n", "lr_param.temp_comp_offset_0", t.offset_0);
        out += &format!(
            "{:<36} {}\n",
            "lr_param.temp_comp_coefficient", t.coefficient
        );
    }
    out
}

/// Reads blocks of `kopf.achs_nr` and the four temperature compensation parameters (`#`
/// comments and blank lines allowed; every block complete, `temp_comp` 1). Anything else is an
/// error at its line and column.
pub fn read_parameters(file: &str, text: &str) -> Result<Vec<IsgTempComp>, ControlError> {
    let mut out: Vec<(IsgTempComp, [bool; 4], usize)> = Vec::new();
    let err = |line: usize, column: usize, message: String| {
        ControlError::Syntax(InputError::at(Path::new(file), line, column, "", message))
    };
    for (i, raw) in text.lines().enumerate() {
        let n = i + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let col = raw.len() - raw.trim_start().len() + 1;
        let mut w = t.split_whitespace();
        let (Some(key), Some(value), None) = (w.next(), w.next(), w.next()) else {
            return Err(err(n, col, format!("expected `name value`, got `{t}`")));
        };
        let vcol = col + t.find(value).unwrap_or(0);
        let v: i64 = value
            .parse()
            .ok()
            .filter(|v: &i64| v.unsigned_abs() <= i32::MAX as u64)
            .ok_or_else(|| {
                err(
                    n,
                    vcol,
                    format!("`{key}`: expected a 32-bit integer, got `{value}`"),
                )
            })?;
        if key == "kopf.achs_nr" {
            let blank = IsgTempComp {
                axis_nr: v,
                position_0: 0,
                offset_0: 0,
                coefficient: 0,
            };
            out.push((blank, [false; 4], n));
            continue;
        }
        let Some((cur, seen, _)) = out.last_mut() else {
            return Err(err(
                n,
                col,
                format!("`{key}` before `kopf.achs_nr`; expected a block per axis"),
            ));
        };
        let slot = match key {
            "lr_param.temp_comp" if v == 1 => 0,
            "lr_param.temp_comp" => {
                return Err(err(
                    n,
                    vcol,
                    format!("temperature compensation switched off ({v}); expected 1"),
                ))
            }
            "lr_param.temp_comp_position_0" => 1,
            "lr_param.temp_comp_offset_0" => 2,
            "lr_param.temp_comp_coefficient" => 3,
            _ => {
                return Err(err(
                    n,
                    col,
                    format!("unknown name `{key}`; expected kopf.achs_nr or lr_param.temp_comp…"),
                ))
            }
        };
        if std::mem::replace(&mut seen[slot], true) {
            return Err(err(
                n,
                col,
                format!("`{key}` given twice for axis {}", cur.axis_nr),
            ));
        }
        match slot {
            1 => cur.position_0 = v,
            2 => cur.offset_0 = v,
            3 => cur.coefficient = v,
            _ => {}
        }
    }
    if let Some((t, _, line)) = out.iter().find(|(_, seen, _)| seen.contains(&false)) {
        return Err(err(
            *line,
            1,
            format!(
                "axis {}: expected lr_param.temp_comp, …_position_0, …_offset_0 and …_coefficient",
                t.axis_nr
            ),
        ));
    }
    if out.is_empty() {
        return Err(err(
            1,
            1,
            "no `kopf.achs_nr` block; expected one per axis".into(),
        ));
    }
    Ok(out.into_iter().map(|(t, _, _)| t).collect())
}
