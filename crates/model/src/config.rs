//! What the compensation service is configured with, owned by the core so that the file
//! formats (`truepos-io`) and the service (`truepos-runtime`) share it without depending on each
//! other: the machine as the service runs it — the checked [`Machine`] with each axis' safety
//! envelope and control path slot ([`AxisConfig`]), each temperature channel's validation
//! limits ([`SensorChecks`]) and what the description says beside (units, text) — and the
//! models with the axis combination each serves ([`ModelEntry`]).

use alloc::string::String;
use alloc::vec::Vec;

use crate::compensation::CompensationModel;
use crate::machine::Machine;

/// Default safety envelope: largest offset magnitude in µm. Thermal errors of machining
/// centres reach tens of µm (−100 … 150 µm on 500 mm at the extreme); 100 µm lets a
/// sound model work and stops a wild one.
pub const DEFAULT_MAX_OFFSET_UM: f64 = 100.0;
/// Default safety envelope: largest offset rate in µm/s. Thermal drift is µm per minute; the
/// position-dependent terms change faster only with fast moves (20 µm over 500 mm at 10 m/min
/// is 6.7 µm/s), so 50 µm/s passes them and stops a jump.
pub const DEFAULT_MAX_RATE_UM_PER_S: f64 = 50.0;
/// Default fastest plausible temperature change: 2 K/min (a sensor in a casting).
pub const DEFAULT_MAX_RATE_K_PER_MIN: f64 = 2.0;
/// Default staleness limit: 10 s without an update.
pub const DEFAULT_MAX_AGE_S: f64 = 10.0;
/// Default stuck limit in s: four hours. A sound sensor read at 0.1 K resolution on a machine at
/// rest can hold one value for hours (FL_THERMAL's t7: 2.5 h), so a shorter default would call
/// healthy sensors stuck.
pub const DEFAULT_STUCK_AFTER_S: f64 = 14_400.0;
/// Default noise band in K: changes this small are never a rate fault. A 0.1 K module flickers
/// between adjacent levels at rest, and FL_THERMAL's noisiest sensor (t16) steps by up to 2.9 K
/// between 15 s samples; a 5 K step within one poll stays a fault.
pub const DEFAULT_NOISE_K: f64 = 3.0;
/// Default time in s a faulted reading must stay sound before it is used again.
pub const DEFAULT_RECOVER_AFTER_S: f64 = 2.0;

/// One axis as the service drives it: its safety envelope and its slot in the control's paths
/// (model selection by axis combination).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisConfig {
    /// Largest offset magnitude in µm.
    pub max_offset_um: f64,
    /// Largest offset rate in µm/s.
    pub max_rate_um_per_s: f64,
    /// Path (channel) at power-on, 1-based.
    pub path: u32,
    /// Axis number within the path, 1-based.
    pub number: u32,
}

impl AxisConfig {
    /// The axis code b = 100·path + axis number of the axis-combination index.
    pub fn code(&self) -> u32 {
        100 * self.path + self.number
    }
}

/// The validation limits of one temperature channel (its valid range is in the machine).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorChecks {
    /// Fastest plausible change in K/s.
    pub max_rate_k_per_s: f64,
    /// Longest time without an update in s.
    pub max_age_s: f64,
    /// Time without any change after which a reading is stuck, in s (0: not checked).
    pub stuck_after_s: f64,
    /// Largest change in K between readings that is never judged by rate: the channel's
    /// quantisation steps and noise.
    pub noise_k: f64,
    /// Time in s a faulted reading must stay sound before it is used again.
    pub recover_after_s: f64,
}

/// The machine as the service runs it: the checked machine and, in its order, every axis'
/// envelope and path slot and every temperature channel's checks.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineConfig {
    /// The machine, checked.
    pub machine: Machine,
    /// Free text describing the machine.
    pub description: String,
    /// Unit of each operating channel, in machine order.
    pub operating_units: Vec<String>,
    /// Envelope and path slot per axis, in machine order.
    pub axes: Vec<AxisConfig>,
    /// Validation limits per temperature channel, in machine order.
    pub sensor_checks: Vec<SensorChecks>,
}

/// Slots of an axis-combination index (three, as in docs/glossary.md).
pub const INDEX_SLOTS: usize = 3;

/// A model with the axis combination it serves.
#[derive(Debug, Clone)]
pub struct ModelEntry {
    /// Name for events and status.
    pub name: String,
    /// The model.
    pub model: CompensationModel,
    /// Its axis-combination index, 0 in unused slots.
    pub index: [u32; INDEX_SLOTS],
}

/// Builds an index from axis codes (100·path + number), 0 in unused slots; codes beyond the
/// slots are ignored (a path with more axes than slots matches on its first three).
pub fn index_of(codes: impl IntoIterator<Item = u32>) -> [u32; INDEX_SLOTS] {
    let mut index = [0; INDEX_SLOTS];
    for (slot, code) in index.iter_mut().zip(codes) {
        *slot = code;
    }
    index
}
