//! Projection of a model onto a control's per-axis form at one thermal state.
//!
//! A truepos model gives the error of every axis anywhere in the working volume; a control's
//! temperature compensation carries, per axis, a line over that axis' own position
//! (Siemens/ISG: ΔK = K0 + tanβ·(P − P0)) or a constant (HEIDENHAIN PLC module 9231). The
//! projection fits the form to the model's compensation along the axis' travel, the other axes
//! where they are now, and states what it loses: the largest deviation along the travel (the
//! curvature a line cannot follow: squared terms, a bending slide) and, per other axis, how far
//! the compensation moves when that axis travels (cross-axis terms no per-axis form carries).

use truepos_model::{AxisKind, Machine};

use crate::ControlError;

/// The model at one thermal state: the error of every axis (µm, error = actual − nominal) at
/// the given axis positions (mm or degrees, one per machine axis).
pub type ErrorAt<'a> = dyn Fn(&[f64]) -> Result<Vec<f64>, String> + 'a;

/// Positions sampled along an axis' own travel for the fit.
pub const ALONG_SAMPLES: usize = 41;
/// Positions sampled along each other axis for the cross-axis figure.
pub const CROSS_SAMPLES: usize = 9;

/// Siemens 840D sl / 828D temperature compensation (Function Manual Extended Functions, K3
/// "Compensations", temperature compensation): the compensation value of an axis at position P
/// is ΔK = K0 + tanβ·(P − P0), with K0 in SD43900 `$SA_TEMP_COMP_ABS_VALUE` (mm), tanβ in SD43910
/// `$SA_TEMP_COMP_SLOPE` (mm per mm) and P0 in SD43920 `$SA_TEMP_COMP_REF_POSITION` (mm). The
/// same form is Beckhoff/ISG's linear temperature compensation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearForm {
    /// K0: the compensation at P0, mm.
    pub k0_mm: f64,
    /// tanβ: change of the compensation per mm of travel.
    pub tan_beta: f64,
    /// P0: the reference position, mm.
    pub p0_mm: f64,
}

impl LinearForm {
    /// The compensation the control applies at position `p_mm`, mm.
    pub fn at(&self, p_mm: f64) -> f64 {
        self.k0_mm + self.tan_beta * (p_mm - self.p0_mm)
    }
}

/// How far the compensation of an axis moves when another axis travels (the form's axis held
/// at each of its sampled positions): what no per-axis form can carry.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossAxis {
    /// The other axis' name.
    pub axis: String,
    /// Largest change of the compensation, µm.
    pub change_um: f64,
}

/// One axis' projection.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisProjection {
    /// Index of the axis in the machine.
    pub axis: usize,
    /// Its name.
    pub name: String,
    /// The line over the axis' travel (a constant form uses `k0_mm` with `tan_beta` 0).
    pub form: LinearForm,
    /// Largest |model − form| along the axis' own travel, the other axes where they are, µm.
    pub along_error_um: f64,
    /// Per other linear axis, the change the form cannot carry.
    pub cross_axis: Vec<CrossAxis>,
}

impl AxisProjection {
    /// The largest error of the form anywhere it was checked: along the travel plus the largest
    /// cross-axis change (a bound, as the two may add up at a corner).
    pub fn worst_um(&self) -> f64 {
        self.along_error_um
            + self
                .cross_axis
                .iter()
                .map(|c| c.change_um)
                .fold(0.0, f64::max)
    }
}

/// Which per-axis form to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Form {
    /// K0 + tanβ·(P − P0), P0 given per axis (default 0: machine zero).
    Linear,
    /// One constant per axis (HEIDENHAIN 9231's thermal offset).
    Constant,
}

fn positions_along(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
    (0..n).map(move |k| lo + (hi - lo) * k as f64 / (n - 1) as f64)
}

/// The compensation (−error) of axis `a` at `pos`, µm, or an error naming the positions.
fn compensation_um(f: &ErrorAt<'_>, a: usize, pos: &[f64]) -> Result<f64, ControlError> {
    let e = f(pos).map_err(|why| ControlError::Model(format!("at positions {pos:?}: {why}")))?;
    let v = e.get(a).copied().unwrap_or(0.0);
    if v.is_finite() {
        Ok(-v)
    } else {
        Err(ControlError::Model(format!(
            "at positions {pos:?}: a non-finite error for axis {a}"
        )))
    }
}

/// Projects the model onto `form` for every linear axis of the machine, at the thermal state
/// `f` was made for, with the axes at `now` (one position per axis). `p0_mm[a]` is axis a's
/// reference position P0 (ignored by [`Form::Constant`]).
pub fn project(
    machine: &Machine,
    f: &ErrorAt<'_>,
    now: &[f64],
    form: Form,
    p0_mm: &[f64],
) -> Result<Vec<AxisProjection>, ControlError> {
    if now.len() != machine.axes.len() || now.iter().any(|p| !p.is_finite()) {
        return Err(ControlError::Positions(format!(
            "expected {} finite axis positions, got {now:?}",
            machine.axes.len()
        )));
    }
    let linear: Vec<usize> = (0..machine.axes.len())
        .filter(|&a| machine.axes[a].kind == AxisKind::Linear)
        .collect();
    linear
        .iter()
        .map(|&a| {
            project_axis(
                machine,
                f,
                now,
                form,
                p0_mm.get(a).copied().unwrap_or(0.0),
                a,
                &linear,
            )
        })
        .collect()
}

fn project_axis(
    machine: &Machine,
    f: &ErrorAt<'_>,
    now: &[f64],
    form: Form,
    p0_mm: f64,
    a: usize,
    linear: &[usize],
) -> Result<AxisProjection, ControlError> {
    let axis = &machine.axes[a];
    let mut pos = now.to_vec();
    let mut samples = Vec::with_capacity(ALONG_SAMPLES);
    for p in positions_along(axis.travel_min, axis.travel_max, ALONG_SAMPLES) {
        pos[a] = p;
        samples.push((p, compensation_um(f, a, &pos)?));
    }
    let (c, b) = match form {
        Form::Linear => line(&samples),
        Form::Constant => (
            samples.iter().map(|s| s.1).sum::<f64>() / samples.len() as f64,
            0.0,
        ),
    };
    let fitted = LinearForm {
        k0_mm: (c + b * p0_mm) / 1000.0,
        tan_beta: b / 1000.0,
        p0_mm,
    };
    let along_error_um = samples
        .iter()
        .map(|&(p, v)| (v - 1000.0 * fitted.at(p)).abs())
        .fold(0.0, f64::max);
    let mut cross_axis = Vec::new();
    for &j in linear.iter().filter(|&&j| j != a) {
        let other = &machine.axes[j];
        let mut change = 0.0_f64;
        for p in positions_along(axis.travel_min, axis.travel_max, CROSS_SAMPLES) {
            let mut at = now.to_vec();
            at[a] = p;
            let here = compensation_um(f, a, &at)?;
            for q in positions_along(other.travel_min, other.travel_max, CROSS_SAMPLES) {
                at[j] = q;
                change = change.max((compensation_um(f, a, &at)? - here).abs());
            }
        }
        cross_axis.push(CrossAxis {
            axis: other.name.clone(),
            change_um: change,
        });
    }
    Ok(AxisProjection {
        axis: a,
        name: axis.name.clone(),
        form: fitted,
        along_error_um,
        cross_axis,
    })
}

/// Least-squares line v ≈ c + b·p through the samples: (c, b).
fn line(samples: &[(f64, f64)]) -> (f64, f64) {
    let n = samples.len() as f64;
    let mp = samples.iter().map(|s| s.0).sum::<f64>() / n;
    let mv = samples.iter().map(|s| s.1).sum::<f64>() / n;
    let spp: f64 = samples.iter().map(|s| (s.0 - mp).powi(2)).sum();
    let spv: f64 = samples.iter().map(|s| (s.0 - mp) * (s.1 - mv)).sum();
    let b = if spp > 0.0 { spv / spp } else { 0.0 };
    (mv - b * mp, b)
}
