//! The `truepos` component as a [`Source`]: axis positions, temperatures, operating values and
//! the control's axis configuration from its input pins.

use truepos_runtime::probe::ProbeInput;
use truepos_runtime::{AxisConfig, Frame, LinkError, Source};

use crate::pins::InputPins;

/// Reads the component's input pins into the frame every cycle (plain memory reads of HAL
/// shared memory: no lock, no allocation, no system call).
#[derive(Debug)]
pub struct HalSource {
    pins: InputPins,
    name: String,
    /// Machine axis indices by axis number: the order of a path's axes (its axis-combination
    /// index).
    by_number: Vec<usize>,
    probe_edge: Edge,
}

/// A rising-edge detector: `true` once when the input goes from low to high.
#[derive(Debug, Clone, Copy, Default)]
pub struct Edge {
    last: bool,
}

impl Edge {
    /// Whether `now` is a rising edge after the previous sample.
    pub fn rising(&mut self, now: bool) -> bool {
        let rose = now && !self.last;
        self.last = now;
        rose
    }
}

impl HalSource {
    /// A source over the input pins of component `component`, for the axes of the machine
    /// file (`axes`, machine order). The temperature pins start at NaN, so that a pin left
    /// unconnected is a sensor fault rather than a plausible 0 °C; the axis-path pins start at
    /// each axis' `path` in the machine file, so that left unconnected they change nothing.
    pub fn new(component: &str, pins: InputPins, axes: &[AxisConfig]) -> Self {
        for (_, pin) in &pins.temperatures {
            pin.set(f64::NAN);
        }
        for (pin, axis) in pins.paths.iter().zip(axes) {
            pin.set(i32::try_from(axis.path).unwrap_or(0));
        }
        let mut by_number: Vec<usize> = (0..axes.len()).collect();
        by_number.sort_by_key(|&a| axes[a].number);
        Self {
            pins,
            name: format!("hal {component}"),
            by_number,
            probe_edge: Edge::default(),
        }
    }
}

impl Source for HalSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        for (i, pin) in self.pins.positions.iter().enumerate() {
            frame.set_position(i, pin.get());
        }
        for (c, pin) in &self.pins.temperatures {
            frame.set_temperature(*c, pin.get());
        }
        for (i, pin) in self.pins.operating.iter().enumerate() {
            frame.set_operating(i, pin.get());
        }
        // One probe event per rising edge of the trigger: the values of that cycle.
        let probe = &self.pins.probe;
        if self.probe_edge.rising(probe.trigger.get()) {
            frame.probe = Some(probe_event(
                probe.positions.len(),
                |a| probe.positions[a].get(),
                |a| probe.deviations[a].get(),
                |a| probe.measured[a].get(),
            ));
        }
        // The axis configuration, rebuilt in the capacity the service reserved (no
        // allocation); an axis whose pin names no path of the machine is in none (parked).
        for axes in &mut frame.paths {
            axes.clear();
        }
        for &a in &self.by_number {
            let path = self.pins.paths.get(a).map_or(0, |p| p.get());
            let slot = usize::try_from(path).ok().and_then(|p| p.checked_sub(1));
            if let Some(axes) = slot.and_then(|p| frame.paths.get_mut(p)) {
                axes.push(a);
            }
        }
        Ok(())
    }
}

/// The probe event of `axes` axes from the values of their `pos-N`, `dev-N` and `measured-N`
/// pins (axes beyond [`truepos_model::MAX_AXES`] are not carried).
pub fn probe_event(
    axes: usize,
    position: impl Fn(usize) -> f64,
    deviation: impl Fn(usize) -> f64,
    measured: impl Fn(usize) -> bool,
) -> ProbeInput {
    let mut event = ProbeInput::EMPTY;
    for a in 0..axes.min(truepos_model::MAX_AXES) {
        event.position_mm[a] = position(a);
        event.deviation_um[a] = deviation(a);
        event.measured[a] = measured(a);
    }
    event
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One event per rising edge: held high is one event, low then high again another.
    #[test]
    fn a_rising_edge_is_one_probe_event() {
        let mut e = Edge::default();
        let trigger = [false, true, true, true, false, false, true, false, true];
        let events: Vec<usize> = trigger
            .iter()
            .enumerate()
            .filter(|(_, &t)| e.rising(t))
            .map(|(i, _)| i)
            .collect();
        assert_eq!(events, [1, 6, 8]);
    }

    /// The pins' values in machine axis order make the event; an unmeasured axis keeps its
    /// value but is marked as such, so the service's check ignores it.
    #[test]
    fn the_pins_values_make_the_event() {
        let pos = [10.0, 20.0, 30.0];
        let dev = [f64::NAN, 0.0, -7.5];
        let p = probe_event(3, |a| pos[a], |a| dev[a], |a| a == 2);
        assert_eq!(&p.position_mm[..3], &pos);
        assert_eq!(p.deviation_um[2], -7.5);
        assert_eq!(&p.measured[..4], &[false, false, true, false]);
        assert!(p.position_mm[3].is_nan(), "no fourth axis");
        // More axes than an event carries: the first MAX_AXES.
        let many = probe_event(12, |a| a as f64, |_| 1.0, |_| true);
        assert_eq!(many.position_mm[8], 8.0);
    }
}
