//! The walk over the recorded cycles that compares every settled, active one with the model: the
//! lag of the position-dependent terms (the timing argument's figure of merit), the update gaps
//! that say when the component and the servo thread were not in step, the offset rate over a
//! window, and how LinuxCNC's joints followed the commands.

use truepos_model::Model;

use super::record::Sample;
use super::report::CheckReport;
use super::targets::{expected_model, position_span_um};
use super::{CheckConfig, Recorded};

/// A change of a model input (K) between two servo cycles above which the cycle says nothing
/// about the lag of the position-dependent terms (the twin drifts by far less per millisecond).
const TEMPERATURE_STEP_K: f64 = 0.01;
/// Cycles after such a step that give no lag fraction either.
const AFTER_STEP_CYCLES: usize = 20;

/// What the cycles are judged against.
struct Judge<'a> {
    recorded: &'a Recorded<'a>,
    /// Operating values: the recording has none, so the model reads zeros.
    operating: Vec<f64>,
}

/// What the walk carries from one cycle to the next.
#[derive(Default)]
struct Walk {
    since_change: usize,
    /// Moving cycles so far in which the offsets sent did not change.
    gap: usize,
    /// Cycles so far, moving or not, in which the offsets sent did not change.
    sent_still: usize,
    /// Cycles left of the catching up after a gap.
    after_gap: usize,
    /// Cycles left after a step of a model input.
    after_step: usize,
    moving_cycles: usize,
    gap_cycles: usize,
    sum_sq: f64,
    diffs: usize,
}

/// Walks the cycles and fills in the report's comparison with the model, the gaps, the
/// switches, the rates and the joints.
pub(super) fn compare_cycles(recorded: &Recorded<'_>, report: &mut CheckReport) {
    let (machine, samples, config) = (recorded.machine, recorded.samples, recorded.config);
    let axes = machine.axes.len();
    let judge = Judge {
        recorded,
        operating: vec![0.0; machine.operating.len()],
    };
    let settle = (config.settle_s / config.period_s).round() as usize;
    let window = ((config.rate_window_s / config.period_s).round() as usize).max(1);
    let mut walk = Walk::default();
    for (k, s) in samples.iter().enumerate() {
        let prev = k.checked_sub(1).map(|p| &samples[p]);
        let moving = prev.is_some_and(|p| walk.follow(report, p, s, axes, config));
        if k >= window {
            let w = &samples[k - window];
            for a in 0..axes {
                let rate = (s.applied_mm[a] - w.applied_mm[a]).abs() * 1000.0
                    / (window as f64 * config.period_s);
                report.max_rate_um_per_s[a] = report.max_rate_um_per_s[a].max(rate);
            }
        }
        walk.since_change += 1;
        if s.holding() {
            report.holding_samples += 1;
        }
        for a in 0..axes {
            report.max_offset_um = report.max_offset_um.max(s.applied_mm[a].abs() * 1000.0);
        }
        if !s.active() || walk.since_change <= settle {
            continue;
        }
        walk.compare(&judge, report, (k, s), prev, moving);
    }
    let (delay, mismatch) = joint_delay(samples, axes);
    report.joint_delay_cycles = delay;
    report.joint_mismatch_mm = if samples.is_empty() { 0.0 } else { mismatch };
    if walk.moving_cycles > 0 {
        report.gap_fraction = walk.gap_cycles as f64 / walk.moving_cycles as f64;
    }
    if walk.diffs > 0 {
        report.rms_diff_um = (walk.sum_sq / walk.diffs as f64).sqrt();
    }
}

impl Walk {
    /// Follows the step from cycle `p` to `s`: update gaps, switches, changes of state, speed.
    /// Returns whether an axis moved.
    fn follow(
        &mut self,
        report: &mut CheckReport,
        p: &Sample,
        s: &Sample,
        axes: usize,
        config: &CheckConfig,
    ) -> bool {
        let moving = (0..axes).any(|a| s.nominal[a] != p.nominal[a]);
        // A change of state restarts the blend from the output last sent, which then stands
        // still for a cycle by design (a fault flickering every cycle freezes it): no gap.
        let new_state = p.status != s.status || p.model != s.model;
        self.gap = if moving && s.sent_um == p.sent_um && !new_state {
            self.gap + 1
        } else {
            0
        };
        report.longest_update_gap_cycles = report.longest_update_gap_cycles.max(self.gap);
        self.sent_still = if s.sent_um == p.sent_um {
            self.sent_still + 1
        } else {
            0
        };
        // In a gap of more than 2 cycles, and 20 cycles after it (LinuxCNC's external-offset
        // planner catches up under its acceleration limit: 5 µm at 300 mm/s² take 6 ms), the
        // offset lags for want of updates, not by the update rate.
        self.after_gap = if self.gap > 2 {
            20
        } else {
            self.after_gap.saturating_sub(1)
        };
        if moving {
            self.moving_cycles += 1;
            if self.gap > 2 || self.after_gap > 0 {
                self.gap_cycles += 1;
            }
        }
        report.model_switches += usize::from(p.model != s.model);
        report.axis_switches += usize::from(p.axis_paths != s.axis_paths);
        if p.select != s.select
            || p.status != s.status
            || p.model != s.model
            || p.axis_paths != s.axis_paths
        {
            self.since_change = 0;
        }
        for a in 0..axes {
            let feed = (s.nominal[a] - p.nominal[a]).abs() / config.period_s * 60.0;
            report.max_feed_mm_per_min = report.max_feed_mm_per_min.max(feed);
        }
        moving
    }

    /// Compares a settled, active cycle, the `k`th recorded, with the model the
    /// axis-combination rule selects, as replayed on the recorded cycles.
    fn compare(
        &mut self,
        judge: &Judge,
        report: &mut CheckReport,
        (k, s): (usize, &Sample),
        prev: Option<&Sample>,
        moving: bool,
    ) {
        let axes = judge.recorded.machine.axes.len();
        let expected = expected_model(
            judge.recorded.models,
            judge.recorded.limits,
            &s.axis_paths,
            s.select,
        );
        if expected.and_then(|i| i32::try_from(i).ok()) != Some(s.model) {
            report.wrong_model_cycles += 1;
        }
        let Some(i) = expected else {
            return;
        };
        let in_path = |a: usize| s.axis_paths.get(a) == Some(&1);
        for a in (0..axes).filter(|&a| !in_path(a)) {
            report.max_parked_offset_um = report
                .max_parked_offset_um
                .max(s.applied_mm[a].abs() * 1000.0);
        }
        let Some(error_um) = judge.recorded.replay.error_um(i, k) else {
            return;
        };
        report.compared += 1;
        let Some(model) = judge.recorded.models[i].model.as_static() else {
            self.compare_dynamic(judge, report, i, (k, s));
            return;
        };
        let span = position_span_um(model, judge.recorded.machine, s, &judge.operating);
        let temperature_step = self.temperature_step(model, prev, s);
        let in_step = !(moving && (self.gap > 2 || self.after_gap > 0)) && !temperature_step;
        report.in_step_moving_cycles += usize::from(moving && in_step);
        for (a, &span_a) in span.iter().enumerate().filter(|(a, _)| in_path(*a)) {
            let diff = s.applied_mm[a] * 1000.0 - (0.0 - error_um[a]);
            self.add_diff(report, diff);
            if span_a >= judge.recorded.config.min_span_um && !temperature_step {
                let fraction = diff.abs() / span_a;
                report.max_lag_fraction_all = report.max_lag_fraction_all.max(fraction);
                if in_step {
                    report.max_lag_fraction = report.max_lag_fraction.max(fraction);
                }
            }
        }
    }

    fn add_diff(&mut self, report: &mut CheckReport, diff: f64) {
        self.sum_sq += diff * diff;
        self.diffs += 1;
        report.max_diff_um = report.max_diff_um.max(diff.abs());
    }

    /// Compares a cycle with a fitted dynamic model `i`, replayed through the recorded cycles.
    /// It has no position-dependent terms, so no lag fraction: the applied offset must lie
    /// within the model's compensation over the cycles it may stem from — the same window as
    /// the output invariant's (LinuxCNC's pipeline, and the cycles the offset sent stood still)
    /// — but for `max_dynamic_excess_um` (see [`CheckConfig`]).
    fn compare_dynamic(
        &mut self,
        judge: &Judge,
        report: &mut CheckReport,
        i: usize,
        (k, s): (usize, &Sample),
    ) {
        report.dynamic_compared += 1;
        let window = judge.recorded.config.invariant_window_cycles + self.sent_still.min(1000);
        for a in (0..s.applied_mm.len()).filter(|&a| s.axis_paths.get(a) == Some(&1)) {
            let v = s.applied_mm[a] * 1000.0;
            let (lo, hi) = (k.saturating_sub(window)..=k)
                .filter_map(|j| judge.recorded.replay.error_um(i, j))
                .map(|e| 0.0 - e[a])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                    (lo.min(c), hi.max(c))
                });
            let now = judge
                .recorded
                .replay
                .error_um(i, k)
                .map_or(f64::NAN, |e| 0.0 - e[a]);
            self.add_diff(report, v - now);
            let excess = (lo - v).max(v - hi).max(0.0);
            report.max_dynamic_excess_um = report.max_dynamic_excess_um.max(excess);
        }
    }

    /// Whether a model input stepped in this cycle or within [`AFTER_STEP_CYCLES`] before.
    ///
    /// The lag judged here is that of the position-dependent terms. A temperature that
    /// stepped since the previous cycle (a quantisation flicker between 0.1 K levels) also
    /// reaches the axis one update later, which is not that lag: such cycles are compared
    /// with the model but give no lag fraction.
    fn temperature_step(&mut self, model: &Model, prev: Option<&Sample>, s: &Sample) -> bool {
        let stepped = prev.is_some_and(|p| {
            model.used_sensors().iter().any(|&c| {
                let d = (s.temperatures_c[c] - p.temperatures_c[c]).abs();
                d.is_nan() || d > TEMPERATURE_STEP_K
            })
        });
        // The envelope's rate limit may hold the output back for a few cycles after a flicker.
        self.after_step = if stepped {
            AFTER_STEP_CYCLES
        } else {
            self.after_step.saturating_sub(1)
        };
        stepped || self.after_step > 0
    }
}

/// The pipeline delay between axis commands and joint feedback that fits best, cycles, and
/// the largest |joint(k) − (nominal + applied offset)(k − delay)| at it, mm: LinuxCNC's joints
/// follow the axis commands through its interpolator a few cycles later.
fn joint_delay(samples: &[Sample], axes: usize) -> (usize, f64) {
    (0..10)
        .map(|d| {
            let worst = samples
                .iter()
                .skip(d)
                .zip(samples)
                .flat_map(|(s, p)| {
                    (0..axes).map(move |a| (s.joint[a] - p.nominal[a] - p.applied_mm[a]).abs())
                })
                .fold(0.0f64, f64::max);
            (d, worst)
        })
        .fold(
            (0, f64::INFINITY),
            |best, x| if x.1 < best.1 { x } else { best },
        )
}
