//! A scenario file as written: the TOML tables and keys of `docs/twin.md`, before any check.
//! Unknown keys are refused here; values are checked in `super::build`.

use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct File {
    pub(super) scenario: Head,
    #[serde(default)]
    pub(super) ambient: Option<AmbientFile>,
    #[serde(default)]
    pub(super) phase: Vec<PhaseFile>,
    #[serde(default)]
    pub(super) probing: Option<ProbingFile>,
    #[serde(default)]
    pub(super) sensors: Option<SensorsFile>,
    #[serde(default)]
    pub(super) fault: Vec<FaultFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Head {
    pub(super) name: String,
    #[serde(default)]
    pub(super) description: String,
    #[serde(default)]
    pub(super) step_s: Option<f64>,
    #[serde(default)]
    pub(super) sample_s: Option<f64>,
    #[serde(default)]
    pub(super) start_hour: Option<f64>,
    #[serde(default)]
    pub(super) initial_c: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AmbientFile {
    pub(super) mean_c: f64,
    #[serde(default)]
    pub(super) daily_amplitude_c: f64,
    #[serde(default)]
    pub(super) daily_peak_hour: Option<f64>,
    #[serde(default)]
    pub(super) drift_c_per_h: f64,
    #[serde(default)]
    pub(super) event: Vec<EventFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EventFile {
    pub(super) at_min: f64,
    pub(super) delta_c: f64,
    #[serde(default)]
    pub(super) duration_min: Option<f64>,
    #[serde(default)]
    pub(super) recovery_min: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PhaseFile {
    pub(super) name: String,
    pub(super) duration_min: f64,
    #[serde(default)]
    pub(super) spindle_rpm: f64,
    #[serde(default)]
    pub(super) coolant: bool,
    #[serde(default)]
    pub(super) probe: Option<bool>,
    #[serde(default)]
    pub(super) servo_on: Option<bool>,
    #[serde(default)]
    pub(super) motion: Vec<MotionFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MotionFile {
    pub(super) axis: String,
    pub(super) pattern: String,
    #[serde(default)]
    pub(super) feed_mm_min: Option<f64>,
    #[serde(default)]
    pub(super) range_mm: Option<[f64; 2]>,
    #[serde(default)]
    pub(super) at_mm: Option<f64>,
    #[serde(default)]
    pub(super) dwell_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ProbingFile {
    pub(super) every_min: f64,
    #[serde(default, rename = "X")]
    pub(super) x: Vec<f64>,
    #[serde(default, rename = "Y")]
    pub(super) y: Vec<f64>,
    #[serde(default, rename = "Z")]
    pub(super) z: Vec<f64>,
    #[serde(default)]
    pub(super) in_place: bool,
    #[serde(default)]
    pub(super) dwell_s: Option<f64>,
    #[serde(default)]
    pub(super) feed_mm_min: Option<f64>,
    #[serde(default)]
    pub(super) stop_spindle: Option<bool>,
    #[serde(default)]
    pub(super) noise_um: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SensorsFile {
    #[serde(default)]
    pub(super) noise_c: Option<f64>,
    #[serde(default)]
    pub(super) resolution_c: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FaultFile {
    pub(super) sensor: String,
    pub(super) kind: String,
    pub(super) start_min: f64,
    #[serde(default)]
    pub(super) end_min: Option<f64>,
    #[serde(default)]
    pub(super) rail_c: Option<f64>,
    #[serde(default)]
    pub(super) c_per_h: Option<f64>,
    #[serde(default)]
    pub(super) amplitude_c: Option<f64>,
    #[serde(default)]
    pub(super) per_hour: Option<f64>,
}
