//! What one cycle hands to the sinks.

use truepos_model::MAX_AXES;

/// The state of compensation in one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CompensationState {
    /// Offsets come from a valid model evaluation.
    Active,
    /// An input is bad and no model without it exists: the last good offsets are held and
    /// ramped to zero.
    Holding,
    /// Compensation is switched off (or ramping to zero after being switched off).
    Disabled,
    /// No model matches the axis configuration of a path.
    NoModel,
}

/// One cycle's result, per machine axis, after the safety envelope.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Output {
    /// Service time in s.
    pub time_s: f64,
    /// Number of axes.
    pub axes: usize,
    /// Compensation to add to each axis' set-point in µm (−error), always finite.
    pub offset_um: [f64; MAX_AXES],
    /// Positions the offsets were computed for.
    pub positions: [f64; MAX_AXES],
    /// What the offsets are.
    pub state: CompensationState,
    /// Whether the envelope clamped any axis this cycle.
    pub clamped: bool,
    /// Whether a path's model is extrapolating: an input beyond its training envelope was
    /// clamped this cycle (`truepos_model::envelope`).
    pub extrapolating: bool,
}

impl Output {
    /// All-zero output for `axes` axes.
    pub fn zero(axes: usize) -> Self {
        Self {
            time_s: 0.0,
            axes: axes.min(MAX_AXES),
            offset_um: [0.0; MAX_AXES],
            positions: [0.0; MAX_AXES],
            state: CompensationState::Disabled,
            clamped: false,
            extrapolating: false,
        }
    }

    /// The offsets of the machine's axes.
    pub fn offsets(&self) -> &[f64] {
        &self.offset_um[..self.axes]
    }
}
