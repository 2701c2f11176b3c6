//! Operating scenarios: phases of spindle speed, axis motion, coolant and idle time, the ambient
//! temperature over the day, probing cycles and injected sensor faults, read from TOML.
//!
//! The format is documented in `docs/twin.md`; the built-in scenarios ([`Scenario::builtin`])
//! are written in it (`crates/sim/scenarios/*.toml`, copied to `examples/twin/scenarios/`).
//! Every error names the file, line, column, key and what was expected.

mod build;
pub(crate) mod checker;
mod file;

use checker::{toml_error, Checker};
use file::File;
use truepos_files::InputError;

/// Names of the built-in scenarios.
pub const BUILTIN: [&str; 5] = [
    "spindle-warmup",
    "linear-axis",
    "environment",
    "mixed-shift",
    "mixed-shift-b",
];

fn builtin_text(name: &str) -> Option<&'static str> {
    Some(match name {
        "spindle-warmup" => include_str!("../../scenarios/spindle-warmup.toml"),
        "linear-axis" => include_str!("../../scenarios/linear-axis.toml"),
        "environment" => include_str!("../../scenarios/environment.toml"),
        "mixed-shift" => include_str!("../../scenarios/mixed-shift.toml"),
        "mixed-shift-b" => include_str!("../../scenarios/mixed-shift-b.toml"),
        _ => return None,
    })
}

/// Longest scenario, s: 30 days. A twin day is hours; a month covers soak and drift studies
/// while bounding the time and memory of a run (and of `truepos run --source twin:`, which
/// computes the whole run before its first cycle).
pub const MAX_DURATION_S: f64 = 30.0 * 86_400.0;
/// Most sampled CSV rows of a run: 30 days at the default 10 s fit. A row holds every sensor,
/// error and node temperature, about 1 kB in memory, so a run stays near 300 MB at most.
pub const MAX_SAMPLES: f64 = 300_000.0;
/// Most integration steps of a run (a day at 0.01 s, 30 days at 0.26 s): seconds of CPU in a
/// release build, about a minute in a debug one.
pub const MAX_STEPS: f64 = 10_000_000.0;

// ---------------------------------------------------------------------------------------------
// Checked form

/// A step change of the ambient temperature (a door opened, a heater switched on).
#[derive(Debug, Clone, PartialEq)]
pub struct AmbientEvent {
    /// Start, s from the run's start.
    pub at_s: f64,
    /// Change, K.
    pub delta_c: f64,
    /// How long it lasts, s (`None` = for good).
    pub duration_s: Option<f64>,
    /// Time constant of the return to normal after it ends, s (0 = at once).
    pub recovery_s: f64,
}

/// The ambient temperature over time: mean + daily swing + drift + events.
#[derive(Debug, Clone, PartialEq)]
pub struct Ambient {
    /// Mean, °C.
    pub mean_c: f64,
    /// Amplitude of the day/night swing, K.
    pub daily_amplitude_c: f64,
    /// Clock hour of the daily maximum.
    pub daily_peak_hour: f64,
    /// Linear drift, K/h.
    pub drift_c_per_h: f64,
    /// Steps.
    pub events: Vec<AmbientEvent>,
}

impl Ambient {
    /// Ambient temperature (°C) at `t_s` after a start at clock hour `start_hour`.
    pub fn at(&self, t_s: f64, start_hour: f64) -> f64 {
        let hour = start_hour + t_s / 3600.0;
        let mut v = self.mean_c
            + self.daily_amplitude_c
                * (std::f64::consts::TAU * (hour - self.daily_peak_hour) / 24.0).cos()
            + self.drift_c_per_h * t_s / 3600.0;
        for e in &self.events {
            if t_s < e.at_s {
                continue;
            }
            match e.duration_s {
                None => v += e.delta_c,
                Some(d) if t_s < e.at_s + d => v += e.delta_c,
                Some(d) => {
                    let since = t_s - e.at_s - d;
                    if e.recovery_s > 0.0 {
                        v += e.delta_c * (-since / e.recovery_s).exp();
                    }
                }
            }
        }
        v
    }
}

/// How an axis moves during a phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pattern {
    /// Back and forth between the ends of the range.
    Sweep,
    /// To random targets in the range, dwelling up to `dwell_s` at each.
    Random,
    /// To `at_mm` and stays there.
    Hold,
}

/// The motion of one axis during a phase.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    /// Axis index (0 = X, 1 = Y, 2 = Z).
    pub axis: usize,
    /// Pattern.
    pub pattern: Pattern,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Range, mm (`None` = the full travel).
    pub range_mm: Option<[f64; 2]>,
    /// Target of `hold` (`None` = where the axis is).
    pub at_mm: Option<f64>,
    /// Longest dwell at a target of `random` (s).
    pub dwell_s: f64,
}

/// One phase of operation.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// Name (shown in the CSV's `phase` column as its index).
    pub name: String,
    /// Length, s.
    pub duration_s: f64,
    /// Spindle speed, 1/min.
    pub spindle_rpm: f64,
    /// Coolant on.
    pub coolant: bool,
    /// Probing cycles run during this phase.
    pub probe: bool,
    /// Servos on (drives hold position with current); off for a machine switched off.
    pub servo_on: bool,
    /// Axis motions; axes not listed hold their position.
    pub motion: Vec<Motion>,
}

/// Periodic measurement of the tool-tip error, as a touch probe would (probing
/// re-identification), or by non-contact sensors at the current position (ISO 230-3).
#[derive(Debug, Clone, PartialEq)]
pub struct Probing {
    /// Period, s.
    pub every_s: f64,
    /// Grid of positions (the product of the three lists), visited in order.
    pub points: Vec<[f64; 3]>,
    /// Measure where the axes are, without moving.
    pub in_place: bool,
    /// Dwell before each touch, s.
    pub dwell_s: f64,
    /// Feed between points, mm/min.
    pub feed_mm_min: f64,
    /// Stop the spindle while probing.
    pub stop_spindle: bool,
    /// Probe repeatability (σ), µm.
    pub noise_um: f64,
}

/// What a fault does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// Open circuit: the reading sits at the converter's rail value.
    OpenCircuit {
        /// Rail value, °C.
        rail_c: f64,
    },
    /// Stuck at the value it had when the fault began.
    Stuck,
    /// Drifts away linearly.
    Drift {
        /// Drift rate, K/h.
        c_per_h: f64,
    },
    /// Random spikes.
    Spikes {
        /// Spike height, K.
        amplitude_c: f64,
        /// Probability that a reading spikes.
        probability: f64,
    },
}

/// A fault injected into one sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// Sensor id.
    pub sensor: String,
    /// What it does.
    pub kind: FaultKind,
    /// Start, s.
    pub start_s: f64,
    /// End, s (`None` = to the end of the run).
    pub end_s: Option<f64>,
}

impl Fault {
    /// Whether the fault acts at `t_s`.
    pub fn active(&self, t_s: f64) -> bool {
        t_s >= self.start_s && self.end_s.is_none_or(|e| t_s < e)
    }
}

/// A checked scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// What it represents.
    pub description: String,
    /// Integration step, s.
    pub step_s: f64,
    /// Sampling period of the CSV rows, s.
    pub sample_s: f64,
    /// Clock hour at the start (for the daily ambient cycle).
    pub start_hour: f64,
    /// Machine temperature at the start (`None` = soaked at the starting ambient).
    pub initial_c: Option<f64>,
    /// Ambient.
    pub ambient: Ambient,
    /// Phases in order.
    pub phases: Vec<Phase>,
    /// Probing cycles.
    pub probing: Option<Probing>,
    /// Sensor noise σ, K.
    pub sensor_noise_c: f64,
    /// Sensor resolution, K.
    pub sensor_resolution_c: f64,
    /// Injected faults.
    pub faults: Vec<Fault>,
}

impl Scenario {
    /// A built-in scenario by name (see [`BUILTIN`]).
    pub fn builtin(name: &str) -> Option<Scenario> {
        let text = builtin_text(name)?;
        Some(
            Scenario::parse(text, &format!("<builtin:{name}>"), None)
                .expect("built-in scenarios are valid (tested)"),
        )
    }

    /// The TOML text of a built-in scenario.
    pub fn builtin_toml(name: &str) -> Option<&'static str> {
        builtin_text(name)
    }

    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.phases.iter().map(|p| p.duration_s).sum()
    }

    /// Checks the size of a run of this scenario: duration, sampled rows and integration
    /// steps within [`MAX_DURATION_S`], [`MAX_SAMPLES`] and [`MAX_STEPS`]. [`Scenario::parse`]
    /// reports the same at the key in the file; this covers scenarios built or changed in code
    /// (`truepos sim --sample-s`).
    pub fn check_size(&self) -> Result<(), String> {
        let d = self.duration_s();
        if !(d.is_finite() && d <= MAX_DURATION_S) {
            return Err(format!(
                "scenario {}: lasts {d} s; expected at most {MAX_DURATION_S} s (30 days)",
                self.name
            ));
        }
        if !(self.sample_s.is_finite() && self.sample_s > 0.0 && d / self.sample_s <= MAX_SAMPLES) {
            return Err(format!(
                "scenario {}: {d} s sampled every {} s gives more than {MAX_SAMPLES} rows; expected sample_s ≥ {} s",
                self.name,
                self.sample_s,
                d / MAX_SAMPLES
            ));
        }
        if !(self.step_s.is_finite() && self.step_s > 0.0 && d / self.step_s <= MAX_STEPS) {
            return Err(format!(
                "scenario {}: {d} s in steps of {} s gives more than {MAX_STEPS} steps; expected step_s ≥ {} s",
                self.name,
                self.step_s,
                d / MAX_STEPS
            ));
        }
        Ok(())
    }

    /// Parses and checks a scenario. `file` names it in errors; `travel_mm` (X, Y, Z) bounds
    /// ranges and probe points when given.
    pub fn parse(
        src: &str,
        file: &str,
        travel_mm: Option<[[f64; 2]; 3]>,
    ) -> Result<Scenario, InputError> {
        let raw: File = toml::from_str(src).map_err(|e| toml_error(src, file, &e))?;
        let ck = Checker::new(src, file);
        ck.build(
            raw,
            travel_mm.unwrap_or([[f64::NEG_INFINITY, f64::INFINITY]; 3]),
        )
    }
}

/// Checks that fault sensor ids exist; the run calls it with the twin's sensor ids.
pub(crate) fn check_fault_sensors(s: &Scenario, ids: &[String]) -> Result<(), String> {
    for (i, f) in s.faults.iter().enumerate() {
        if !ids.contains(&f.sensor) {
            return Err(format!(
                "scenario {}: fault[{i}].sensor: expected one of {}, got \"{}\"",
                s.name,
                ids.join(", "),
                f.sensor
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse() {
        for name in BUILTIN {
            let s = Scenario::builtin(name).unwrap();
            assert_eq!(s.name, name);
            assert!(s.duration_s() > 3600.0);
        }
        assert!(Scenario::builtin("nope").is_none());
    }

    fn err(src: &str) -> InputError {
        Scenario::parse(
            src,
            "bad.toml",
            Some([[0.0, 800.0], [0.0, 500.0], [0.0, 500.0]]),
        )
        .unwrap_err()
    }

    /// A red-team case: a scenario of 10⁹ hours allocated 5.6 GB and aborted; durations, sampled rows
    /// and steps are bounded, each reported at its key.
    #[test]
    fn a_billion_hours_is_refused_at_the_phase_that_crosses_30_days() {
        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 600\n[[phase]]\nname = \"q\"\nduration_min = 6e10\n";
        let e = err(src);
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (8, "phase[1].duration_min"),
            "{e}"
        );
        assert!(e.message.contains("at most 43200 min (30 days)"), "{e}");
    }

    #[test]
    fn too_many_rows_or_steps_are_refused_at_sample_s_and_step_s() {
        let month = "[[phase]]\nname = \"p\"\nduration_min = 43200\n";
        // 30 days at the default 10 s and 1 s step: allowed.
        let ok = format!("[scenario]\nname = \"a\"\n{month}");
        let sc = Scenario::parse(&ok, "ok.toml", None).unwrap();
        assert!(sc.check_size().is_ok());
        let e = err(&format!("[scenario]\nname = \"a\"\nsample_s = 1\n{month}"));
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (3, "scenario.sample_s"),
            "{e}"
        );
        assert!(e.message.contains("300000 rows"), "{e}");
        let e = err(&format!(
            "[scenario]\nname = \"a\"\nstep_s = 0.01\nsample_s = 10\n{month}"
        ));
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (3, "scenario.step_s"),
            "{e}"
        );
        // Changed in code (`truepos sim --sample-s`): the run refuses it too.
        let mut fine = sc;
        fine.sample_s = 1.0;
        assert!(fine.check_size().unwrap_err().contains("300000 rows"));
    }

    #[test]
    fn type_errors_name_file_line_key_and_expectation() {
        let e =
            err("[scenario]\nname = \"a\"\n\n[[phase]]\nname = \"p\"\nduration_min = \"long\"\n");
        assert_eq!(
            (
                e.file.to_str().unwrap(),
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            ("bad.toml", 6, "duration_min")
        );
        assert!(e.message.contains("expected"), "{}", e.message);
        let e = err("[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\nspindel_rpm = 3\n");
        assert_eq!(e.position.map_or(0, |p| p.0), 6);
        assert!(
            e.message.contains("unknown field `spindel_rpm`"),
            "{}",
            e.message
        );
    }

    #[test]
    fn value_errors_name_file_line_key_and_expectation() {
        let src = "[scenario]\nname = \"a\"\n\n[[phase]]\nname = \"p\"\nduration_min = 5\n\n[[phase]]\nname = \"q\"\nduration_min = -5\n";
        let e = err(src);
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.position.map_or(0, |p| p.1),
                e.key.as_deref().unwrap_or("")
            ),
            (10, 1, "phase[1].duration_min")
        );
        assert!(e.message.contains("positive"), "{e}");
        assert!(
            e.to_string()
                .starts_with("bad.toml:10:1: `phase[1].duration_min`: expected"),
            "{e}"
        );

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[[phase.motion]]\naxis = \"X\"\npattern = \"sweep\"\nfeed_mm_min = 1000\nrange_mm = [0, 900]\n";
        let e = err(src);
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (10, "phase[0].motion[0].range_mm")
        );
        assert!(e.message.contains("[0, 800]"), "{e}");

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[probing]\nevery_min = 10\nX = [0, 400]\nY = [0, 600]\nZ = [0]\n";
        let e = err(src);
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (9, "probing.Y[1]")
        );

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[[phase.motion]]\naxis = \"W\"\npattern = \"sweep\"\n";
        let e = err(src);
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (7, "phase[0].motion[0].axis")
        );
        assert!(e.message.contains("X, Y, Z"));
    }

    /// Day/night swing: mean 20, amplitude 2, peak at 15:00. A run starting at 03:00 (12 h
    /// before the peak) starts at 18 °C and is at 22 °C 12 h later. A door opening at 60 min:
    /// −3 K for 10 min, then back with τ = 20 min: at 90 min, −3·e^{−1} = −1.1036 K.
    #[test]
    fn ambient_profile() {
        let a = Ambient {
            mean_c: 20.0,
            daily_amplitude_c: 2.0,
            daily_peak_hour: 15.0,
            drift_c_per_h: 0.0,
            events: vec![AmbientEvent {
                at_s: 3600.0,
                delta_c: -3.0,
                duration_s: Some(600.0),
                recovery_s: 1200.0,
            }],
        };
        assert!((a.at(0.0, 3.0) - 18.0).abs() < 1e-12);
        assert!((a.at(12.0 * 3600.0, 3.0) - 22.0).abs() < 1e-12);
        let flat = Ambient {
            daily_amplitude_c: 0.0,
            ..a.clone()
        };
        assert!((flat.at(3700.0, 3.0) - 17.0).abs() < 1e-12);
        assert!((flat.at(5400.0, 3.0) - (20.0 - 3.0 * (-1.0f64).exp())).abs() < 1e-12);
    }
}
