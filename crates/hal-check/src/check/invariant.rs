//! The output invariant (ARCHITECTURE.md) judged on the offsets LinuxCNC applied.

use truepos_hal::eoffset::RESOLUTION_UM;
use truepos_model::Machine;
use truepos_runtime::model_set::ModelEntry;
use truepos_runtime::AxisConfig;

use super::record::Sample;
use super::replay::servo_intervals_s;
use super::report::CheckReport;
use super::targets::targets_um;
use super::{CheckConfig, Recorded};

/// The output invariant (ARCHITECTURE.md) judged on the offsets LinuxCNC applied.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InvariantReport {
    /// Cycles whose applied offset was not finite.
    pub nonfinite_cycles: usize,
    /// Largest |applied offset| per axis, µm (the envelope: `max_offset_um`).
    pub max_abs_um: Vec<f64>,
    /// Largest change of the applied offset from one servo cycle to the next, per axis, µm.
    pub max_step_um: Vec<f64>,
    /// Largest ratio of a cycle's change to what the envelope's rate allows over the real time
    /// since the offset could last have moved (see [`output_invariant`]), per axis.
    pub max_step_ratio: Vec<f64>,
    /// Largest distance of the applied offset outside the values it may take (between the
    /// output at the latest change of state and the current target, over the pipeline window),
    /// per axis, µm.
    pub max_bracket_excess_um: Vec<f64>,
    /// Changes of state (status, model, axis configuration, model-select) seen.
    pub state_changes: usize,
    /// Cycles (any axis) where the model could not be evaluated on the recorded temperatures
    /// (an injected NaN) and the previous target was kept.
    pub target_kept_cycles: usize,
}

/// Judges the output invariant on the applied offsets (`axis.L.eoffset`), every cycle and axis:
///
/// - finite, and within `max_offset_um` (plus two counts of quantisation);
/// - the change from the previous cycle is at most `max_rate_um_per_s` × (the real time since
///   the offset could last have moved + one period of the component's own clock) + two counts.
///   That time spans the cycles in which the applied offset stood still (the component held up:
///   its next step covers the whole time) and the `pipeline_cycles` before them (LinuxCNC
///   applies a request a cycle or more after the component wrote it), each at its real length
///   from `motion.servo.last-period` (the servo thread held up: the component went on);
/// - the offset lies between the output at the latest change of state and the current target
///   (see [`targets_um`]; in a hold, the value at the change ramped linearly to zero over
///   `hold_ramp_s` of real time): a *bracket*. The value at the change is what the component sent
///   just before it, projected onto the bracket then allowed — never the output itself, so an
///   output running away cannot carry its bracket along. Since LinuxCNC applies what the
///   component computed from positions and temperatures read a few cycles before, the applied
///   offset is compared with the union of the brackets over the last `invariant_window_cycles`
///   cycles, and over the cycles in which the offset sent stood still before them.
///
/// A target that cannot be evaluated (the recorded temperatures hold the injected NaN, which
/// the component may not have read) keeps the previous one.
pub fn output_invariant(
    machine: &Machine,
    models: &[ModelEntry],
    limits: &[AxisConfig],
    samples: &[Sample],
    config: &CheckConfig,
) -> InvariantReport {
    output_invariant_with(&Recorded::new(machine, models, limits, samples, config))
}

/// [`output_invariant`] on the models' values already replayed.
pub(super) fn output_invariant_with(recorded: &Recorded<'_>) -> InvariantReport {
    let Recorded {
        machine,
        models,
        replay,
        limits,
        samples,
        config,
    } = recorded;
    let axes = machine.axes.len();
    let count = RESOLUTION_UM;
    let intervals = servo_intervals_s(samples, config.period_s);
    let mut r = InvariantReport {
        max_abs_um: vec![0.0; axes],
        max_step_um: vec![0.0; axes],
        max_step_ratio: vec![0.0; axes],
        max_bracket_excess_um: vec![0.0; axes],
        ..InvariantReport::default()
    };
    // Per cycle and axis: the bracket (lo, hi), µm.
    let mut brackets: Vec<Vec<(f64, f64)>> = Vec::with_capacity(samples.len());
    let mut from = vec![0.0f64; axes];
    let mut target = vec![0.0f64; axes];
    // Cycles in which the sent offsets / each applied offset stood still, up to this one.
    let mut since_change_s = 0.0f64;
    let mut sent_still = 0usize;
    let mut applied_still = vec![0usize; axes];
    // The union of the brackets over the window of the previous cycle, per axis.
    let mut allowed_before: Vec<Option<(f64, f64)>> = vec![None; axes];
    for (k, s) in samples.iter().enumerate() {
        let prev = k.checked_sub(1).map(|p| &samples[p]);
        let changed = prev.is_none_or(|p| {
            p.status != s.status
                || p.model != s.model
                || p.select != s.select
                || p.axis_paths != s.axis_paths
        });
        let targets = targets_um(machine, models, replay, limits, s, k);
        r.target_kept_cycles += usize::from(targets.iter().any(Option::is_none));
        for a in 0..axes {
            if let Some(t) = targets[a] {
                target[a] = t;
            } else if k == 0 {
                target[a] = s.sent_um[a];
            }
        }
        since_change_s += intervals[k];
        if changed {
            since_change_s = 0.0;
            r.state_changes += usize::from(k > 0);
            for a in 0..axes {
                from[a] = match (prev, allowed_before[a]) {
                    (Some(p), Some((lo, hi))) if p.sent_um[a].is_finite() => {
                        p.sent_um[a].clamp(lo, hi)
                    }
                    (Some(_), Some((lo, hi))) => (lo + hi) / 2.0,
                    _ => s.sent_um[a],
                };
            }
        }
        if s.holding() {
            // The held value ramps to zero; one period more, for the two clocks.
            let left = (1.0 - (since_change_s + config.period_s) / config.hold_ramp_s).max(0.0);
            for a in (0..axes).filter(|&a| s.axis_paths.get(a) == Some(&1)) {
                target[a] = from[a] * left;
            }
        }
        brackets.push(
            (0..axes)
                .map(|a| (from[a].min(target[a]), from[a].max(target[a])))
                .collect(),
        );
        if let Some(p) = prev {
            sent_still = if p.sent_um == s.sent_um {
                sent_still + 1
            } else {
                0
            };
        }
        let first = k.saturating_sub(config.invariant_window_cycles + sent_still.min(1000));
        for a in 0..axes {
            let v = s.applied_mm[a] * 1000.0;
            if !v.is_finite() {
                r.nonfinite_cycles += 1;
                continue;
            }
            r.max_abs_um[a] = r.max_abs_um[a].max(v.abs());
            let (lo, hi) = brackets[first..=k]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| {
                    (lo.min(b[a].0), hi.max(b[a].1))
                });
            allowed_before[a] = Some((lo, hi));
            let excess = (lo - v).max(v - hi).max(0.0);
            r.max_bracket_excess_um[a] = r.max_bracket_excess_um[a].max(excess);
            let Some(p) = prev else { continue };
            let step = (v - p.applied_mm[a] * 1000.0).abs();
            let since = k.saturating_sub(applied_still[a] + config.pipeline_cycles);
            // After a stall LinuxCNC's servo thread catches up with short periods while the
            // component keeps its own pace, one period per cycle: the longer of the two counts.
            let servo_s: f64 = intervals[since + 1..=k].iter().sum();
            let time = servo_s.max((k - since) as f64 * config.period_s);
            let allowed = limits[a].max_rate_um_per_s * (time + config.period_s) + 2.0 * count;
            r.max_step_um[a] = r.max_step_um[a].max(step);
            r.max_step_ratio[a] = r.max_step_ratio[a].max(step / allowed);
            applied_still[a] = if step == 0.0 { applied_still[a] + 1 } else { 0 };
        }
    }
    r
}

/// Adds the failures of the output invariant to the report.
pub(super) fn invariant_failures(
    machine: &Machine,
    limits: &[AxisConfig],
    config: &CheckConfig,
    report: &mut CheckReport,
) {
    let inv = &report.invariant;
    let mut failures = Vec::new();
    if inv.nonfinite_cycles > 0 {
        failures.push(format!(
            "the applied offset was not finite in {} cycle(s)",
            inv.nonfinite_cycles
        ));
    }
    for (a, axis) in machine.axes.iter().enumerate() {
        let name = &axis.name;
        let max = limits[a].max_offset_um + 2.0 * RESOLUTION_UM;
        if inv.max_abs_um[a] > max {
            failures.push(format!(
                "axis {name}: applied offset {:.3} µm exceeds the envelope's {} µm",
                inv.max_abs_um[a], limits[a].max_offset_um
            ));
        }
        if inv.max_step_ratio[a] > 1.0 {
            failures.push(format!(
                "axis {name}: the applied offset changed in one servo cycle by {:.2} × what the \
                 envelope's {} µm/s allows (largest step {:.3} µm)",
                inv.max_step_ratio[a], limits[a].max_rate_um_per_s, inv.max_step_um[a]
            ));
        }
        if inv.max_bracket_excess_um[a] > config.max_bracket_excess_um {
            failures.push(format!(
                "axis {name}: the applied offset left the range between its value at the latest \
                 change of state and its target (model, held value ramping to zero, or zero) by \
                 {:.3} µm (allowed {} µm)",
                inv.max_bracket_excess_um[a], config.max_bracket_excess_um
            ));
        }
    }
    report.failures.extend(failures);
}
