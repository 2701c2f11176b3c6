//! Probe measurements as an input of the service (probing re-identification: the working
//! model's parameters are re-estimated from probe measurements taken during operation).
//!
//! A source that sees a probe event (the HAL component on a rising edge of
//! `truepos.probe.trigger`) puts a [`ProbeInput`] in the frame: where the probe touched and the
//! measured error per axis. The cycle checks it ([`check`]) and queues one [`ProbeRecord`] with
//! the inputs of that cycle — temperatures, axis positions, operating state, the model in
//! effect per path and its predicted error at the probed position — accepted or rejected with
//! the reason; the logger writes every record to the `probes` table (docs/formats.md). A
//! rejected event is kept for the record and never used by `truepos reidentify`.

use truepos_model::{Axis, MAX_AXES};

use crate::events::Reason;
use crate::output::CompensationState;
use crate::service::{MAX_LOG_OPERATING, MAX_LOG_TEMPERATURES, MAX_PATHS};

/// Largest measured error a probe event may report (µm): a thermal or geometric error of a
/// machine tool is tens of µm; a millimetre is a missed touch, a wrong unit or a broken stylus.
pub const MAX_PROBE_DEVIATION_UM: f64 = 1000.0;
/// How far beyond an axis' travel a probed position may lie (mm), for a touch at the end of
/// travel measured with a small overshoot.
pub const PROBE_TRAVEL_MARGIN_MM: f64 = 1.0;

/// One probe event as a source delivers it, per machine axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeInput {
    /// Where the probe touched (mm or degrees).
    pub position_mm: [f64; MAX_AXES],
    /// Measured error (actual − nominal, µm) of the axes that were measured.
    pub deviation_um: [f64; MAX_AXES],
    /// Which axes were measured.
    pub measured: [bool; MAX_AXES],
}

impl ProbeInput {
    /// An event with nothing measured yet.
    pub const EMPTY: Self = Self {
        position_mm: [f64::NAN; MAX_AXES],
        deviation_um: [f64::NAN; MAX_AXES],
        measured: [false; MAX_AXES],
    };
}

/// One probe event as the log keeps it (fixed size, so queuing it allocates nothing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeRecord {
    /// Service time in s.
    pub time_s: f64,
    /// Why it was rejected; empty for an accepted event.
    pub rejected: Reason,
    /// The event as delivered.
    pub probe: ProbeInput,
    /// Error per axis that the model in effect for the axis' path predicts at the probed
    /// position with this cycle's inputs (µm); NaN where no model is in effect.
    pub predicted_um: [f64; MAX_AXES],
    /// Compensation state of the cycle.
    pub state: CompensationState,
    /// Model per path (−1: none).
    pub model_per_path: [i32; MAX_PATHS],
    /// Axis positions of the cycle.
    pub positions: [f64; MAX_AXES],
    /// Temperatures of the cycle (first [`MAX_LOG_TEMPERATURES`] channels, lagged ones
    /// computed).
    pub temperatures_c: [f64; MAX_LOG_TEMPERATURES],
    /// Operating state of the cycle (first [`MAX_LOG_OPERATING`] channels).
    pub operating: [f64; MAX_LOG_OPERATING],
}

/// Checks a probe event against the axes' travel: at least one axis measured; every probed
/// position finite and within travel (± [`PROBE_TRAVEL_MARGIN_MM`]), since the model reads every
/// axis' position; every measured error finite and within ± [`MAX_PROBE_DEVIATION_UM`]. Returns
/// the reason of the first failure. Allocates nothing.
pub fn check(probe: &ProbeInput, axes: &[Axis]) -> Result<(), Reason> {
    let name = |a: usize| axes[a].name.as_str();
    if !probe.measured.iter().take(axes.len()).any(|&m| m) {
        return Err(Reason::new("no axis measured"));
    }
    for (a, t) in axes.iter().enumerate().take(MAX_AXES) {
        let p = probe.position_mm[a];
        if !p.is_finite()
            || p < t.travel_min - PROBE_TRAVEL_MARGIN_MM
            || p > t.travel_max + PROBE_TRAVEL_MARGIN_MM
        {
            return Err(reason(format_args!(
                "probed position of {} is {p}, outside its travel [{}, {}]",
                name(a),
                t.travel_min,
                t.travel_max
            )));
        }
        let d = probe.deviation_um[a];
        if probe.measured[a] && !(d.is_finite() && d.abs() <= MAX_PROBE_DEVIATION_UM) {
            return Err(reason(format_args!(
                "measured error of {} is {d} µm, expected a finite number within ±{MAX_PROBE_DEVIATION_UM}",
                name(a)
            )));
        }
    }
    Ok(())
}

/// Replays recorded probe events as a source (for controls without the HAL pin group, and for
/// testing): an event is delivered in the cycle whose service time reaches its run time
/// (relative to `start_s`, the run's first row: the service's clock is the run's, as for
/// [`crate::replay::ReplaySource`]), one event per cycle so that none is lost when two fall
/// into one cycle.
pub struct ProbeReplay {
    name: String,
    events: Vec<(f64, ProbeInput)>,
    start_s: f64,
    next: usize,
}

impl ProbeReplay {
    /// Events as (run time in s, event), in time order.
    pub fn new(name: impl Into<String>, events: Vec<(f64, ProbeInput)>, start_s: f64) -> Self {
        Self {
            name: name.into(),
            events,
            start_s,
            next: 0,
        }
    }
}

impl crate::Source for ProbeReplay {
    fn name(&self) -> &str {
        &self.name
    }

    fn read(&mut self, frame: &mut crate::Frame) -> Result<(), crate::LinkError> {
        let run_time = self.start_s + frame.time_s;
        if let Some((t, p)) = self.events.get(self.next) {
            if *t <= run_time {
                frame.probe = Some(*p);
                self.next += 1;
            }
        }
        Ok(())
    }
}

/// A reason formatted into a fixed buffer, so that a rejection allocates nothing.
pub(crate) fn reason(args: std::fmt::Arguments<'_>) -> Reason {
    let mut buf = FixedText::default();
    let _ = std::fmt::write(&mut buf, args);
    Reason::new(buf.as_str())
}

/// A stack buffer of [`crate::events::REASON_BYTES`] bytes that formatting writes into; text
/// beyond it is cut on a character boundary.
struct FixedText {
    bytes: [u8; crate::events::REASON_BYTES],
    len: usize,
}

impl Default for FixedText {
    fn default() -> Self {
        Self {
            bytes: [0; crate::events::REASON_BYTES],
            len: 0,
        }
    }
}

impl FixedText {
    fn as_str(&self) -> &str {
        std::str::from_utf8(&self.bytes[..self.len]).unwrap_or_default()
    }
}

impl std::fmt::Write for FixedText {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let room = self.bytes.len() - self.len;
        let mut take = s.len().min(room);
        while !s.is_char_boundary(take) {
            take -= 1;
        }
        self.bytes[self.len..self.len + take].copy_from_slice(&s.as_bytes()[..take]);
        self.len += take;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe() -> ProbeInput {
        let mut p = ProbeInput::EMPTY;
        p.position_mm[..3].copy_from_slice(&[100.0, 200.0, 50.0]);
        p.deviation_um[2] = 12.5;
        p.measured[2] = true;
        p
    }

    fn axes() -> Vec<Axis> {
        ["X", "Y", "Z"]
            .map(|n| Axis {
                name: n.into(),
                kind: truepos_model::AxisKind::Linear,
                travel_min: 0.0,
                travel_max: 800.0,
                carried_by: None,
                carriage: truepos_model::Carriage::Cantilever,
            })
            .to_vec()
    }

    #[test]
    fn a_good_event_passes_and_bad_ones_say_why() {
        let axes = axes();
        assert_eq!(check(&probe(), &axes), Ok(()));
        let mut nan = probe();
        nan.deviation_um[2] = f64::NAN;
        let why = check(&nan, &axes).unwrap_err();
        assert!(why.contains("measured error of Z is NaN"), "{why}");
        let mut absurd = probe();
        absurd.deviation_um[2] = 5e4;
        assert!(check(&absurd, &axes).unwrap_err().contains("±1000"));
        let mut outside = probe();
        outside.position_mm[0] = 900.0;
        let why = check(&outside, &axes).unwrap_err();
        assert!(why.contains("probed position of X is 900"), "{why}");
        let mut none = probe();
        none.measured = [false; MAX_AXES];
        assert_eq!(
            check(&none, &axes).unwrap_err().as_str(),
            "no axis measured"
        );
        // An axis not measured may carry any error value.
        let mut unmeasured = probe();
        unmeasured.deviation_um[0] = f64::NAN;
        assert_eq!(check(&unmeasured, &axes), Ok(()));
    }

    #[test]
    fn checking_allocates_nothing() {
        let mut bad = probe();
        bad.deviation_um[2] = f64::INFINITY;
        let axes = axes();
        let counted = allocation_counter::measure(|| {
            for _ in 0..100 {
                let _ = check(&bad, &axes);
                let _ = check(&probe(), &axes);
            }
        });
        assert_eq!(counted.count_total, 0);
    }
}
