//! The service's configuration: the machine with each axis' safety envelope and control path
//! slot, and each temperature channel's validation limits. `truepos-io` parses a machine
//! description file into a [`MachineConfig`]; the service, its envelope and its validator take
//! it and its parts.
//!
//! The types are defined beside the core's `Machine` (`truepos_model::config`, which says why);
//! this module is their name for the runtime and its users.

pub use truepos_model::config::{
    AxisConfig, MachineConfig, SensorChecks, DEFAULT_MAX_AGE_S, DEFAULT_MAX_OFFSET_UM,
    DEFAULT_MAX_RATE_K_PER_MIN, DEFAULT_MAX_RATE_UM_PER_S, DEFAULT_NOISE_K,
    DEFAULT_RECOVER_AFTER_S, DEFAULT_STUCK_AFTER_S,
};
