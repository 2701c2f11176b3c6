//! The last stage before the control: bumpless blending and the safety envelope.
//!
//! Switching models, enabling or disabling compensation, or falling back to holding must never make
//! the output jump (blend via the difference of the two values; docs/glossary.md: blend). Each axis
//! has exactly one blend: when the origin of its offset changes, the blend restarts from the output
//! last sent and moves linearly to the new target over the blend time, `from + (target − from)·w`
//! with `w` rising from 0 to 1. A new change restarts it from wherever the output then is; blends
//! are never stacked, so the output always lies between the value it left and the value it is going
//! to. Then the envelope clamps the rate (µm/s against the last sent value) and the magnitude (µm).

use truepos_model::MAX_AXES;

use crate::config::AxisConfig;
use crate::events::{Event, EventKind, EventQueue};

/// Time in s without clamping after which an axis' clamp counts as released.
pub const CLAMP_RELEASE_S: f64 = 1.0;

/// Per-axis blending and clamping state.
#[derive(Debug, Clone)]
pub struct Envelope {
    limits: Vec<AxisConfig>,
    last_out: [f64; MAX_AXES],
    /// The output when the running blend began.
    blend_from: [f64; MAX_AXES],
    blend_start: [f64; MAX_AXES],
    blend_s: [f64; MAX_AXES],
    blending: [bool; MAX_AXES],
    clamping: [bool; MAX_AXES],
    /// Service time of the latest clamped cycle per axis.
    clamp_seen_s: [f64; MAX_AXES],
    /// Clamps per axis since start (each `clamped` event counts one).
    clamps: [u64; MAX_AXES],
    last_time: f64,
    started: bool,
}

impl Envelope {
    /// An envelope for the machine's axes, all outputs at zero.
    pub fn new(limits: &[AxisConfig]) -> Self {
        Self {
            limits: limits.iter().take(MAX_AXES).copied().collect(),
            last_out: [0.0; MAX_AXES],
            blend_from: [0.0; MAX_AXES],
            blend_start: [0.0; MAX_AXES],
            blend_s: [0.0; MAX_AXES],
            blending: [false; MAX_AXES],
            clamping: [false; MAX_AXES],
            clamp_seen_s: [f64::NEG_INFINITY; MAX_AXES],
            clamps: [0; MAX_AXES],
            last_time: 0.0,
            started: false,
        }
    }

    /// The offsets last sent.
    pub fn last(&self) -> &[f64] {
        &self.last_out[..self.limits.len()]
    }

    /// Whether `axis` is being clamped now (from its `clamped` event to its `clamp-released`).
    pub fn clamping(&self, axis: usize) -> bool {
        axis < self.limits.len() && self.clamping[axis]
    }

    /// How many times `axis` has been clamped since start (one per `clamped` event).
    pub fn clamps(&self, axis: usize) -> u64 {
        self.clamps.get(axis).copied().unwrap_or(0)
    }

    /// The value `axis`' running blend started from, if a blend is running.
    pub fn blend_origin(&self, axis: usize) -> Option<f64> {
        (axis < self.limits.len() && self.blending[axis]).then(|| self.blend_from[axis])
    }

    /// Restarts the blend of `axis` because the origin of its target changes now: the output
    /// continues from what was last sent and reaches the new target after `blend_s` seconds. A
    /// blend still running is replaced, not added to.
    pub fn restart_blend(&mut self, axis: usize, now_s: f64, blend_s: f64) {
        if axis < self.limits.len() {
            self.blend_from[axis] = self.last_out[axis];
            self.blend_start[axis] = now_s;
            self.blend_s[axis] = if blend_s.is_finite() {
                blend_s.max(0.0)
            } else {
                0.0
            };
            self.blending[axis] = self.blend_s[axis] > 0.0;
        }
    }

    /// The blended value of `axis` for `target` at `now_s`: between the blend's origin and the
    /// target. Ends the blend once it is complete.
    fn blend(&mut self, a: usize, target: f64, now_s: f64) -> f64 {
        if !self.blending[a] {
            return target;
        }
        let w = ((now_s - self.blend_start[a]) / self.blend_s[a]).clamp(0.0, 1.0);
        if w >= 1.0 {
            self.blending[a] = false;
            return target;
        }
        let from = self.blend_from[a];
        from + (target - from) * w
    }

    /// Takes the target offsets of one cycle, applies blending and the envelope, writes the
    /// result to `out` and returns whether any axis was clamped. A target that is not finite
    /// keeps the axis where it is. Raises an event when an axis starts or stops being clamped.
    pub fn apply(
        &mut self,
        target_um: &[f64],
        now_s: f64,
        out: &mut [f64],
        events: &EventQueue,
    ) -> bool {
        let dt = if self.started && now_s.is_finite() {
            (now_s - self.last_time).max(0.0)
        } else {
            0.0
        };
        if now_s.is_finite() {
            self.started = true;
            self.last_time = now_s;
        }
        let mut any = false;
        for a in 0..self.limits.len() {
            let lim = self.limits[a];
            let target = target_um.get(a).copied().unwrap_or(0.0);
            let mut v = if target.is_finite() {
                self.blend(a, target, now_s)
            } else {
                self.last_out[a]
            };
            if !v.is_finite() {
                v = self.last_out[a];
            }
            let mut clamped_rate = false;
            let max_step = lim.max_rate_um_per_s * dt;
            let step = v - self.last_out[a];
            if step.abs() > max_step {
                v = self.last_out[a] + max_step.copysign(step);
                clamped_rate = true;
            }
            let mut clamped_abs = false;
            if v.abs() > lim.max_offset_um {
                v = lim.max_offset_um.copysign(v);
                clamped_abs = true;
            }
            let clamped = clamped_rate || clamped_abs;
            if clamped {
                self.clamp_seen_s[a] = now_s;
            }
            // Released only after a quiet second: an output held at its rate limit every other
            // cycle (an input flickering between two levels) is one clamp, not thousands.
            let report = clamped || now_s - self.clamp_seen_s[a] >= CLAMP_RELEASE_S;
            if report && clamped != self.clamping[a] {
                let kind = if clamped {
                    self.clamps[a] += 1;
                    EventKind::Clamped {
                        axis: a,
                        rate: clamped_rate,
                    }
                } else {
                    EventKind::ClampReleased { axis: a }
                };
                events.push(Event {
                    time_s: now_s,
                    kind,
                });
                self.clamping[a] = clamped;
            }
            any |= clamped;
            self.last_out[a] = v;
            if let Some(o) = out.get_mut(a) {
                *o = v;
            }
        }
        any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMIT: AxisConfig = AxisConfig {
        max_offset_um: 100.0,
        max_rate_um_per_s: 50.0,
        path: 1,
        number: 1,
    };

    /// An envelope of one axis at `LIMIT` and the queue its events go to.
    fn one_axis() -> (EventQueue, Envelope) {
        (EventQueue::new(16), Envelope::new(&[LIMIT]))
    }

    /// The kinds of the events queued so far, oldest first.
    fn drain(q: &EventQueue) -> Vec<EventKind> {
        std::iter::from_fn(|| q.pop()).map(|e| e.kind).collect()
    }

    /// One rate clamp of axis 0, then its release.
    fn one_rate_clamp() -> Vec<EventKind> {
        vec![
            EventKind::Clamped {
                axis: 0,
                rate: true,
            },
            EventKind::ClampReleased { axis: 0 },
        ]
    }

    #[test]
    fn rate_and_magnitude_are_clamped() {
        let (q, mut e) = one_axis();
        let mut out = [0.0];
        e.apply(&[0.0], 0.0, &mut out, &q);
        // A jump to 80 µm within 0.1 s: at most 50 µm/s · 0.1 s = 5 µm.
        assert!(e.apply(&[80.0], 0.1, &mut out, &q));
        assert!((out[0] - 5.0).abs() < 1e-12);
        // Much later the rate allows it, but 300 µm is beyond the 100 µm magnitude.
        assert!(e.apply(&[300.0], 100.0, &mut out, &q));
        assert_eq!(out[0], 100.0);
        // Back inside: released.
        assert!(!e.apply(&[90.0], 101.0, &mut out, &q));
        assert_eq!(out[0], 90.0);
        assert_eq!(drain(&q), one_rate_clamp());
    }

    #[test]
    fn blending_is_bumpless_and_reaches_the_new_value() {
        // Sending 20 µm; the new model says 30 µm: the output starts at 20 and is at 25 half
        // way through a 10 s blend, 30 at its end (well within 50 µm/s).
        let (q, mut e) = one_axis();
        let mut out = [0.0];
        e.apply(&[0.0], 0.0, &mut out, &q);
        e.apply(&[20.0], 1.0, &mut out, &q);
        assert_eq!(out[0], 20.0);
        e.restart_blend(0, 1.0, 10.0);
        e.apply(&[30.0], 1.0, &mut out, &q);
        assert!((out[0] - 20.0).abs() < 1e-12);
        e.apply(&[30.0], 6.0, &mut out, &q);
        assert!((out[0] - 25.0).abs() < 1e-12);
        e.apply(&[30.0], 11.0, &mut out, &q);
        assert!((out[0] - 30.0).abs() < 1e-12);
        assert!(q.pop().is_none());
    }

    #[test]
    fn a_restarted_blend_continues_from_the_output_and_never_stacks() {
        // Blending 0 → 40 over 10 s; at 5 s (output 20) the target changes to −10: the new blend
        // starts at 20, not at 20 plus what was left of the first one.
        let (q, mut e) = one_axis();
        let mut out = [0.0];
        e.apply(&[0.0], 0.0, &mut out, &q);
        e.restart_blend(0, 0.0, 10.0);
        e.apply(&[40.0], 5.0, &mut out, &q);
        assert!((out[0] - 20.0).abs() < 1e-12);
        e.restart_blend(0, 5.0, 10.0);
        assert_eq!(e.blend_origin(0), Some(20.0));
        for k in 1..=10 {
            let t = 5.0 + k as f64;
            e.apply(&[-10.0], t, &mut out, &q);
            let expected = 20.0 + (-10.0 - 20.0) * (k as f64 / 10.0);
            assert!(
                (out[0] - expected).abs() < 1e-9,
                "{t}: {} vs {expected}",
                out[0]
            );
        }
        assert_eq!(e.blend_origin(0), None);
        assert_eq!(out[0], -10.0);
    }

    #[test]
    fn a_clamp_every_other_cycle_is_one_event() {
        // A target flickering by ±1 µm at 1 kHz: the 50 µm/s limit (0.05 µm per cycle) binds
        // on every cycle that moves; one clamp event, released a quiet second after it ends.
        let (q, mut e) = one_axis();
        let mut out = [0.0];
        for k in 0..4000 {
            let target = if k < 2000 && k % 2 == 1 { 1.0 } else { 0.0 };
            e.apply(&[target], k as f64 * 0.001, &mut out, &q);
        }
        assert_eq!(drain(&q), one_rate_clamp());
    }

    #[test]
    fn non_finite_raw_values_never_pass() {
        let (q, mut e) = one_axis();
        let mut out = [1.0];
        e.apply(&[f64::NAN], 0.0, &mut out, &q);
        assert_eq!(out[0], 0.0);
    }
}
