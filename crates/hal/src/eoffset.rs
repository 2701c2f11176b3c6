//! LinuxCNC's external offsets (`axis.L.eoffset-*`) in truepos's units.
//!
//! LinuxCNC 2.9 accumulates an axis' external offset request from its counts pin like a jog
//! wheel: every change of `axis.L.eoffset-counts` adds Δcounts × `axis.L.eoffset-scale` (mm),
//! while `axis.L.eoffset-enable` is true (verified on the simulator with `halcmd`: counts 25 at
//! scale 0.001 gave 0.025 mm; then scale 0.002 and counts 30 gave 0.025 + 5 × 0.002 = 0.035 mm).
//! truepos keeps the scale constant, so the offset in force is counts × scale and the counts
//! are the offset in units of the resolution.

/// Resolution of the offsets truepos sends: 0.01 µm per count. An s32 then spans ±21 m, far
/// beyond any envelope, and quantisation (≤ 0.005 µm) stays far below thermal errors.
pub const RESOLUTION_UM: f64 = 0.01;

/// The value for `axis.L.eoffset-scale` in mm per count: 0.01 µm = 1e-5 mm.
pub const SCALE_MM_PER_COUNT: f64 = RESOLUTION_UM / 1000.0;

/// The counts that make LinuxCNC apply `offset_um` (rounded to the nearest count; saturated to
/// the s32 range; NaN — never produced by the envelope — gives 0).
///
/// ```
/// use truepos_hal::eoffset::counts_for;
/// assert_eq!(counts_for(12.345), 1235); // 12.345 µm / 0.01 µm, rounded half away from zero
/// assert_eq!(counts_for(-0.004), 0);
/// ```
pub fn counts_for(offset_um: f64) -> i32 {
    let c = (offset_um / RESOLUTION_UM).round();
    if c.is_nan() {
        0
    } else {
        // `as` saturates at i32::MIN/MAX for out-of-range floats.
        c as i32
    }
}

/// The offset in µm that `counts` stand for.
pub fn offset_um_of(counts: i32) -> f64 {
    f64::from(counts) * RESOLUTION_UM
}

/// Turns each cycle's offset into the counts to write, following what LinuxCNC accepts.
///
/// LinuxCNC 2.9 (`axis_plan_external_offsets` in motion's `axis.c`) drops count changes while
/// motion is disabled or not every joint is homed, and zeroes the external offsets when motion
/// is enabled (machine on). So truepos holds its counts still while LinuxCNC is not *ready*
/// (`motion.motion-enabled` and `motion.is-all-homed`), and when it becomes ready it takes the
/// counts written so far as the base for the offset LinuxCNC holds then (`axis.L.eoffset-request`,
/// 0 after a machine-on). From then on counts = base + offset / resolution, so LinuxCNC's
/// accumulated request equals the offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CountsTracker {
    base: i64,
    last: i32,
    ready: bool,
}

impl CountsTracker {
    /// A tracker that has written 0 and waits for LinuxCNC to be ready.
    pub fn new() -> Self {
        Self::default()
    }

    /// The counts to write this cycle for `offset_um`, given whether LinuxCNC accepts count
    /// changes (`ready`) and the offset it has requested so far (`requested_mm`).
    pub fn update(&mut self, ready: bool, offset_um: f64, requested_mm: f64) -> i32 {
        if !ready {
            self.ready = false;
            return self.last;
        }
        if !self.ready {
            self.ready = true;
            let held = if requested_mm.is_finite() {
                (requested_mm / SCALE_MM_PER_COUNT).round() as i64
            } else {
                0
            };
            self.base = i64::from(self.last) - held;
        }
        let c = (self.base + i64::from(counts_for(offset_um)))
            .clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        self.last = c;
        c
    }

    /// Whether LinuxCNC was ready at the last update.
    pub fn ready(&self) -> bool {
        self.ready
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// LinuxCNC's accumulation, as in `axis_plan_external_offsets`: deltas count only when ready.
    struct Motion {
        old: i32,
        request_counts: i64,
    }

    impl Motion {
        fn servo(&mut self, counts: i32, ready: bool) {
            let delta = i64::from(counts) - i64::from(self.old);
            self.old = counts;
            if ready {
                self.request_counts += delta;
            }
        }
    }

    #[test]
    fn follows_linuxcnc_through_machine_off_and_homing() {
        let mut t = CountsTracker::new();
        let mut m = Motion {
            old: 0,
            request_counts: 0,
        };
        // Before homing the model already asks for 12 µm: nothing is written.
        assert_eq!(t.update(false, 12.0, 0.0), 0);
        m.servo(0, false);
        // Ready with nothing requested: base 0, 12 µm = 1200 counts, LinuxCNC requests 1200.
        let c = t.update(true, 12.0, 0.0);
        m.servo(c, true);
        assert_eq!(m.request_counts, 1200);
        // Re-homing: not ready, the model moves to 15 µm; counts held at 1200.
        assert_eq!(t.update(false, 15.0, 0.012), 1200);
        m.servo(1200, false);
        // Ready again with 12 µm requested (0.012 mm): base = 1200 − 1200 = 0; 15 µm → 1500.
        let c = t.update(true, 15.0, 0.012);
        m.servo(c, true);
        assert_eq!(m.request_counts, 1500);
        // Machine off and on: LinuxCNC zeroes its request; counts stay 1500 meanwhile.
        assert_eq!(t.update(false, 20.0, 0.015), 1500);
        m.servo(1500, false);
        m.request_counts = 0;
        // Ready: base = 1500 − 0; 20 µm → 1500 + 2000 = 3500, LinuxCNC requests 2000 = 20 µm.
        let c = t.update(true, 20.0, 0.0);
        assert_eq!(c, 3500);
        m.servo(c, true);
        assert_eq!(m.request_counts, 2000);
    }
    use proptest::prelude::*;

    #[test]
    fn hand_computed_counts() {
        // 25.004 µm / 0.01 µm = 2500.4 → 2500 counts; × 1e-5 mm = 0.025 mm.
        assert_eq!(counts_for(25.004), 2500);
        assert!((f64::from(counts_for(25.004)) * SCALE_MM_PER_COUNT - 0.025).abs() < 1e-15);
        // −7.125 µm → −712.5 → −713 (half away from zero).
        assert_eq!(counts_for(-7.125), -713);
        assert_eq!(counts_for(f64::NAN), 0);
        assert_eq!(counts_for(1e30), i32::MAX);
        assert_eq!(counts_for(-1e30), i32::MIN);
    }

    proptest! {
        #[test]
        fn round_trip_within_half_a_count(offset in -1.0e4f64..1.0e4) {
            let back = offset_um_of(counts_for(offset));
            prop_assert!((back - offset).abs() <= RESOLUTION_UM / 2.0 + 1e-9);
        }
    }
}
