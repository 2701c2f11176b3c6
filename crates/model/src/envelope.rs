//! Where a model was trained, and the guard that keeps it there.
//!
//! A fitted model is a regression: inside the range of its training inputs it interpolates,
//! beyond it it extrapolates, and a sensor that rises three times as far as it ever did in
//! training drives the prediction several times beyond anything seen (a held-back machine: one
//! sensor 38 K up where training saw 12 K, 161 µm RMS against 54 µm uncompensated). The
//! training envelope stores, per input the model reads, the range it saw in training and, per
//! axis, the largest |prediction| on the training rows. The guard
//! ([`TrainingEnvelope::clamp`], [`TrainingEnvelope::cap`]):
//!
//! - clamps every input to its training range widened by a margin — temperatures by
//!   [`TEMPERATURE_MARGIN`] of the range but at least [`TEMPERATURE_MARGIN_MIN_K`], operating
//!   inputs by [`OPERATING_MARGIN`] of the range — so the model is never evaluated far outside
//!   what it saw (the margin lets a warmer day than any in training still count), and says
//!   which input was beyond and by how much;
//! - caps each axis' predicted error at [`OUTPUT_FACTOR`] × the largest |prediction| on the
//!   training rows.
//!
//! Clamping the inputs rather than holding the output keeps the compensation continuous: the
//! model goes on following every input still inside, and the clamped input contributes what it
//! did at the edge of its range.
//!
//! ```
//! use truepos_model::envelope::TrainingEnvelope;
//! use truepos_model::CycleInput;
//! let env = TrainingEnvelope {
//!     temperatures: vec![Some((20.0, 32.0))],
//!     operating: vec![],
//!     max_abs_um: vec![Some(40.0)],
//! };
//! let (mut t, mut o) = (vec![0.0; 1], vec![]);
//! let input = CycleInput { temperatures_c: &[58.0], positions: &[], operating: &[] };
//! let beyond = env.clamp(&input, &mut t, &mut o).unwrap();
//! assert_eq!(t[0], 35.0); // 32 K + 25 % of the 12 K range
//! assert_eq!(beyond.value, 58.0);
//! let mut error = [95.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
//! assert!(env.cap(&mut error));
//! assert_eq!(error[0], 60.0);
//! ```

use alloc::vec::Vec;

use crate::evaluate::CycleInput;
use crate::MachineInput;

/// The share of a temperature's training range it may go beyond before it is clamped.
pub const TEMPERATURE_MARGIN: f64 = 0.25;
/// The least margin of a temperature, K: a sensor that barely moved in training may still move
/// a little.
pub const TEMPERATURE_MARGIN_MIN_K: f64 = 2.0;
/// The share of an operating input's training range it may go beyond before it is clamped.
pub const OPERATING_MARGIN: f64 = 0.25;
/// The largest predicted |error| of an axis, as a multiple of the largest on the training rows.
pub const OUTPUT_FACTOR: f64 = 1.5;

/// The training envelope of a model bound to a machine: ranges per machine channel (`None`:
/// not read, or not known) and the largest |predicted error| per machine axis, µm.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrainingEnvelope {
    /// Per machine temperature channel, (min, max) in training, °C.
    pub temperatures: Vec<Option<(f64, f64)>>,
    /// Per machine operating channel, (min, max) in training.
    pub operating: Vec<Option<(f64, f64)>>,
    /// Per machine axis, the largest |predicted error| on the training rows, µm.
    pub max_abs_um: Vec<Option<f64>>,
}

/// An input beyond its widened training range in one cycle: which, its value, and the edge it
/// was clamped to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beyond {
    /// The machine channel.
    pub input: MachineInput,
    /// Its value this cycle.
    pub value: f64,
    /// The edge of its widened training range it was clamped to.
    pub limit: f64,
}

impl Beyond {
    /// How far beyond the widened range, in the input's unit.
    pub fn distance(&self) -> f64 {
        (self.value - self.limit).abs()
    }
}

/// `(min, max)` widened by `share` of its width, and at least by `least`.
fn widened((lo, hi): (f64, f64), share: f64, least: f64) -> (f64, f64) {
    let margin = (share * (hi - lo).abs()).max(least);
    (lo - margin, hi + margin)
}

impl TrainingEnvelope {
    /// Copies the temperatures and operating inputs of `input` into `temperatures` and
    /// `operating` (as many as each holds), every value the envelope knows clamped to its
    /// widened training range, and returns the input farthest beyond it, if any. A NaN stays a
    /// NaN (validation's business). Allocates nothing.
    pub fn clamp(
        &self,
        input: &CycleInput<'_>,
        temperatures: &mut [f64],
        operating: &mut [f64],
    ) -> Option<Beyond> {
        let mut worst: Option<Beyond> = None;
        let mut note = |b: Beyond| {
            if worst.is_none_or(|w| b.distance() > w.distance()) {
                worst = Some(b);
            }
        };
        for (c, (out, &v)) in temperatures
            .iter_mut()
            .zip(input.temperatures_c)
            .enumerate()
        {
            *out = v;
            if let Some(Some(range)) = self.temperatures.get(c) {
                let (lo, hi) = widened(*range, TEMPERATURE_MARGIN, TEMPERATURE_MARGIN_MIN_K);
                if v < lo || v > hi {
                    *out = v.clamp(lo, hi);
                    note(Beyond {
                        input: MachineInput::Temperature(c),
                        value: v,
                        limit: *out,
                    });
                }
            }
        }
        for (c, (out, &v)) in operating.iter_mut().zip(input.operating).enumerate() {
            *out = v;
            if let Some(Some(range)) = self.operating.get(c) {
                let (lo, hi) = widened(*range, OPERATING_MARGIN, 0.0);
                if v < lo || v > hi {
                    *out = v.clamp(lo, hi);
                    note(Beyond {
                        input: MachineInput::Operating(c),
                        value: v,
                        limit: *out,
                    });
                }
            }
        }
        worst
    }

    /// Caps each axis' predicted error at [`OUTPUT_FACTOR`] × its largest |prediction| in
    /// training; returns whether any was capped. Allocates nothing.
    pub fn cap(&self, error_um: &mut [f64]) -> bool {
        let mut capped = false;
        for (e, max) in error_um.iter_mut().zip(&self.max_abs_um) {
            if let Some(max) = max {
                let limit = OUTPUT_FACTOR * max.abs();
                if e.abs() > limit {
                    *e = limit.copysign(*e);
                    capped = true;
                }
            }
        }
        capped
    }

    /// Whether every stored figure is finite and every range ordered (a file's check).
    pub fn is_consistent(&self) -> bool {
        let range_ok = |r: &Option<(f64, f64)>| {
            r.is_none_or(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo <= hi)
        };
        self.temperatures.iter().all(range_ok)
            && self.operating.iter().all(range_ok)
            && self
                .max_abs_um
                .iter()
                .all(|m| m.is_none_or(|m| m.is_finite() && m >= 0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn envelope() -> TrainingEnvelope {
        TrainingEnvelope {
            temperatures: vec![Some((20.0, 32.0)), None, Some((21.0, 21.5))],
            operating: vec![Some((0.0, 8000.0))],
            max_abs_um: vec![Some(40.0), None, Some(10.0)],
        }
    }

    #[test]
    fn inputs_inside_the_margin_pass_and_beyond_are_clamped_and_named() {
        let env = envelope();
        let (mut t, mut o) = ([0.0; 3], [0.0; 1]);
        let inside = CycleInput {
            temperatures_c: &[34.9, 80.0, 23.4],
            positions: &[],
            operating: &[9999.0],
        };
        assert_eq!(env.clamp(&inside, &mut t, &mut o), None);
        assert_eq!((t, o), ([34.9, 80.0, 23.4], [9999.0]));
        // The quiet sensor's margin is 2 K, not 25 % of its 0.5 K.
        let beyond = CycleInput {
            temperatures_c: &[36.0, 80.0, 30.0],
            positions: &[],
            operating: &[12000.0],
        };
        let b = env.clamp(&beyond, &mut t, &mut o).unwrap();
        assert_eq!(t, [35.0, 80.0, 23.5]);
        assert_eq!(o, [10000.0]);
        // The farthest in its own unit: the spindle, 2000 rpm beyond.
        assert_eq!(b.input, MachineInput::Operating(0));
        assert_eq!(b.distance(), 2000.0);
        // A NaN stays a NaN.
        let nan = CycleInput {
            temperatures_c: &[f64::NAN, 20.0, 21.0],
            positions: &[],
            operating: &[0.0],
        };
        assert_eq!(env.clamp(&nan, &mut t, &mut o), None);
        assert!(t[0].is_nan());
    }

    #[test]
    fn the_output_is_capped_per_axis() {
        let env = envelope();
        let mut e = [-100.0, 500.0, 14.0];
        assert!(env.cap(&mut e));
        assert_eq!(e, [-60.0, 500.0, 14.0]);
        let mut ok = [59.0, -3.0, -15.0];
        assert!(!env.cap(&mut ok));
        assert!(env.is_consistent());
        let mut bad = envelope();
        bad.temperatures[0] = Some((30.0, 20.0));
        assert!(!bad.is_consistent());
    }
}
