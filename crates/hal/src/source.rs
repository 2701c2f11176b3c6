//! The `truepos` component as a [`Source`]: axis positions, temperatures and operating values
//! from its input pins.

use truepos_runtime::{Frame, LinkError, Source};

use crate::pins::InputPins;

/// Reads the component's input pins into the frame every cycle (plain memory reads of HAL
/// shared memory: no lock, no allocation, no system call).
#[derive(Debug)]
pub struct HalSource {
    pins: InputPins,
    name: String,
}

impl HalSource {
    /// A source over the input pins of component `component`. The temperature pins start at
    /// NaN, so that a pin left unconnected is a sensor fault rather than a plausible 0 °C.
    pub fn new(component: &str, pins: InputPins) -> Self {
        for pin in &pins.temperatures {
            pin.set(f64::NAN);
        }
        Self {
            pins,
            name: format!("hal {component}"),
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
        for (i, pin) in self.pins.temperatures.iter().enumerate() {
            frame.set_temperature(i, pin.get());
        }
        for (i, pin) in self.pins.operating.iter().enumerate() {
            frame.set_operating(i, pin.get());
        }
        Ok(())
    }
}
