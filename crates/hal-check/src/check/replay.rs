//! What every model of the set gave on every recorded cycle, as the component computes it: each
//! model stepped through the recorded cycles in order, through the one door the component uses
//! ([`CompensationModel::step_guarded`]: a model with a training envelope has its inputs clamped to
//! it and its output capped, as on the machine). For a position-dependent model that is an
//! evaluation of the cycle's temperatures and nominal positions; a fitted dynamic model's filters
//! advance by the real length of each servo cycle, so its output carries the history the
//! component's carries.
//!
//! The component steps its dynamic models every one of its own cycles from its first good one;
//! the replay starts them at the first recorded cycle. The two agree when the model's inputs held
//! still between the component's start and the recording's (the end-to-end test's temperatures
//! do: the samplers start once the component is active, and the twin plays only after that),
//! because every filter then sits at its input and every rise is zero. When the set holds a
//! fitted dynamic model, a recording whose first cycle is not active fails the check: it may
//! hold pins not yet connected (0.0, a valid ambient temperature), from which the replay would
//! take its reference. Like the component's validator, the replay steps no model on a
//! temperature outside its channel's valid range or not finite (the filters wait, the cycle has
//! no value); the validator's rate, staleness and stuck checks are not replayed, so a dynamic
//! model under test must read sensors the test does not fault that way.

use truepos_model::{CompensationModel, CycleInput, Machine};
use truepos_runtime::model_set::ModelEntry;

use super::record::Sample;

/// The predicted error (µm) of every model, recorded cycle and axis.
#[derive(Debug, Clone)]
pub struct Replay {
    axes: usize,
    samples: usize,
    /// Model-major, then cycle, then axis; NaN where the model gave nothing (its results are
    /// never NaN).
    errors_um: Vec<f64>,
}

impl Replay {
    /// Steps every model of the set through the samples in order.
    pub fn new(
        machine: &Machine,
        models: &[ModelEntry],
        samples: &[Sample],
        period_s: f64,
    ) -> Self {
        let axes = machine.axes.len();
        let intervals = servo_intervals_s(samples, period_s);
        // The recording has no operating values: the models read zeros (unconnected HAL pins).
        let operating = vec![0.0; machine.operating.len()];
        let mut errors_um = Vec::with_capacity(models.len() * samples.len() * axes);
        let mut masked = Vec::new();
        let mut guarded = (Vec::new(), Vec::new());
        for entry in models {
            let mut model: CompensationModel = entry.model.clone();
            model.reset();
            let mut time_s = 0.0;
            let mut last_good_s: Option<f64> = None;
            for (k, s) in samples.iter().enumerate() {
                if k > 0 {
                    time_s += intervals[k];
                }
                masked.clear();
                masked.extend(s.temperatures_c.iter().enumerate().map(|(c, &v)| {
                    let ok = machine
                        .temperatures
                        .get(c)
                        .is_some_and(|t| (t.valid_min_c..=t.valid_max_c).contains(&v));
                    if ok {
                        v
                    } else {
                        f64::NAN
                    }
                }));
                let input = CycleInput {
                    temperatures_c: &masked,
                    positions: &s.nominal,
                    operating: &operating,
                };
                let dt = last_good_s.map_or(0.0, |l| time_s - l);
                match model.step_guarded(dt, &input, (&mut guarded.0, &mut guarded.1)) {
                    Ok((e, _)) => {
                        errors_um.extend_from_slice(&e[..axes]);
                        last_good_s = Some(time_s);
                    }
                    Err(_) => errors_um.extend(std::iter::repeat_n(f64::NAN, axes)),
                }
            }
        }
        Self {
            axes,
            samples: samples.len(),
            errors_um,
        }
    }

    /// The predicted error of every axis by model `model` in cycle `k`, µm; `None` where it gave
    /// nothing (a bad input).
    pub fn error_um(&self, model: usize, k: usize) -> Option<&[f64]> {
        let start = (model * self.samples + k) * self.axes;
        let e = self.errors_um.get(start..start + self.axes)?;
        e.iter().all(|v| v.is_finite()).then_some(e)
    }
}

/// The real length of every servo cycle, s: `motion.servo.last-period` scaled so that its
/// median is the nominal period (its clock's rate is unknown); the nominal period where the
/// column reads nothing usable.
pub(super) fn servo_intervals_s(samples: &[Sample], period_s: f64) -> Vec<f64> {
    let mut clocks: Vec<f64> = samples
        .iter()
        .map(|s| s.servo_clocks)
        .filter(|c| c.is_finite() && *c > 0.0)
        .collect();
    if clocks.is_empty() {
        return vec![period_s; samples.len()];
    }
    clocks.sort_by(f64::total_cmp);
    let median = clocks[clocks.len() / 2];
    samples
        .iter()
        .map(|s| {
            if s.servo_clocks.is_finite() && s.servo_clocks > 0.0 {
                s.servo_clocks / median * period_s
            } else {
                period_s
            }
        })
        .collect()
}
