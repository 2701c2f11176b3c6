//! The `truepos` component as a [`Sink`]: each cycle's offsets onto the pins that drive
//! LinuxCNC's external offsets.

use truepos_model::MAX_AXES;
use truepos_runtime::{LinkError, Output, Sink};

use crate::eoffset::{CountsTracker, SCALE_MM_PER_COUNT};
use crate::pins::{status_code, OutputPins};

/// Writes offsets, counts, scale, enable and status pins (plain memory writes), holding the
/// counts still while LinuxCNC does not accept them (see [`CountsTracker`]).
#[derive(Debug)]
pub struct HalSink {
    pins: OutputPins,
    trackers: Vec<CountsTracker>,
    name: String,
}

impl HalSink {
    /// A sink over the output pins of component `component`. Sets every axis' scale to
    /// [`SCALE_MM_PER_COUNT`], its counts to 0 and its external-offset enable on. The
    /// `motion-enabled` and `all-homed` inputs start true, so that a configuration that does
    /// not net them behaves as if LinuxCNC were always ready.
    pub fn new(component: &str, pins: OutputPins) -> Self {
        for axis in &pins.axes {
            axis.scale.set(SCALE_MM_PER_COUNT);
            axis.counts.set(0);
            axis.offset_um.set(0.0);
            axis.enable.set(true);
        }
        pins.motion_enabled.set(true);
        pins.all_homed.set(true);
        Self {
            trackers: vec![CountsTracker::new(); pins.axes.len()],
            pins,
            name: format!("hal {component}"),
        }
    }

    /// Whether LinuxCNC accepts offsets now: motion enabled and every joint homed.
    pub fn control_ready(&self) -> bool {
        self.pins.motion_enabled.get() && self.pins.all_homed.get()
    }

    /// The offsets LinuxCNC has requested so far per axis (`axis.L.eoffset-request`), µm.
    pub fn requested_um(&self) -> [f64; MAX_AXES] {
        let mut out = [0.0; MAX_AXES];
        for (o, axis) in out.iter_mut().zip(&self.pins.axes) {
            let r = axis.request.get() * 1000.0;
            *o = if r.is_finite() { r } else { 0.0 };
        }
        out
    }

    /// Publishes the duration of the last cycle and the cycle count.
    pub fn set_cycle_stats(&self, cycle_us: f64, cycles: u64) {
        self.pins.cycle_us.set(cycle_us);
        // The pin is an s32: it wraps, as LinuxCNC's own counters do.
        self.pins.cycles.set(cycles as u32 as i32);
    }
}

impl Sink for HalSink {
    fn name(&self) -> &str {
        &self.name
    }

    fn write(&mut self, output: &Output) -> Result<(), LinkError> {
        let ready = self.control_ready();
        for ((pins, tracker), &offset) in self
            .pins
            .axes
            .iter()
            .zip(self.trackers.iter_mut())
            .zip(output.offsets())
        {
            // The service never hands over NaN; a zero is the safe value should one appear.
            let offset = if offset.is_finite() { offset } else { 0.0 };
            pins.offset_um.set(offset);
            pins.counts
                .set(tracker.update(ready, offset, pins.request.get()));
        }
        self.pins.status.set(status_code(output.state));
        self.pins.clamped.set(output.clamped);
        self.pins.extrapolating.set(output.extrapolating);
        Ok(())
    }

    /// The path of the offsets to LinuxCNC's axes (its writes are plain memory writes, so it
    /// does not fail; should a future one, the service reports the axes unreachable).
    fn drives_axes(&self) -> bool {
        true
    }
}
