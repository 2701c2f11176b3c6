//! FANUC: the linear thermal form per axis as custom macro common variables, for a PMC ladder
//! or a macro that applies it (e.g. as an external machine coordinate shift). FANUC identifies
//! no thermal model and has no per-axis linear form of its own; its documented external write
//! path is FOCAS `cnc_wrmacro(handle, number, length, mcr_val, dec_val)` (the value is
//! `mcr_val` × 10^−`dec_val`), port 8193, for which there is no public simulator: truepos
//! computes the values and their `cnc_wrmacro` arguments and writes the same values as a
//! macro program (`%`, `O` number, `#n=value` blocks, `M99`, `%`) that sets them once.
//!
//! Per axis, three consecutive variables from a base (common variables #500–#999 are kept at
//! power off): the compensation at P0 in µm, its slope in µm/m, P0 in mm — so that
//! `ΔK [µm] = K0 + slope · (P − P0) / 1000`, the SINUMERIK line in units that keep the digits of
//! a macro value. Values are the compensation (−error), which the applying side adds to the
//! position.

use crate::projection::AxisProjection;
use crate::ControlError;
use std::path::Path;
use truepos_files::InputError;

/// Decimal places of every value in `cnc_wrmacro` (`dec_val`): 0.001 µm, 0.001 µm/m,
/// 0.001 mm.
pub const DEC_VAL: i16 = 3;

/// One axis' three variables.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanucMacroAxis {
    /// The first variable's number (K0); slope and P0 follow.
    pub number: u32,
    /// K0: the compensation at P0, µm.
    pub k0_um: f64,
    /// The slope of the compensation, µm/m.
    pub slope_um_per_m: f64,
    /// P0, mm.
    pub p0_mm: f64,
}

impl FanucMacroAxis {
    /// The compensation the applying side computes at `p_mm`, µm.
    pub fn compensation_um(&self, p_mm: f64) -> f64 {
        self.k0_um + self.slope_um_per_m * (p_mm - self.p0_mm) / 1000.0
    }

    /// The values rounded to `DEC_VAL` places, as `cnc_wrmacro` carries them.
    pub fn quantised(&self) -> Self {
        let q = |v: f64| (v * 1000.0).round() / 1000.0;
        Self {
            k0_um: q(self.k0_um),
            slope_um_per_m: q(self.slope_um_per_m),
            p0_mm: q(self.p0_mm),
            ..*self
        }
    }

    /// `(number, mcr_val, dec_val)` of the three `cnc_wrmacro` calls.
    pub fn wrmacro(&self) -> Result<[(u32, i32, i16); 3], ControlError> {
        let arg = |v: f64, n: u32| -> Result<(u32, i32, i16), ControlError> {
            let m = (v * 1000.0).round();
            if m.is_finite() && m.abs() <= f64::from(i32::MAX) {
                Ok((n, m as i32, DEC_VAL))
            } else {
                Err(ControlError::Range(format!(
                    "#{n}: {v} does not fit cnc_wrmacro's 32-bit mcr_val at {DEC_VAL} decimals"
                )))
            }
        };
        Ok([
            arg(self.k0_um, self.number)?,
            arg(self.slope_um_per_m, self.number + 1)?,
            arg(self.p0_mm, self.number + 2)?,
        ])
    }
}

/// The variables of every projected axis from variable `base` on (three per axis, within the
/// common variables #100–#199 or #500–#999).
pub fn macro_axes(proj: &[AxisProjection], base: u32) -> Result<Vec<FanucMacroAxis>, ControlError> {
    let last = base + 3 * proj.len() as u32 - 1;
    let ok = |a: u32, b: u32| {
        (100..=199).contains(&a) && b <= 199 || (500..=999).contains(&a) && b <= 999
    };
    if !ok(base, last) {
        return Err(ControlError::Range(format!(
            "variables #{base} to #{last}: expected common variables within #100–#199 or #500–#999"
        )));
    }
    Ok(proj
        .iter()
        .enumerate()
        .map(|(i, p)| FanucMacroAxis {
            number: base + 3 * i as u32,
            k0_um: p.form.k0_mm * 1000.0,
            slope_um_per_m: p.form.tan_beta * 1e6,
            p0_mm: p.form.p0_mm,
        })
        .collect())
}

/// A FANUC comment: upper case, no parentheses inside.
fn comment(s: &str) -> String {
    let clean: String = s
        .chars()
        .map(|c| match c {
            '(' | ')' => ' ',
            c if c.is_ascii_graphic() || c == ' ' => c.to_ascii_uppercase(),
            _ => '?',
        })
        .collect();
    format!("({})", clean.trim())
}

/// The macro program `O<program>` setting the variables; `header` lines and each axis' error
/// become comments.
pub fn write_macro_program(
    program: u32,
    axes: &[(FanucMacroAxis, &AxisProjection)],
    header: &[String],
) -> String {
    let mut out = format!("%\nO{program:04} (TRUEPOS THERMAL COMPENSATION)\n");
    for h in header {
        out += &(comment(h) + "\n");
    }
    for (a, p) in axes {
        let q = a.quantised();
        out += &(comment(&format!(
            "{}: #{} K0 UM, #{} SLOPE UM/M, #{} P0 MM; MISSES THE MODEL BY UP TO {:.3} UM",
            p.name,
            a.number,
            a.number + 1,
            a.number + 2,
            p.worst_um()
        )) + "\n");
        out += &format!("#{}={:.3}\n", a.number, q.k0_um);
        out += &format!("#{}={:.3}\n", a.number + 1, q.slope_um_per_m);
        out += &format!("#{}={:.3}\n", a.number + 2, q.p0_mm);
    }
    out += "M99\n%\n";
    out
}

/// Reads a macro program of `#n=value` assignments between `%` lines (an `O` line, comments in
/// parentheses and `M99`/`M30` allowed): the variables in order. Anything else is an error at
/// its line and column.
pub fn read_macro_program(file: &str, text: &str) -> Result<Vec<(u32, f64)>, ControlError> {
    let err = |line: usize, column: usize, message: String| {
        ControlError::Syntax(InputError::at(Path::new(file), line, column, "", message))
    };
    let mut vars: Vec<(u32, f64)> = Vec::new();
    let (mut percent, mut ended) = (0, false);
    for (i, raw) in text.lines().enumerate() {
        let n = i + 1;
        // A comment runs to its closing parenthesis; an unclosed one is an error.
        let mut code = String::new();
        let mut depth_at = None;
        for (c_i, c) in raw.char_indices() {
            match (c, depth_at) {
                ('(', None) => depth_at = Some(c_i),
                (')', Some(_)) => depth_at = None,
                (_, None) => code.push(c),
                _ => {}
            }
        }
        if let Some(at) = depth_at {
            return Err(err(n, at + 1, "comment without its closing `)`".into()));
        }
        let t = code.trim();
        let col = raw.len() - raw.trim_start().len() + 1;
        if t.is_empty() {
            continue;
        }
        if percent == 2 {
            return Err(err(n, col, format!("`{t}` after the closing `%`")));
        }
        if t == "%" {
            percent += 1;
            continue;
        }
        if percent == 0 {
            return Err(err(n, col, "expected `%` opening the program".into()));
        }
        if ended {
            return Err(err(
                n,
                col,
                format!("`{t}` after M99/M30; expected the closing `%`"),
            ));
        }
        if matches!(t, "M99" | "M30" | "M02" | "M2") {
            ended = true;
            continue;
        }
        if t.starts_with('O') && t[1..].chars().all(|c| c.is_ascii_digit()) && t.len() > 1 {
            continue;
        }
        let Some((lhs, rhs)) = t.strip_prefix('#').and_then(|r| r.split_once('=')) else {
            return Err(err(n, col, format!("expected `#n=value`, got `{t}`")));
        };
        let num: u32 = lhs.trim().parse().map_err(|_| {
            err(
                n,
                col + 1,
                format!("expected a variable number after `#`, got `{lhs}`"),
            )
        })?;
        let v: f64 = rhs
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                err(
                    n,
                    col + lhs.len() + 2,
                    format!("#{num}: expected a finite number, got `{}`", rhs.trim()),
                )
            })?;
        if vars.iter().any(|(k, _)| *k == num) {
            return Err(err(n, col, format!("#{num} set twice")));
        }
        vars.push((num, v));
    }
    if percent < 2 {
        return Err(err(
            text.lines().count().max(1),
            1,
            "no closing `%`: the program is cut short".into(),
        ));
    }
    Ok(vars)
}
