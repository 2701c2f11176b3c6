//! The model file's filtered form (JSON): what a fitted [`truepos_model::DynamicModel`] needs to
//! run on a control, with its provenance and validation figures, readable by a person.
//!
//! ```json
//! { "format": "truepos-model", "version": 2, "form": "filtered", "machine": "fl-thermal",
//!   "inputs": [{"name": "t5_c", "kind": "temperature"}, {"name": "spindle_rpm", "kind": "operating"}],
//!   "temperature_rise": true, "temperature_taus_s": [900, 3600, 28800], "rate_taus_s": [1800],
//!   "operating_taus_s": [300, …], "operating_square": true, "rise_while_running": true,
//!   "features": ["rise(t5_c)", …],
//!   "outputs": [{"name": "ch1_um", "intercept_um": 0.1, "coefficients": [ … one per feature … ]}],
//!   "provenance": {…}, "validation": {…} }
//! ```
//! Outputs are errors (actual − nominal) in µm; the compensation is their negative. For the
//! runtime each output names the machine axis it compensates (`"axis": "Z"`; by default an
//! output called `Z`, `Z_um` or `dz_um` serves axis Z), and the file may carry the
//! axis-combination index (`"axis_index": [101, 102, 103]`).
//!
//! `truepos fit` writes this file; every user (`truepos run`, `eval`, `report`, the LinuxCNC
//! component) loads it beside the position model files ([`super::position`]) through
//! [`super::load`], bound to the machine as a [`truepos_model::BoundDynamicModel`]:
//! every input must be one of its channels, every mapped output one of its axes.

use std::path::Path;

use serde::{Deserialize, Serialize};
use truepos_model::{
    BoundDynamicModel, Channels, DynamicModel, FeatureBank, FeatureSpec, Machine, MachineInput,
};

use super::envelope::EnvelopeEntry;
use crate::error::{json_key_offset, parse_json, read_text};
use truepos_files::InputError;

/// A problem at a key of the file (`outputs[0].coefficients`): the key and what was expected.
type Problem = (String, String);

/// What a model input is: a temperature (°C, filtered as the rise since the first cycle) or an
/// operating-state channel (spindle speed, axis speed; filtered as is).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InputKind {
    /// A temperature in °C.
    Temperature,
    /// An operating-state quantity in its own unit.
    Operating,
}

/// The `format` value of files written before both forms shared one (read as version 1).
pub const LEGACY_FORMAT: &str = "truepos-dynamic-model";
/// The `format`, `version` and `form` this crate writes: the model file's, of the filtered
/// form.
pub use super::{FORMAT, FORM_FILTERED, VERSION};

/// One input the model reads every cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputEntry {
    /// Channel name (a run column, a machine channel id).
    pub name: String,
    /// Temperature (°C, taken relative to the first cycle) or operating state.
    pub kind: InputKind,
}

/// One output: intercept and one coefficient per feature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputEntry {
    /// Target name.
    pub name: String,
    /// µm.
    pub intercept_um: f64,
    /// One per entry of `features`, in µm per feature unit.
    pub coefficients: Vec<f64>,
    /// The machine axis whose error this output is (see the module documentation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<String>,
}

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DynamicModelFile {
    /// [`FORMAT`] (or [`LEGACY_FORMAT`] in version 1).
    pub format: String,
    /// [`VERSION`] (or 1 with [`LEGACY_FORMAT`]).
    pub version: u32,
    /// [`FORM_FILTERED`] (absent in version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<String>,
    /// The machine it belongs to.
    pub machine: String,
    /// Inputs, temperatures first, in the order the cycle gives them.
    pub inputs: Vec<InputEntry>,
    /// See [`FeatureSpec::temperature_rise`].
    pub temperature_rise: bool,
    /// See [`FeatureSpec::temperature_taus_s`].
    pub temperature_taus_s: Vec<f64>,
    /// See [`FeatureSpec::rate_taus_s`].
    pub rate_taus_s: Vec<f64>,
    /// See [`FeatureSpec::operating_taus_s`].
    pub operating_taus_s: Vec<f64>,
    /// See [`FeatureSpec::operating_square`].
    pub operating_square: bool,
    /// See [`FeatureSpec::rise_while_running`] (absent in older files: false).
    #[serde(default)]
    pub rise_while_running: bool,
    /// Feature names, for people (checked against the spec on load).
    pub features: Vec<String>,
    /// Outputs.
    pub outputs: Vec<OutputEntry>,
    /// The axis-combination index of the axes it serves; `None` = path 1's axes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_index: Option<Vec<u32>>,
    /// Where it came from (runs, split, choices).
    pub provenance: serde_json::Value,
    /// Validation figures.
    pub validation: serde_json::Value,
    /// Where it was trained (`truepos_model::envelope`), outputs by their names; absent: not
    /// known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training_envelope: Option<EnvelopeEntry>,
}

impl DynamicModelFile {
    /// Describes a model.
    pub fn new(
        machine: &str,
        model: &DynamicModel,
        inputs: Vec<InputEntry>,
        outputs: &[String],
        provenance: serde_json::Value,
        validation: serde_json::Value,
    ) -> Self {
        let spec = model.bank().spec();
        let n = model.bank().features().len();
        Self {
            format: FORMAT.into(),
            version: VERSION,
            form: Some(FORM_FILTERED.into()),
            machine: machine.into(),
            features: model
                .bank()
                .features()
                .iter()
                .map(|f| f.name(|i| &inputs[i].name))
                .collect(),
            inputs,
            temperature_rise: spec.temperature_rise,
            temperature_taus_s: spec.temperature_taus_s.clone(),
            rate_taus_s: spec.rate_taus_s.clone(),
            operating_taus_s: spec.operating_taus_s.clone(),
            operating_square: spec.operating_square,
            rise_while_running: spec.rise_while_running,
            outputs: outputs
                .iter()
                .enumerate()
                .map(|(k, name)| OutputEntry {
                    name: name.clone(),
                    intercept_um: model.intercepts()[k],
                    coefficients: model.coefficients()[k * n..(k + 1) * n].to_vec(),
                    axis: None,
                })
                .collect(),
            axis_index: None,
            provenance,
            validation,
            training_envelope: None,
        }
    }

    /// Builds the real-time model, checking format, version, input order and feature count;
    /// an error names `path` and the key of the problem.
    pub fn to_model(&self, path: &Path) -> Result<DynamicModel, InputError> {
        self.check()
            .map_err(|(key, message)| keyed(path, key, message))
    }

    /// [`Self::to_model`], naming the key of the problem.
    fn check(&self) -> Result<DynamicModel, Problem> {
        let legacy = self.format == LEGACY_FORMAT;
        if !legacy && self.format != FORMAT {
            return Err((
                "format".into(),
                format!("expected \"{FORMAT}\", got \"{}\"", self.format),
            ));
        }
        let version = if legacy { 1 } else { VERSION };
        if self.version != version {
            return Err((
                "version".into(),
                format!("expected {version}, got {}", self.version),
            ));
        }
        let form = if legacy { None } else { Some(FORM_FILTERED) };
        if self.form.as_deref() != form {
            return Err((
                "form".into(),
                match form {
                    Some(f) => format!("expected \"{f}\", got {:?}", self.form),
                    None => format!("no `form` in version 1, got {:?}", self.form),
                },
            ));
        }
        let temperatures = self
            .inputs
            .iter()
            .take_while(|i| i.kind == InputKind::Temperature)
            .count();
        if let Some(i) = self.inputs[temperatures..]
            .iter()
            .position(|i| i.kind != InputKind::Operating)
        {
            let i = temperatures + i;
            return Err((
                format!("inputs[{i}].kind"),
                format!(
                    "expected temperatures before operating inputs, got temperature `{}` after operating input `{}`",
                    self.inputs[i].name,
                    self.inputs[i - 1].name
                ),
            ));
        }
        for (key, taus) in [
            ("temperature_taus_s", &self.temperature_taus_s),
            ("rate_taus_s", &self.rate_taus_s),
            ("operating_taus_s", &self.operating_taus_s),
        ] {
            if let Some(j) = taus.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
                return Err((
                    format!("{key}[{j}]"),
                    format!("expected a positive time constant in s, got {}", taus[j]),
                ));
            }
        }
        let bank = FeatureBank::new(FeatureSpec {
            temperatures,
            operating: self.inputs.len() - temperatures,
            temperature_rise: self.temperature_rise,
            temperature_taus_s: self.temperature_taus_s.clone(),
            rate_taus_s: self.rate_taus_s.clone(),
            operating_taus_s: self.operating_taus_s.clone(),
            operating_square: self.operating_square,
            rise_while_running: self.rise_while_running,
        })
        .map_err(|e| ("temperature_taus_s".to_string(), e.to_string()))?;
        let n = bank.features().len();
        if self.features.len() != n {
            return Err((
                "features".into(),
                format!(
                    "expected {n} names (one per feature the inputs and time constants give), got {}",
                    self.features.len()
                ),
            ));
        }
        let mut flat = Vec::new();
        for (k, o) in self.outputs.iter().enumerate() {
            if o.coefficients.len() != n {
                return Err((
                    format!("outputs[{k}].coefficients"),
                    format!(
                        "expected {n} values (one per feature), got {}",
                        o.coefficients.len()
                    ),
                ));
            }
            flat.extend_from_slice(&o.coefficients);
        }
        let intercepts = self.outputs.iter().map(|o| o.intercept_um).collect();
        DynamicModel::new(bank, intercepts, flat).map_err(|e| ("outputs".into(), e.to_string()))
    }

    /// Reads the JSON text (`path` names it in errors); errors name line, column and key.
    pub fn from_json(path: &Path, text: &str) -> Result<Self, InputError> {
        parse_json(path, text)
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

/// The axis a target or output named `name` serves by its name alone: `Z`, `Z_um` or `dz_um`
/// (case-insensitive) serve axis Z.
pub fn axis_named_like(name: &str, machine: &Machine) -> Option<usize> {
    machine.axes.iter().position(|a| names_axis(name, &a.name))
}

/// Whether a target or output named `name` serves the axis named `axis` by its name alone
/// (`Z`, `Z_um` or `dz_um` for Z, case-insensitive).
pub fn names_axis(name: &str, axis: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    let stem = lower.strip_suffix("_um").unwrap_or(&lower);
    let axis = axis.to_ascii_lowercase();
    stem == axis || stem.strip_prefix('d') == Some(axis.as_str())
}

impl DynamicModelFile {
    /// The axis an output serves: its `axis`, else an axis named like the output (`Z`, `Z_um`,
    /// `dz_um`, case-insensitive).
    fn output_axis(&self, k: usize, machine: &Machine) -> Result<Option<usize>, Problem> {
        let o = &self.outputs[k];
        if let Some(name) = &o.axis {
            return machine.axis_index(name).map(Some).ok_or_else(|| {
                let axes: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
                (
                    format!("outputs[{k}].axis"),
                    format!(
                        "machine `{}` has no axis `{name}`; expected one of: {}",
                        machine.name,
                        axes.join(", ")
                    ),
                )
            });
        }
        Ok(axis_named_like(&o.name, machine))
    }

    /// Binds the model to a machine: same machine name, every input a channel of the right kind,
    /// every output mapped to a distinct axis or reported unused, at least one output applied.
    /// Errors name the file and the key; [`parse`] and [`load`] also give line and column.
    pub fn bind(&self, path: &Path, machine: &Machine) -> Result<BoundDynamicModel, InputError> {
        self.bind_checked(path, machine)
            .map_err(|(key, message)| keyed(path, key, message))
    }

    /// [`Self::bind`], naming the key of the problem.
    fn bind_checked(&self, path: &Path, machine: &Machine) -> Result<BoundDynamicModel, Problem> {
        if self.machine != machine.name {
            return Err((
                "machine".into(),
                format!(
                    "expected `{}` (the machine it is loaded for), got `{}`",
                    machine.name, self.machine
                ),
            ));
        }
        let model = self.check()?;
        let mut inputs = Vec::with_capacity(self.inputs.len());
        for (i, input) in self.inputs.iter().enumerate() {
            let (found, kind, names): (_, _, Vec<&str>) = match input.kind {
                InputKind::Temperature => (
                    machine
                        .temperature_index(&input.name)
                        .map(MachineInput::Temperature),
                    "temperature channel",
                    machine.temperatures.iter().map(|t| t.id.as_str()).collect(),
                ),
                InputKind::Operating => (
                    machine
                        .operating_index(&input.name)
                        .map(MachineInput::Operating),
                    "operating channel",
                    machine.operating.iter().map(|o| o.id.as_str()).collect(),
                ),
            };
            inputs.push(found.ok_or_else(|| {
                (
                    format!("inputs[{i}].name"),
                    format!(
                        "machine `{}` has no {kind} `{}`; expected one of: {}",
                        machine.name,
                        input.name,
                        names.join(", ")
                    ),
                )
            })?);
        }
        let mut axes = Vec::with_capacity(self.outputs.len());
        let mut unused_outputs = Vec::new();
        for k in 0..self.outputs.len() {
            let axis = self.output_axis(k, machine)?;
            if let Some(a) = axis {
                if let Some(j) = axes.iter().position(|b| *b == Some(a)) {
                    return Err((
                        format!("outputs[{k}]"),
                        format!(
                            "`{}` and `{}` both compensate axis {}; give each output its own `axis`",
                            self.outputs[j].name, self.outputs[k].name, machine.axes[a].name
                        ),
                    ));
                }
            } else {
                unused_outputs.push(self.outputs[k].name.clone());
            }
            axes.push(axis);
        }
        if axes.iter().all(Option::is_none) {
            return Err((
                "outputs".into(),
                format!(
                    "no output names an axis of machine `{}`; give one an `axis` (or fit with `--axis {}=<axis>`)",
                    machine.name,
                    self.outputs.first().map_or("<target>", |o| o.name.as_str())
                ),
            ));
        }
        let name = path
            .file_stem()
            .map_or_else(|| "dynamic".into(), |s| s.to_string_lossy().into_owned());
        let channels = Channels {
            temperatures: machine.temperatures.len(),
            operating: machine.operating.len(),
            axes: machine.axes.len(),
        };
        // Everything the core checks was checked above with names; what is left is an axis
        // beyond the core's MAX_AXES.
        let mut bound =
            BoundDynamicModel::new(name, model, inputs, axes.clone(), unused_outputs, channels)
                .map_err(|e| ("outputs".to_string(), e.to_string()))?;
        if let Some(env) = &self.training_envelope {
            let output_axis = |name: &str| {
                let k = self.outputs.iter().position(|o| o.name == name)?;
                axes[k]
            };
            bound.set_envelope(Some(env.bind(machine, output_axis)?));
        }
        Ok(bound)
    }
}

/// Whether a model file's text is a filtered model file: JSON of the filtered `form`, or of
/// version 1's own `format`.
pub fn is_dynamic(text: &str) -> bool {
    #[derive(Deserialize)]
    struct Head {
        format: String,
        #[serde(default)]
        form: Option<String>,
    }
    serde_json::from_str::<Head>(text)
        .is_ok_and(|h| h.format == LEGACY_FORMAT || h.form.as_deref() == Some(FORM_FILTERED))
}

/// Reads a dynamic model file and binds it to the machine.
pub fn load(path: &Path, machine: &Machine) -> Result<BoundDynamicModel, InputError> {
    parse(path, &read_text(path, truepos_files::MODEL)?, machine)
}

/// Parses a dynamic model file's text (`path` names it in errors) and binds it to the machine.
/// Every error names the file, line, column and key and what was expected.
pub fn parse(path: &Path, text: &str, machine: &Machine) -> Result<BoundDynamicModel, InputError> {
    parse_entry(path, text, machine).map(|(bound, _)| bound)
}

/// [`parse`], with the axis-combination index the file carries, if any.
pub fn parse_entry(
    path: &Path,
    text: &str,
    machine: &Machine,
) -> Result<(BoundDynamicModel, Option<Vec<u32>>), InputError> {
    let file: DynamicModelFile = parse_json(path, text)?;
    let bound = file.bind_checked(path, machine).map_err(|(key, message)| {
        let at = json_key_offset(text, &key);
        InputError::at_span(path, text, at..at, key, message)
    })?;
    Ok((bound, file.axis_index))
}

/// An error at a key of the file, without a position (the text is not at hand).
fn keyed(path: &Path, key: String, message: String) -> InputError {
    InputError {
        file: path.to_path_buf(),
        position: None,
        key: Some(key).filter(|k| !k.is_empty()),
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_gives_the_same_model() {
        let spec = FeatureSpec {
            temperatures: 1,
            operating: 1,
            temperature_rise: true,
            temperature_taus_s: vec![600.0],
            rate_taus_s: vec![],
            operating_taus_s: vec![300.0],
            operating_square: true,
            rise_while_running: true,
        };
        let model = DynamicModel::new(
            FeatureBank::new(spec).unwrap(),
            vec![0.5],
            vec![1.0, 2.0, 3e-3, 4e-7, 0.25],
        )
        .unwrap();
        let inputs = vec![
            InputEntry {
                name: "t5_c".into(),
                kind: InputKind::Temperature,
            },
            InputEntry {
                name: "spindle_rpm".into(),
                kind: InputKind::Operating,
            },
        ];
        let file = DynamicModelFile::new(
            "m",
            &model,
            inputs,
            &["dz_um".into()],
            serde_json::json!({}),
            serde_json::json!({}),
        );
        assert_eq!(
            file.features,
            vec![
                "rise(t5_c)",
                "lp600(t5_c)",
                "lp300(spindle_rpm)",
                "lp300(spindle_rpm^2)",
                "rise(t5_c)·running(spindle_rpm)"
            ]
        );
        let path = Path::new("d.json");
        let back = DynamicModelFile::from_json(path, &file.to_json()).unwrap();
        assert_eq!(back.to_model(path).unwrap(), model);
        let mut bad = back.clone();
        bad.outputs[0].coefficients.pop();
        assert!(bad
            .to_model(path)
            .unwrap_err()
            .to_string()
            .contains("expected 5 values (one per feature), got 4"));
        bad.version = 3;
        assert!(bad.to_model(path).is_err());
        bad.version = VERSION;
        bad.form = None;
        assert!(bad.to_model(path).unwrap_err().to_string().contains("form"));
        assert!(DynamicModelFile::from_json(path, "{\n\"format\": 3}")
            .unwrap_err()
            .to_string()
            .starts_with("d.json:2:"));
    }
}
