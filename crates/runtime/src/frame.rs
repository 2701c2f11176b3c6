//! The inputs of one cycle as sources deliver them: a value and the time of its last update per
//! channel, in the machine description's channel order.

/// Time of an update that never happened.
pub const NEVER: f64 = f64::NEG_INFINITY;

/// The latest value of every channel and when it arrived (seconds on the service clock).
///
/// Allocated once when the service starts; sources overwrite values in place every cycle, so the
/// cycle path allocates nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Service time of this cycle in s.
    pub time_s: f64,
    /// Temperature per machine temperature channel in °C.
    pub temperatures_c: Vec<f64>,
    /// Service time of each temperature's last update (or [`NEVER`]).
    pub temperature_stamp_s: Vec<f64>,
    /// Position per machine axis (mm or degrees), as the control reports it.
    pub positions: Vec<f64>,
    /// Service time of each position's last update.
    pub position_stamp_s: Vec<f64>,
    /// Operating state per machine operating channel.
    pub operating: Vec<f64>,
    /// Service time of each operating value's last update.
    pub operating_stamp_s: Vec<f64>,
    /// The control's axis configuration: for each path (1-based index − 1), the machine axis
    /// indices it drives in order (e.g. path 1 = X1, Z1). Sources that know it (a control)
    /// overwrite it; it stays as configured otherwise.
    pub paths: Vec<Vec<usize>>,
    /// A probe event seen by a source this cycle (the HAL component on a rising edge of its
    /// trigger pin); the service takes it, checks it and logs it.
    pub probe: Option<crate::probe::ProbeInput>,
}

impl Frame {
    /// A frame for a machine with the given channel counts, every value NaN and never updated.
    pub fn new(temperatures: usize, axes: usize, operating: usize) -> Self {
        Self {
            time_s: 0.0,
            temperatures_c: vec![f64::NAN; temperatures],
            temperature_stamp_s: vec![NEVER; temperatures],
            positions: vec![f64::NAN; axes],
            position_stamp_s: vec![NEVER; axes],
            operating: vec![f64::NAN; operating],
            operating_stamp_s: vec![NEVER; operating],
            paths: Vec::new(),
            probe: None,
        }
    }

    /// Sets a temperature and stamps it with the frame's time.
    pub fn set_temperature(&mut self, channel: usize, value_c: f64) {
        if let Some(v) = self.temperatures_c.get_mut(channel) {
            *v = value_c;
            self.temperature_stamp_s[channel] = self.time_s;
        }
    }

    /// Sets an axis position and stamps it with the frame's time.
    pub fn set_position(&mut self, axis: usize, value: f64) {
        if let Some(v) = self.positions.get_mut(axis) {
            *v = value;
            self.position_stamp_s[axis] = self.time_s;
        }
    }

    /// Sets an operating value and stamps it with the frame's time.
    pub fn set_operating(&mut self, channel: usize, value: f64) {
        if let Some(v) = self.operating.get_mut(channel) {
            *v = value;
            self.operating_stamp_s[channel] = self.time_s;
        }
    }
}
