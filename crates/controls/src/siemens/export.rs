//! Siemens SINUMERIK 840D sl / 828D temperature compensation as a part program: the three
//! setting data per axis (Function Manual Extended Functions, K3, temperature compensation:
//! SD43900 `$SA_TEMP_COMP_ABS_VALUE`, SD43910 `$SA_TEMP_COMP_SLOPE`, SD43920
//! `$SA_TEMP_COMP_REF_POSITION`), which take effect when written and which the control applies
//! only where MD32750 `$MA_TEMP_COMP_TYPE` enables them (limited in rate by MD32760
//! `$MA_COMP_ADD_VELO_FACTOR`). The program sets a state once; a cyclic update goes through the
//! PLC, a synchronized action or OPC UA.
//!
//! [`write_program`] writes the program; [`read_program`] reads one back (and any program made
//! of such assignments), with errors at line and column.

use crate::projection::{AxisProjection, LinearForm};
use crate::ControlError;
use std::path::Path;
use truepos_files::InputError;

/// Setting data names, in the order written.
const ABS: &str = "$SA_TEMP_COMP_ABS_VALUE";
const SLOPE: &str = "$SA_TEMP_COMP_SLOPE";
const REF: &str = "$SA_TEMP_COMP_REF_POSITION";

/// The part program setting every projected axis; `header` lines become comments.
pub fn write_program(projections: &[AxisProjection], header: &[String]) -> String {
    let mut out = String::new();
    for h in header {
        for line in h.lines() {
            out += &format!("; {line}\n");
        }
    }
    for p in projections {
        out += &format!(
            "; {}: largest error of the line along the travel {:.3} µm{}\n",
            p.name,
            p.along_error_um,
            p.cross_axis
                .iter()
                .map(|c| format!(", when {} travels {:.3} µm", c.axis, c.change_um))
                .collect::<String>()
        );
        out += &format!("{ABS}[{}]={:.7}\n", p.name, p.form.k0_mm);
        out += &format!("{SLOPE}[{}]={:.10}\n", p.name, p.form.tan_beta);
        out += &format!("{REF}[{}]={:.4}\n", p.name, p.form.p0_mm);
    }
    out += "M17\n";
    out
}

/// One axis as a program sets it.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisSetting {
    /// The axis identifier in brackets.
    pub axis: String,
    /// Its form (a setting data the program leaves out reads 0, the control's default).
    pub form: LinearForm,
}

/// Reads a program of `$SA_TEMP_COMP_…[AXIS]=value` assignments (comments after `;`, blank
/// lines and the end `M17`/`M30`/`M2` allowed): the axes in order of first appearance. Anything
/// else is an error at its line and column, so a file that is not such a program is not read
/// as one.
pub fn read_program(file: &str, text: &str) -> Result<Vec<AxisSetting>, ControlError> {
    let mut axes: Vec<AxisSetting> = Vec::new();
    let mut ended = false;
    for (i, raw) in text.lines().enumerate() {
        let at = |col: usize, what: String| {
            ControlError::Syntax(InputError::at(Path::new(file), i + 1, col + 1, "", what))
        };
        let code = raw.split(';').next().unwrap_or("");
        let trimmed = code.trim();
        let col = code.len() - code.trim_start().len();
        if trimmed.is_empty() {
            continue;
        }
        if ended {
            return Err(at(col, format!("`{trimmed}` after the program's end")));
        }
        if matches!(trimmed, "M17" | "M30" | "M2" | "M02") {
            ended = true;
            continue;
        }
        let (name, rest) = trimmed.split_once('[').ok_or_else(|| {
            at(
                col,
                format!("expected `{ABS}[AXIS]=value` (or SLOPE, REF_POSITION), got `{trimmed}`"),
            )
        })?;
        let (axis, value) = rest
            .split_once("]=")
            .ok_or_else(|| at(col + name.len(), "expected `[AXIS]=value`".to_string()))?;
        let value_col = col + name.len() + axis.len() + 3;
        let v: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                at(
                    value_col,
                    format!(
                        "`{name}[{axis}]`: expected a finite number, got `{}`",
                        value.trim()
                    ),
                )
            })?;
        if axis.is_empty() || !axis.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(at(
                col + name.len() + 1,
                format!("`{axis}` is not an axis identifier"),
            ));
        }
        let k = match axes.iter().position(|s| s.axis == axis) {
            Some(k) => k,
            None => {
                axes.push(AxisSetting {
                    axis: axis.to_string(),
                    form: LinearForm {
                        k0_mm: 0.0,
                        tan_beta: 0.0,
                        p0_mm: 0.0,
                    },
                });
                axes.len() - 1
            }
        };
        let form = &mut axes[k].form;
        match name {
            ABS => form.k0_mm = v,
            SLOPE => form.tan_beta = v,
            REF => form.p0_mm = v,
            other => {
                return Err(at(
                    col,
                    format!("`{other}`: expected {ABS}, {SLOPE} or {REF}"),
                ));
            }
        }
    }
    Ok(axes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn projection(name: &str, k0: f64, tb: f64, p0: f64) -> AxisProjection {
        AxisProjection {
            axis: 0,
            name: name.into(),
            form: LinearForm {
                k0_mm: k0,
                tan_beta: tb,
                p0_mm: p0,
            },
            along_error_um: 0.25,
            cross_axis: Vec::new(),
        }
    }

    #[test]
    fn a_bad_line_is_located() {
        let e = read_program("t.mpf", "; c\n$SA_TEMP_COMP_SLOPE[X]=abc\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.mpf:2:24: `$SA_TEMP_COMP_SLOPE[X]`: expected a finite number, got `abc`"
        );
        let e = read_program("t.mpf", "G0 X10\n").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("t.mpf:1:1: expected `$SA_TEMP_COMP_ABS_VALUE[AXIS]=value`"),
            "{e}"
        );
        let e = read_program("t.mpf", "M17\n$SA_TEMP_COMP_SLOPE[X]=1\n").unwrap_err();
        assert!(e.to_string().contains("after the program's end"), "{e}");
    }

    proptest! {
        /// What is written reads back to the written precision.
        #[test]
        fn round_trip(k0 in -3.0f64..3.0, tb in -1e-3f64..1e-3, p0 in -2000.0f64..2000.0, k1 in -3.0f64..3.0) {
            let ps = [projection("X1", k0, tb, p0), projection("Z", k1, 0.0, 0.0)];
            let text = write_program(&ps, &["model `m` at t = 1 h".into()]);
            let back = read_program("p.mpf", &text).unwrap();
            prop_assert_eq!(back.len(), 2);
            prop_assert_eq!(&back[0].axis, "X1");
            prop_assert!((back[0].form.k0_mm - k0).abs() <= 0.5e-7);
            prop_assert!((back[0].form.tan_beta - tb).abs() <= 0.5e-10);
            prop_assert!((back[0].form.p0_mm - p0).abs() <= 0.5e-4);
            prop_assert!((back[1].form.k0_mm - k1).abs() <= 0.5e-7);
        }

        /// Arbitrary text never panics: it reads or fails at a line.
        #[test]
        fn any_text_reads_or_fails_located(text in ".{0,200}") {
            if let Err(e) = read_program("p.mpf", &text) {
                prop_assert!(e.to_string().starts_with("p.mpf:"));
            }
        }
    }
}
