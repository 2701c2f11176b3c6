//! What the sink writes: the running compensation as the control's per-axis line
//! ΔK = K0 + tanβ·(P − P0), kept inside the envelope and the control's own rate limit.
//!
//! A line over an axis' travel is held here by its values at the two ends of the travel (µm),
//! because both limits are simple there: the magnitude of a line is largest at an end, and a
//! step of the line anywhere on the travel is at most the larger step of its ends. K0 and tanβ
//! are computed from the ends only when written.

use truepos_controls::projection::{project, Form};
use truepos_model::{CycleInput, Machine, Model};
use truepos_runtime::CompensationState;

/// A line over one axis' travel by its compensation at the travel's ends, µm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ends {
    /// At `travel_min`.
    pub lo_um: f64,
    /// At `travel_max`.
    pub hi_um: f64,
}

/// One axis' travel and limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Travel, mm.
    pub travel_min: f64,
    /// Travel, mm.
    pub travel_max: f64,
    /// The envelope's largest compensation, µm.
    pub max_offset_um: f64,
    /// The control's rate limit, µm/s.
    pub max_rate_um_per_s: f64,
    /// P0, mm.
    pub p0_mm: f64,
}

/// The three values the control takes (SINUMERIK's units: mm and mm per mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Written {
    /// K0, mm.
    pub k0_mm: f64,
    /// tanβ.
    pub tan_beta: f64,
    /// P0, mm.
    pub p0_mm: f64,
}

impl Ends {
    /// A constant.
    pub fn constant(v_um: f64) -> Self {
        Self {
            lo_um: v_um,
            hi_um: v_um,
        }
    }

    /// The compensation at `p` mm, µm.
    pub fn at(&self, lim: &AxisLimits, p: f64) -> f64 {
        let span = lim.travel_max - lim.travel_min;
        if span <= 0.0 {
            return self.lo_um;
        }
        self.lo_um + (self.hi_um - self.lo_um) * (p - lim.travel_min) / span
    }

    /// The slope, µm per mm.
    pub fn slope(&self, lim: &AxisLimits) -> f64 {
        let span = lim.travel_max - lim.travel_min;
        if span <= 0.0 {
            0.0
        } else {
            (self.hi_um - self.lo_um) / span
        }
    }

    /// K0 (at P0), tanβ and P0 in the control's units.
    pub fn written(&self, lim: &AxisLimits) -> Written {
        Written {
            k0_mm: self.at(lim, lim.p0_mm) / 1000.0,
            tan_beta: self.slope(lim) / 1000.0,
            p0_mm: lim.p0_mm,
        }
    }

    /// The line the control applies from the values it holds.
    pub fn from_written(w: &Written, lim: &AxisLimits) -> Self {
        let at = |p: f64| 1000.0 * (w.k0_mm + w.tan_beta * (p - w.p0_mm));
        Self {
            lo_um: at(lim.travel_min),
            hi_um: at(lim.travel_max),
        }
    }

    /// Within the envelope (|compensation| ≤ `max_offset_um` on the whole travel) and at most
    /// `max_rate_um_per_s × dt_s` away from `applied` anywhere on the travel. Non-finite
    /// targets keep `applied`.
    pub fn limited(&self, applied: &Ends, lim: &AxisLimits, dt_s: f64) -> Self {
        let step = lim.max_rate_um_per_s * dt_s.max(0.0);
        let one = |want: f64, was: f64| {
            if !want.is_finite() {
                return was;
            }
            let want = want.clamp(-lim.max_offset_um, lim.max_offset_um);
            want.clamp(was - step, was + step)
        };
        Self {
            lo_um: one(self.lo_um, applied.lo_um),
            hi_um: one(self.hi_um, applied.hi_um),
        }
    }
}

/// One cycle's view the sink projects from.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Service time, s.
    pub time_s: f64,
    /// The service's state.
    pub state: CompensationState,
    /// The service's output per axis (after its envelope), µm.
    pub offsets_um: Vec<f64>,
    /// Axis positions, mm.
    pub positions: Vec<f64>,
    /// Temperatures (lagged channels computed), °C.
    pub temperatures_c: Vec<f64>,
    /// Operating state.
    pub operating: Vec<f64>,
}

/// The line each of `axes` should carry now: while the service is active, the model's
/// least-squares line along the axis' travel (the other axes where they are) at the cycle's
/// temperatures; otherwise — holding, ramping to zero, no model — or without a static model
/// (a fitted dynamic model's form is its K0), or when the model cannot be evaluated at these
/// inputs, the constant the service outputs.
///
/// Not the service's output moved onto the line: the output is rate-limited per cycle, and a
/// position source that updates every 100 ms makes it step and lag behind the model for a few
/// cycles after each update, which a line that carries the position itself must not copy.
/// Smooth transitions on the control are the sink's own rate limit's job.
pub fn target(
    machine: &Machine,
    model: Option<&Model>,
    snap: &Snapshot,
    axes: &[(usize, AxisLimits)],
) -> Vec<Ends> {
    let constant = || {
        axes.iter()
            .map(|&(a, _)| Ends::constant(snap.offsets_um.get(a).copied().unwrap_or(0.0)))
            .collect()
    };
    let Some(model) = model else {
        return constant();
    };
    if snap.state != CompensationState::Active || snap.positions.iter().any(|p| !p.is_finite()) {
        return constant();
    }
    let error_at = |p: &[f64]| -> Result<Vec<f64>, String> {
        model
            .evaluate(&CycleInput {
                temperatures_c: &snap.temperatures_c,
                positions: p,
                operating: &snap.operating,
            })
            .map(|c| c.error_um().to_vec())
            .map_err(|e| e.to_string())
    };
    let Ok(proj) = project(machine, &error_at, &snap.positions, Form::Linear, &[]) else {
        return constant();
    };
    axes.iter()
        .map(|&(a, lim)| {
            let Some(p) = proj.iter().find(|p| p.axis == a) else {
                return Ends::constant(snap.offsets_um[a]);
            };
            Ends {
                lo_um: 1000.0 * p.form.at(lim.travel_min),
                hi_um: 1000.0 * p.form.at(lim.travel_max),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn lim() -> AxisLimits {
        AxisLimits {
            travel_min: -100.0,
            travel_max: 700.0,
            max_offset_um: 50.0,
            max_rate_um_per_s: 10.0,
            p0_mm: 200.0,
        }
    }

    #[test]
    fn written_values_give_back_the_line() {
        let l = lim();
        let e = Ends {
            lo_um: -12.0,
            hi_um: 20.0,
        };
        let w = e.written(&l);
        assert!((w.tan_beta - 32.0 / 800.0 / 1000.0).abs() < 1e-15);
        assert!((w.k0_mm * 1000.0 - e.at(&l, 200.0)).abs() < 1e-12);
        let back = Ends::from_written(&w, &l);
        assert!((back.lo_um - e.lo_um).abs() < 1e-9 && (back.hi_um - e.hi_um).abs() < 1e-9);
    }

    proptest! {
        /// Anywhere on the travel the limited line is within the envelope (given the applied
        /// one was) and moved at most rate × dt from the applied one.
        #[test]
        fn limits_hold_on_the_whole_travel(
            lo in -1e3f64..1e3, hi in -1e3f64..1e3,
            alo in -50f64..50.0, ahi in -50f64..50.0,
            dt in 0.0f64..1.0, p in -100f64..700.0,
        ) {
            let l = lim();
            let applied = Ends { lo_um: alo, hi_um: ahi };
            let out = Ends { lo_um: lo, hi_um: hi }.limited(&applied, &l, dt);
            prop_assert!(out.at(&l, p).abs() <= l.max_offset_um + 1e-9);
            prop_assert!((out.at(&l, p) - applied.at(&l, p)).abs() <= l.max_rate_um_per_s * dt + 1e-9);
        }
    }

    #[test]
    fn a_nan_target_keeps_the_applied_line() {
        let l = lim();
        let applied = Ends::constant(3.0);
        let out = Ends::constant(f64::NAN).limited(&applied, &l, 0.1);
        assert_eq!(out, applied);
    }
}
