//! The dynamic model file (JSON): what a fitted [`truepos_model::DynamicModel`] needs to run on a
//! control, with its provenance and validation figures, readable by a person.
//!
//! ```json
//! { "format": "truepos-dynamic-model", "version": 1, "machine": "fl-thermal",
//!   "inputs": [{"name": "t5_c", "kind": "temperature"}, {"name": "spindle_rpm", "kind": "operating"}],
//!   "temperature_rise": true, "temperature_taus_s": [900, 3600], "rate_taus_s": [1800],
//!   "operating_taus_s": [300, …], "operating_square": true,
//!   "features": ["rise(t5_c)", …],
//!   "outputs": [{"name": "ch1_um", "intercept_um": 0.1, "coefficients": [ … one per feature … ]}],
//!   "provenance": {…}, "validation": {…} }
//! ```
//! Outputs are errors (actual − nominal) in µm; the compensation is their negative.

use serde::{Deserialize, Serialize};
use truepos_model::{DynamicModel, FeatureBank, FeatureSpec};

use crate::dataset::InputKind;

/// The `format` value.
pub const FORMAT: &str = "truepos-dynamic-model";
/// The `version` value this crate writes and reads.
pub const VERSION: u32 = 1;

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
}

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DynamicModelFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
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
    /// Feature names, for people (checked against the spec on load).
    pub features: Vec<String>,
    /// Outputs.
    pub outputs: Vec<OutputEntry>,
    /// Where it came from (runs, split, choices).
    pub provenance: serde_json::Value,
    /// Validation figures.
    pub validation: serde_json::Value,
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
            machine: machine.into(),
            features: model
                .bank()
                .features()
                .iter()
                .map(|f| f.name(&inputs[f.input].name))
                .collect(),
            inputs,
            temperature_rise: spec.temperature_rise,
            temperature_taus_s: spec.temperature_taus_s.clone(),
            rate_taus_s: spec.rate_taus_s.clone(),
            operating_taus_s: spec.operating_taus_s.clone(),
            operating_square: spec.operating_square,
            outputs: outputs
                .iter()
                .enumerate()
                .map(|(k, name)| OutputEntry {
                    name: name.clone(),
                    intercept_um: model.intercepts()[k],
                    coefficients: model.coefficients()[k * n..(k + 1) * n].to_vec(),
                })
                .collect(),
            provenance,
            validation,
        }
    }

    /// Builds the real-time model, checking format, version, input order and feature count.
    pub fn to_model(&self) -> Result<DynamicModel, String> {
        if self.format != FORMAT || self.version != VERSION {
            return Err(format!(
                "`format`/`version`: expected \"{FORMAT}\" version {VERSION}, got \"{}\" version {}",
                self.format, self.version
            ));
        }
        let temperatures = self
            .inputs
            .iter()
            .take_while(|i| i.kind == InputKind::Temperature)
            .count();
        if self.inputs[temperatures..]
            .iter()
            .any(|i| i.kind != InputKind::Operating)
        {
            return Err("`inputs`: temperatures must come before operating inputs".into());
        }
        let bank = FeatureBank::new(FeatureSpec {
            temperatures,
            operating: self.inputs.len() - temperatures,
            temperature_rise: self.temperature_rise,
            temperature_taus_s: self.temperature_taus_s.clone(),
            rate_taus_s: self.rate_taus_s.clone(),
            operating_taus_s: self.operating_taus_s.clone(),
            operating_square: self.operating_square,
        })
        .map_err(|e| format!("time constants: {e}"))?;
        let n = bank.features().len();
        if self.features.len() != n {
            return Err(format!(
                "`features`: the spec gives {n} features, the file lists {}",
                self.features.len()
            ));
        }
        let mut flat = Vec::new();
        for (k, o) in self.outputs.iter().enumerate() {
            if o.coefficients.len() != n {
                return Err(format!(
                    "`outputs[{k}].coefficients`: expected {n} values, got {}",
                    o.coefficients.len()
                ));
            }
            flat.extend_from_slice(&o.coefficients);
        }
        let intercepts = self.outputs.iter().map(|o| o.intercept_um).collect();
        DynamicModel::new(bank, intercepts, flat).map_err(|e| format!("`outputs`: {e}"))
    }

    /// Reads the JSON text; errors name line and column.
    pub fn from_json(text: &str) -> Result<Self, String> {
        serde_json::from_str(text).map_err(|e| format!("{}:{}: {e}", e.line(), e.column()))
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
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
        };
        let model = DynamicModel::new(
            FeatureBank::new(spec).unwrap(),
            vec![0.5],
            vec![1.0, 2.0, 3e-3, 4e-7],
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
                "lp300(spindle_rpm^2)"
            ]
        );
        let back = DynamicModelFile::from_json(&file.to_json()).unwrap();
        assert_eq!(back.to_model().unwrap(), model);
        let mut bad = back.clone();
        bad.outputs[0].coefficients.pop();
        assert!(bad
            .to_model()
            .unwrap_err()
            .contains("expected 4 values, got 3"));
        bad.version = 2;
        assert!(bad.to_model().is_err());
        assert!(DynamicModelFile::from_json("{\n\"format\": 3}")
            .unwrap_err()
            .starts_with("2:"));
    }
}
