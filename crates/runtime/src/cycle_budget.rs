//! Whether a model's evaluation fits the cycle, measured when it is loaded (start and hot
//! reload): a model of 200 000 terms is a valid file, yet at 1 kHz it overruns nearly every
//! cycle. The share of the period it may take leaves room for everything else the cycle does
//! (sources, validation, the envelope, the log hand-over) and for the host's jitter.

use std::time::{Duration, Instant};

use truepos_model::{CycleInput, Machine};

use crate::model_set::ModelEntry;

/// The share of the cycle period one model's evaluation may take.
pub const EVALUATION_SHARE: f64 = 0.25;

/// Evaluations timed; the median is compared, so one preempted step does not refuse a model.
const REPEATS: usize = 31;

/// The median time of one evaluation of `entry` (a copy: the running model's filters are not
/// stepped) at the middle of every axis' travel, 20 °C and operating inputs at 0, or an error
/// naming the model, the time and the budget when it is more than [`EVALUATION_SHARE`] of
/// `period_s`.
pub fn check(entry: &ModelEntry, machine: &Machine, period_s: f64) -> Result<Duration, String> {
    let positions: Vec<f64> = machine
        .axes
        .iter()
        .map(|a| 0.5 * (a.travel_min + a.travel_max))
        .collect();
    let temperatures = vec![20.0; machine.temperatures.len()];
    let operating = vec![0.0; machine.operating.len()];
    let input = CycleInput {
        temperatures_c: &temperatures,
        positions: &positions,
        operating: &operating,
    };
    let mut model = entry.model.clone();
    let mut times: Vec<Duration> = (0..REPEATS)
        .map(|_| {
            let start = Instant::now();
            let _ = std::hint::black_box(model.step(period_s, &input));
            start.elapsed()
        })
        .collect();
    times.sort();
    let median = times[REPEATS / 2];
    let budget = Duration::from_secs_f64(EVALUATION_SHARE * period_s.max(0.0));
    if median > budget {
        return Err(format!(
            "model `{}`: one evaluation takes {:.1} µs, more than {:.0} % of the {:.3} ms cycle \
             ({:.1} µs): it would overrun the cycle; a smaller model or a longer period",
            entry.name,
            median.as_secs_f64() * 1e6,
            EVALUATION_SHARE * 100.0,
            period_s * 1e3,
            budget.as_secs_f64() * 1e6
        ));
    }
    Ok(median)
}
