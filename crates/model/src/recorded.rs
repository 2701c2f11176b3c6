//! A recorded run as the machine saw it — the one type of a run for every user: io reads a run
//! file into it, the runtime's replay plays it, the twin fills it, the position-dependent fit
//! learns from it, and the commands step a model through its rows.

use alloc::vec::Vec;

use crate::evaluate::CycleInput;

/// Per row: its time and every channel in the machine description's order (NaN where the run
/// holds no value for a channel).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordedRun {
    /// Time of each row in s, increasing.
    pub time_s: Vec<f64>,
    /// Temperatures of each row in °C, one per machine temperature channel.
    pub temperatures_c: Vec<Vec<f64>>,
    /// Axis positions of each row (mm or degrees), one per machine axis.
    pub positions: Vec<Vec<f64>>,
    /// Operating state of each row, one per machine operating channel.
    pub operating: Vec<Vec<f64>>,
}

impl RecordedRun {
    /// Rows in the run.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// Whether the run has no row.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Row `i` as one cycle's inputs.
    ///
    /// # Panics
    /// If `i` is not below [`Self::len`].
    pub fn row(&self, i: usize) -> CycleInput<'_> {
        CycleInput {
            temperatures_c: &self.temperatures_c[i],
            positions: &self.positions[i],
            operating: &self.operating[i],
        }
    }

    /// Appends the rows of `other` (a run of the same machine).
    pub fn extend(&mut self, other: RecordedRun) {
        self.time_s.extend(other.time_s);
        self.temperatures_c.extend(other.temperatures_c);
        self.positions.extend(other.positions);
        self.operating.extend(other.operating);
    }
}
