//! Operating scenarios: phases of spindle speed, axis motion, coolant and idle time, the ambient
//! temperature over the day, probing cycles and injected sensor faults, read from TOML.
//!
//! The format is documented in `docs/twin.md`; the built-in scenarios ([`Scenario::builtin`])
//! are written in it (`crates/sim/scenarios/*.toml`, copied to `examples/twin/scenarios/`).
//! Every error names the file, line, column, key and what was expected.

use std::fmt;
use std::ops::Range;

use serde::Deserialize;

use crate::machine::AXES;

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
        "spindle-warmup" => include_str!("../scenarios/spindle-warmup.toml"),
        "linear-axis" => include_str!("../scenarios/linear-axis.toml"),
        "environment" => include_str!("../scenarios/environment.toml"),
        "mixed-shift" => include_str!("../scenarios/mixed-shift.toml"),
        "mixed-shift-b" => include_str!("../scenarios/mixed-shift-b.toml"),
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

/// A bad scenario file: where and what was expected.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioError {
    /// File name (or `<builtin:name>`).
    pub file: String,
    /// Line (1-based), 0 if unknown.
    pub line: usize,
    /// Column (1-based), 0 if unknown.
    pub column: usize,
    /// The key path (`phase[2].duration_min`), empty if unknown.
    pub key: String,
    /// What was expected (or what went wrong).
    pub expected: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: ", self.file, self.line, self.column)?;
        if !self.key.is_empty() {
            write!(f, "key `{}`: ", self.key)?;
        }
        write!(f, "{}", self.expected)
    }
}

impl std::error::Error for ScenarioError {}

// ---------------------------------------------------------------------------------------------
// File form

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    scenario: Head,
    #[serde(default)]
    ambient: Option<AmbientFile>,
    #[serde(default)]
    phase: Vec<PhaseFile>,
    #[serde(default)]
    probing: Option<ProbingFile>,
    #[serde(default)]
    sensors: Option<SensorsFile>,
    #[serde(default)]
    fault: Vec<FaultFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Head {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    step_s: Option<f64>,
    #[serde(default)]
    sample_s: Option<f64>,
    #[serde(default)]
    start_hour: Option<f64>,
    #[serde(default)]
    initial_c: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AmbientFile {
    mean_c: f64,
    #[serde(default)]
    daily_amplitude_c: f64,
    #[serde(default)]
    daily_peak_hour: Option<f64>,
    #[serde(default)]
    drift_c_per_h: f64,
    #[serde(default)]
    event: Vec<EventFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EventFile {
    at_min: f64,
    delta_c: f64,
    #[serde(default)]
    duration_min: Option<f64>,
    #[serde(default)]
    recovery_min: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PhaseFile {
    name: String,
    duration_min: f64,
    #[serde(default)]
    spindle_rpm: f64,
    #[serde(default)]
    coolant: bool,
    #[serde(default)]
    probe: Option<bool>,
    #[serde(default)]
    servo_on: Option<bool>,
    #[serde(default)]
    motion: Vec<MotionFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionFile {
    axis: String,
    pattern: String,
    #[serde(default)]
    feed_mm_min: Option<f64>,
    #[serde(default)]
    range_mm: Option<[f64; 2]>,
    #[serde(default)]
    at_mm: Option<f64>,
    #[serde(default)]
    dwell_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProbingFile {
    every_min: f64,
    #[serde(default, rename = "X")]
    x: Vec<f64>,
    #[serde(default, rename = "Y")]
    y: Vec<f64>,
    #[serde(default, rename = "Z")]
    z: Vec<f64>,
    #[serde(default)]
    in_place: bool,
    #[serde(default)]
    dwell_s: Option<f64>,
    #[serde(default)]
    feed_mm_min: Option<f64>,
    #[serde(default)]
    stop_spindle: Option<bool>,
    #[serde(default)]
    noise_um: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorsFile {
    #[serde(default)]
    noise_c: Option<f64>,
    #[serde(default)]
    resolution_c: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FaultFile {
    sensor: String,
    kind: String,
    start_min: f64,
    #[serde(default)]
    end_min: Option<f64>,
    #[serde(default)]
    rail_c: Option<f64>,
    #[serde(default)]
    c_per_h: Option<f64>,
    #[serde(default)]
    amplitude_c: Option<f64>,
    #[serde(default)]
    per_hour: Option<f64>,
}

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

/// Periodic measurement of the tool-tip error, as a touch probe would (seed C, on-line
/// procedure), or by non-contact sensors at the current position (ISO 230-3).
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
    ) -> Result<Scenario, ScenarioError> {
        let raw: File = toml::from_str(src).map_err(|e| toml_error(src, file, &e))?;
        let ck = Checker::new(src, file);
        ck.build(
            raw,
            travel_mm.unwrap_or([[f64::NEG_INFINITY, f64::INFINITY]; 3]),
        )
    }
}

/// A TOML syntax or type error as a [`ScenarioError`].
pub(crate) fn toml_error(src: &str, file: &str, e: &toml::de::Error) -> ScenarioError {
    let (line, column) = e.span().map_or((0, 0), |s| line_col(src, s.start));
    ScenarioError {
        file: file.into(),
        line,
        column,
        key: e.span().map(|s| key_at(src, s)).unwrap_or_default(),
        expected: e.message().trim().to_string(),
    }
}

/// 1-based line and column of a byte offset.
fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let before = &src[..offset.min(src.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The key written on the line of a span (`key = …`), or the table header.
fn key_at(src: &str, span: Range<usize>) -> String {
    let start = src[..span.start.min(src.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let end = src[start..].find('\n').map_or(src.len(), |i| start + i);
    let line = src[start..end].trim();
    if let Some((k, _)) = line.split_once('=') {
        k.trim().to_string()
    } else {
        line.trim_matches(|c| c == '[' || c == ']').to_string()
    }
}

/// One step of a key path.
pub(crate) enum Seg<'a> {
    Key(&'a str),
    Index(usize),
}

pub(crate) struct Checker<'a> {
    src: &'a str,
    file: &'a str,
    doc: Option<toml_edit::ImDocument<&'a str>>,
}

impl<'a> Checker<'a> {
    /// A checker for the TOML text `src` of `file`.
    pub(crate) fn new(src: &'a str, file: &'a str) -> Self {
        Self {
            src,
            file,
            doc: toml_edit::ImDocument::parse(src).ok(),
        }
    }

    fn span(&self, path: &[Seg]) -> Option<Range<usize>> {
        let doc = self.doc.as_ref()?;
        self.span_in_table(doc.as_table(), path, None)
    }

    fn span_in_table(
        &self,
        t: &toml_edit::Table,
        rest: &[Seg],
        mut span: Option<Range<usize>>,
    ) -> Option<Range<usize>> {
        let mut tl: &dyn toml_edit::TableLike = t;
        for (n, seg) in rest.iter().enumerate() {
            match seg {
                Seg::Key(k) => {
                    let Some((key, next)) = tl.get_key_value(k) else {
                        return span;
                    };
                    span = key.span().or(span);
                    if n + 1 == rest.len() {
                        return span;
                    }
                    if let Some(aot) = next.as_array_of_tables() {
                        if let Some(Seg::Index(i)) = rest.get(n + 1) {
                            let Some(t2) = aot.get(*i) else { return span };
                            return self.span_in_table(t2, &rest[n + 2..], t2.span().or(span));
                        }
                    }
                    if let Some(arr) = next.as_array() {
                        if let Some(Seg::Index(i)) = rest.get(n + 1) {
                            return arr.get(*i).and_then(|v| v.span()).or(span);
                        }
                    }
                    match next.as_table_like() {
                        Some(inner) => tl = inner,
                        None => return span,
                    }
                }
                Seg::Index(_) => return span,
            }
        }
        span
    }

    pub(crate) fn err(&self, path: &[Seg], expected: impl Into<String>) -> ScenarioError {
        let (line, column) = self
            .span(path)
            .map_or((0, 0), |s| line_col(self.src, s.start));
        let mut key = String::new();
        for seg in path {
            match seg {
                Seg::Key(k) => {
                    if !key.is_empty() {
                        key.push('.');
                    }
                    key.push_str(k);
                }
                Seg::Index(i) => key.push_str(&format!("[{i}]")),
            }
        }
        ScenarioError {
            file: self.file.into(),
            line,
            column,
            key,
            expected: format!("expected {}", expected.into()),
        }
    }

    fn positive(&self, path: &[Seg], v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a positive number, got {v}")))
        }
    }

    fn non_negative(&self, path: &[Seg], v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.err(path, format!("a number ≥ 0, got {v}")))
        }
    }

    pub(crate) fn within(
        &self,
        path: &[Seg],
        v: f64,
        lo: f64,
        hi: f64,
        what: &str,
    ) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(self.err(path, format!("{what} between {lo} and {hi}, got {v}")))
        }
    }

    /// The bounds of [`Scenario::check_size`], reported at the key that crosses them: the
    /// phase whose end passes [`MAX_DURATION_S`], else `sample_s` or `step_s`.
    fn check_size(
        &self,
        phases: &[Phase],
        step_s: f64,
        sample_s: f64,
        h: &Head,
    ) -> Result<(), ScenarioError> {
        use Seg::{Index as I, Key as K};
        let mut end_s = 0.0;
        for (i, p) in phases.iter().enumerate() {
            end_s += p.duration_s;
            if end_s > MAX_DURATION_S {
                return Err(self.err(
                    &[K("phase"), I(i), K("duration_min")],
                    format!(
                        "phases lasting at most {} min (30 days) in all; this one ends at {} min",
                        MAX_DURATION_S / 60.0,
                        end_s / 60.0
                    ),
                ));
            }
        }
        // Point at the key when it is written, else at the head of the file.
        let at = |key: &'static str, given: bool| {
            if given {
                vec![K("scenario"), K(key)]
            } else {
                vec![K("scenario")]
            }
        };
        if end_s / sample_s > MAX_SAMPLES {
            return Err(self.err(
                &at("sample_s", h.sample_s.is_some()),
                format!(
                    "sample_s ≥ {} s: {end_s} s sampled every {sample_s} s gives more than {MAX_SAMPLES} rows",
                    end_s / MAX_SAMPLES
                ),
            ));
        }
        if end_s / step_s > MAX_STEPS {
            return Err(self.err(
                &at("step_s", h.step_s.is_some()),
                format!(
                    "step_s ≥ {} s: {end_s} s in steps of {step_s} s gives more than {MAX_STEPS} steps",
                    end_s / MAX_STEPS
                ),
            ));
        }
        Ok(())
    }

    fn axis(&self, path: &[Seg], name: &str) -> Result<usize, ScenarioError> {
        AXES.iter()
            .position(|a| *a == name)
            .ok_or_else(|| self.err(path, format!("one of the axes X, Y, Z, got \"{name}\"")))
    }

    /// Checks a parsed scenario section by section, in file order, and builds it; `travel`
    /// (mm per axis X, Y, Z) bounds every position.
    fn build(&self, f: File, travel: [[f64; 2]; 3]) -> Result<Scenario, ScenarioError> {
        use Seg::Key as K;
        let h = &f.scenario;
        let (step_s, sample_s) = self.step_and_sample(h)?;
        let start_hour = match h.start_hour {
            Some(v) => self.within(
                &[K("scenario"), K("start_hour")],
                v,
                0.0,
                24.0,
                "a clock hour",
            )?,
            None => 8.0,
        };
        let initial_c = match h.initial_c {
            Some(v) => Some(self.within(
                &[K("scenario"), K("initial_c")],
                v,
                -20.0,
                60.0,
                "a temperature in °C",
            )?),
            None => None,
        };
        let ambient = match &f.ambient {
            None => Ambient {
                mean_c: 20.0,
                daily_amplitude_c: 0.0,
                daily_peak_hour: 15.0,
                drift_c_per_h: 0.0,
                events: vec![],
            },
            Some(a) => self.ambient(a)?,
        };
        if f.phase.is_empty() {
            return Err(self.err(&[K("phase")], "at least one [[phase]]"));
        }
        let mut phases = Vec::new();
        for (i, ph) in f.phase.iter().enumerate() {
            phases.push(self.phase(i, ph, travel)?);
        }
        self.check_size(&phases, step_s, sample_s, h)?;
        let probing = match &f.probing {
            None => None,
            Some(p) => Some(self.probing(p, travel)?),
        };
        let (sensor_noise_c, sensor_resolution_c) = self.sensor_noise(&f.sensors)?;
        let mut faults = Vec::new();
        for (i, ft) in f.fault.iter().enumerate() {
            faults.push(self.fault(i, ft, sample_s)?);
        }
        Ok(Scenario {
            name: h.name.clone(),
            description: h.description.clone(),
            step_s,
            sample_s,
            start_hour,
            initial_c,
            ambient,
            phases,
            probing,
            sensor_noise_c,
            sensor_resolution_c,
            faults,
        })
    }

    /// The integration step (default 1 s) and the sampling period (default 10 s, at least the
    /// step), the latter a whole multiple of the former so that samples fall on steps.
    fn step_and_sample(&self, h: &Head) -> Result<(f64, f64), ScenarioError> {
        use Seg::Key as K;
        let step_s = match h.step_s {
            Some(v) => self.within(&[K("scenario"), K("step_s")], v, 0.01, 600.0, "a step in s")?,
            None => 1.0,
        };
        let sample_s = match h.sample_s {
            Some(v) => {
                let v = self.within(
                    &[K("scenario"), K("sample_s")],
                    v,
                    step_s,
                    86_400.0,
                    "a sampling period in s (at least step_s)",
                )?;
                let ratio = v / step_s;
                if (ratio - ratio.round()).abs() > 1e-9 {
                    return Err(self.err(
                        &[K("scenario"), K("sample_s")],
                        format!("a whole multiple of step_s = {step_s} s, got {v}"),
                    ));
                }
                v
            }
            None => 10.0_f64.max(step_s),
        };
        Ok((step_s, sample_s))
    }

    /// The ambient temperature: mean, daily swing, drift and events, each within a plausible
    /// range for a workshop.
    fn ambient(&self, a: &AmbientFile) -> Result<Ambient, ScenarioError> {
        use Seg::Key as K;
        let p = |k| [K("ambient"), K(k)];
        let mut events = Vec::new();
        for (i, e) in a.event.iter().enumerate() {
            events.push(self.ambient_event(i, e)?);
        }
        Ok(Ambient {
            mean_c: self.within(&p("mean_c"), a.mean_c, -20.0, 50.0, "a temperature in °C")?,
            daily_amplitude_c: self.within(
                &p("daily_amplitude_c"),
                a.daily_amplitude_c,
                0.0,
                20.0,
                "an amplitude in K",
            )?,
            daily_peak_hour: self.within(
                &p("daily_peak_hour"),
                a.daily_peak_hour.unwrap_or(15.0),
                0.0,
                24.0,
                "a clock hour",
            )?,
            drift_c_per_h: self.within(
                &p("drift_c_per_h"),
                a.drift_c_per_h,
                -5.0,
                5.0,
                "a drift in K/h",
            )?,
            events,
        })
    }

    /// Ambient event `i`: a step of at most ±30 K at a time ≥ 0, optionally held for a while and
    /// recovering over a time ≥ 0.
    fn ambient_event(&self, i: usize, e: &EventFile) -> Result<AmbientEvent, ScenarioError> {
        use Seg::{Index as I, Key as K};
        let pe = |k| [K("ambient"), K("event"), I(i), K(k)];
        Ok(AmbientEvent {
            at_s: 60.0 * self.non_negative(&pe("at_min"), e.at_min)?,
            delta_c: self.within(&pe("delta_c"), e.delta_c, -30.0, 30.0, "a change in K")?,
            duration_s: match e.duration_min {
                Some(d) => Some(60.0 * self.positive(&pe("duration_min"), d)?),
                None => None,
            },
            recovery_s: 60.0
                * self.non_negative(&pe("recovery_min"), e.recovery_min.unwrap_or(0.0))?,
        })
    }

    /// Phase `i`: its motions, a positive duration and a spindle speed up to 60 000 1/min.
    fn phase(
        &self,
        i: usize,
        ph: &PhaseFile,
        travel: [[f64; 2]; 3],
    ) -> Result<Phase, ScenarioError> {
        use Seg::{Index as I, Key as K};
        let pp = |k| [K("phase"), I(i), K(k)];
        let mut motion: Vec<Motion> = Vec::new();
        for (j, m) in ph.motion.iter().enumerate() {
            let next = self.motion(i, j, m, &motion, travel)?;
            motion.push(next);
        }
        Ok(Phase {
            name: ph.name.clone(),
            duration_s: 60.0 * self.positive(&pp("duration_min"), ph.duration_min)?,
            spindle_rpm: self.within(
                &pp("spindle_rpm"),
                ph.spindle_rpm,
                0.0,
                60_000.0,
                "a speed in 1/min",
            )?,
            coolant: ph.coolant,
            probe: ph.probe.unwrap_or(true),
            servo_on: ph.servo_on.unwrap_or(true),
            motion,
        })
    }

    /// Motion `j` of phase `i`: an axis not yet moved in this phase (`earlier`), a known
    /// pattern, range and position inside the travel, and a feed unless the axis holds.
    fn motion(
        &self,
        i: usize,
        j: usize,
        m: &MotionFile,
        earlier: &[Motion],
        travel: [[f64; 2]; 3],
    ) -> Result<Motion, ScenarioError> {
        use Seg::{Index as I, Key as K};
        let pm = |k| [K("phase"), I(i), K("motion"), I(j), K(k)];
        let axis = self.axis(&pm("axis"), &m.axis)?;
        if earlier.iter().any(|o| o.axis == axis) {
            return Err(self.err(
                &pm("axis"),
                format!("each axis once per phase; {} appears twice", m.axis),
            ));
        }
        let pattern = match m.pattern.as_str() {
            "sweep" => Pattern::Sweep,
            "random" => Pattern::Random,
            "hold" => Pattern::Hold,
            other => {
                return Err(self.err(
                    &pm("pattern"),
                    format!("one of \"sweep\", \"random\", \"hold\", got \"{other}\""),
                ))
            }
        };
        let [lo, hi] = travel[axis];
        let range_mm = match m.range_mm {
            Some([a, b]) => {
                if !(a.is_finite() && b.is_finite() && a < b && a >= lo && b <= hi) {
                    return Err(self.err(&pm("range_mm"), format!("[min, max] with min < max inside the travel [{lo}, {hi}] mm, got [{a}, {b}]")));
                }
                Some([a, b])
            }
            None => None,
        };
        let at_mm = match m.at_mm {
            Some(v) => Some(self.within(
                &pm("at_mm"),
                v,
                lo,
                hi,
                "a position inside the travel in mm",
            )?),
            None => None,
        };
        let feed_mm_min = match (m.feed_mm_min, pattern) {
            (Some(v), _) => {
                self.within(&pm("feed_mm_min"), v, 1.0, 120_000.0, "a feed in mm/min")?
            }
            (None, Pattern::Hold) => 10_000.0,
            (None, _) => {
                return Err(self.err(
                    &[K("phase"), I(i), K("motion"), I(j)],
                    "feed_mm_min for a moving axis",
                ))
            }
        };
        Ok(Motion {
            axis,
            pattern,
            feed_mm_min,
            range_mm,
            at_mm,
            dwell_s: self.non_negative(&pm("dwell_s"), m.dwell_s)?,
        })
    }

    /// The probing cycle: a grid of positions inside the travel (unless probing in place), its
    /// period, dwell, feed and repeatability.
    fn probing(&self, p: &ProbingFile, travel: [[f64; 2]; 3]) -> Result<Probing, ScenarioError> {
        use Seg::{Index as I, Key as K};
        let pk = |k| [K("probing"), K(k)];
        let mut lists = Vec::new();
        for (a, (name, list)) in [("X", &p.x), ("Y", &p.y), ("Z", &p.z)]
            .into_iter()
            .enumerate()
        {
            if list.is_empty() && !p.in_place {
                return Err(self.err(
                    &[K("probing")],
                    format!("a list of {name} positions (mm) for the probing grid"),
                ));
            }
            for (k, v) in list.iter().enumerate() {
                self.within(
                    &[K("probing"), K(name), I(k)],
                    *v,
                    travel[a][0],
                    travel[a][1],
                    "a position inside the travel in mm",
                )?;
            }
            lists.push(list.clone());
        }
        Ok(Probing {
            every_s: 60.0 * self.positive(&pk("every_min"), p.every_min)?,
            points: probing_grid(&lists),
            in_place: p.in_place,
            dwell_s: self.non_negative(&pk("dwell_s"), p.dwell_s.unwrap_or(3.0))?,
            feed_mm_min: self.within(
                &pk("feed_mm_min"),
                p.feed_mm_min.unwrap_or(10_000.0),
                1.0,
                120_000.0,
                "a feed in mm/min",
            )?,
            stop_spindle: p.stop_spindle.unwrap_or(!p.in_place),
            noise_um: self.within(
                &pk("noise_um"),
                p.noise_um.unwrap_or(0.5),
                0.0,
                100.0,
                "a repeatability in µm",
            )?,
        })
    }

    /// The temperature sensors' noise σ and resolution in K (defaults 0.02 and 0.01).
    fn sensor_noise(&self, s: &Option<SensorsFile>) -> Result<(f64, f64), ScenarioError> {
        use Seg::Key as K;
        Ok(match s {
            None => (0.02, 0.01),
            Some(s) => (
                self.within(
                    &[K("sensors"), K("noise_c")],
                    s.noise_c.unwrap_or(0.02),
                    0.0,
                    5.0,
                    "a noise σ in K",
                )?,
                self.within(
                    &[K("sensors"), K("resolution_c")],
                    s.resolution_c.unwrap_or(0.01),
                    0.0,
                    5.0,
                    "a resolution in K",
                )?,
            ),
        })
    }

    /// Fault `i`: a time window (an end after the start, if any) and a known kind with the
    /// settings that kind needs; a spike rate becomes a probability per sample.
    fn fault(&self, i: usize, ft: &FaultFile, sample_s: f64) -> Result<Fault, ScenarioError> {
        use Seg::{Index as I, Key as K};
        let pf = |k| [K("fault"), I(i), K(k)];
        let start_s = 60.0 * self.non_negative(&pf("start_min"), ft.start_min)?;
        let end_s = match ft.end_min {
            Some(e) if e * 60.0 > start_s && e.is_finite() => Some(e * 60.0),
            Some(e) => {
                return Err(self.err(
                    &pf("end_min"),
                    format!("an end after start_min = {}, got {e}", ft.start_min),
                ))
            }
            None => None,
        };
        let need = |k: &'static str, v: Option<f64>| {
            v.ok_or_else(|| {
                self.err(
                    &[K("fault"), I(i)],
                    format!("`{k}` for a {} fault", ft.kind),
                )
            })
        };
        let kind = match ft.kind.as_str() {
            "open-circuit" => FaultKind::OpenCircuit {
                // What an open input reads: a rail far outside any valid range, but a number.
                rail_c: self.within(
                    &pf("rail_c"),
                    ft.rail_c.unwrap_or(850.0),
                    -1.0e4,
                    1.0e4,
                    "an open-circuit reading in °C",
                )?,
            },
            "stuck" => FaultKind::Stuck,
            "drift" => FaultKind::Drift {
                c_per_h: self.within(
                    &pf("c_per_h"),
                    need("c_per_h", ft.c_per_h)?,
                    -50.0,
                    50.0,
                    "a drift in K/h",
                )?,
            },
            "spikes" => {
                let per_hour = self.positive(&pf("per_hour"), need("per_hour", ft.per_hour)?)?;
                FaultKind::Spikes {
                    amplitude_c: self.within(
                        &pf("amplitude_c"),
                        need("amplitude_c", ft.amplitude_c)?,
                        -500.0,
                        500.0,
                        "a spike height in K",
                    )?,
                    probability: (per_hour * sample_s / 3600.0).min(1.0),
                }
            }
            other => {
                return Err(self.err(
                    &pf("kind"),
                    format!(
                    "one of \"open-circuit\", \"stuck\", \"drift\", \"spikes\", got \"{other}\""
                ),
                ))
            }
        };
        Ok(Fault {
            sensor: ft.sensor.clone(),
            kind,
            start_s,
            end_s,
        })
    }
}

/// The probing points from the X, Y and Z lists, in serpentine order: Y rows alternate their
/// X direction, which keeps the moves short.
fn probing_grid(lists: &[Vec<f64>]) -> Vec<[f64; 3]> {
    let mut points = Vec::new();
    for &z in &lists[2] {
        for (yi, &y) in lists[1].iter().enumerate() {
            let xs: Vec<f64> = if yi % 2 == 0 {
                lists[0].clone()
            } else {
                lists[0].iter().rev().copied().collect()
            };
            for x in xs {
                points.push([x, y, z]);
            }
        }
    }
    points
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

    fn err(src: &str) -> ScenarioError {
        Scenario::parse(
            src,
            "bad.toml",
            Some([[0.0, 800.0], [0.0, 500.0], [0.0, 500.0]]),
        )
        .unwrap_err()
    }

    /// Issue 11: a scenario of 10⁹ hours allocated 5.6 GB and aborted; durations, sampled rows
    /// and steps are bounded, each reported at its key.
    #[test]
    fn a_billion_hours_is_refused_at_the_phase_that_crosses_30_days() {
        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 600\n[[phase]]\nname = \"q\"\nduration_min = 6e10\n";
        let e = err(src);
        assert_eq!(
            (e.line, e.key.as_str()),
            (8, "phase[1].duration_min"),
            "{e}"
        );
        assert!(e.expected.contains("at most 43200 min (30 days)"), "{e}");
    }

    #[test]
    fn too_many_rows_or_steps_are_refused_at_sample_s_and_step_s() {
        let month = "[[phase]]\nname = \"p\"\nduration_min = 43200\n";
        // 30 days at the default 10 s and 1 s step: allowed.
        let ok = format!("[scenario]\nname = \"a\"\n{month}");
        let sc = Scenario::parse(&ok, "ok.toml", None).unwrap();
        assert!(sc.check_size().is_ok());
        let e = err(&format!("[scenario]\nname = \"a\"\nsample_s = 1\n{month}"));
        assert_eq!((e.line, e.key.as_str()), (3, "scenario.sample_s"), "{e}");
        assert!(e.expected.contains("300000 rows"), "{e}");
        let e = err(&format!(
            "[scenario]\nname = \"a\"\nstep_s = 0.01\nsample_s = 10\n{month}"
        ));
        assert_eq!((e.line, e.key.as_str()), (3, "scenario.step_s"), "{e}");
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
            (e.file.as_str(), e.line, e.key.as_str()),
            ("bad.toml", 6, "duration_min")
        );
        assert!(e.expected.contains("expected"), "{}", e.expected);
        let e = err("[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\nspindel_rpm = 3\n");
        assert_eq!(e.line, 6);
        assert!(
            e.expected.contains("unknown field `spindel_rpm`"),
            "{}",
            e.expected
        );
    }

    #[test]
    fn value_errors_name_file_line_key_and_expectation() {
        let src = "[scenario]\nname = \"a\"\n\n[[phase]]\nname = \"p\"\nduration_min = 5\n\n[[phase]]\nname = \"q\"\nduration_min = -5\n";
        let e = err(src);
        assert_eq!(
            (e.line, e.column, e.key.as_str()),
            (10, 1, "phase[1].duration_min")
        );
        assert!(e.expected.contains("positive"), "{e}");
        assert!(
            e.to_string()
                .starts_with("bad.toml:10:1: key `phase[1].duration_min`"),
            "{e}"
        );

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[[phase.motion]]\naxis = \"X\"\npattern = \"sweep\"\nfeed_mm_min = 1000\nrange_mm = [0, 900]\n";
        let e = err(src);
        assert_eq!(
            (e.line, e.key.as_str()),
            (10, "phase[0].motion[0].range_mm")
        );
        assert!(e.expected.contains("[0, 800]"), "{e}");

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[probing]\nevery_min = 10\nX = [0, 400]\nY = [0, 600]\nZ = [0]\n";
        let e = err(src);
        assert_eq!((e.line, e.key.as_str()), (9, "probing.Y[1]"));

        let src = "[scenario]\nname = \"a\"\n[[phase]]\nname = \"p\"\nduration_min = 5\n[[phase.motion]]\naxis = \"W\"\npattern = \"sweep\"\n";
        let e = err(src);
        assert_eq!((e.line, e.key.as_str()), (7, "phase[0].motion[0].axis"));
        assert!(e.expected.contains("X, Y, Z"));
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
