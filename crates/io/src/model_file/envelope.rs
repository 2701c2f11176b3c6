//! The training envelope in a model file (`truepos_model::envelope`): the range of every input
//! the model read in training and the largest |prediction| of every output, written by
//! `truepos fit` and read by every loader. Both model files carry it under the same key,
//! `training_envelope`, with the same two tables — TOML:
//!
//! ```toml
//! [training_envelope]
//! inputs = { x_slide_top = [19.8, 24.1], spindle_rpm = [0.0, 12000.0] }
//! max_abs_prediction_um = { Z = 38.2 }
//! ```
//!
//! and the same as a JSON object in a fitted dynamic model. Inputs are named by their machine
//! channel ids (temperature or operating), outputs by the axis (a model of a machine file) or
//! by the output's name (a fitted dynamic model). A file without it loads as before: nothing is
//! clamped, nothing capped.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use truepos_model::envelope::TrainingEnvelope;
use truepos_model::{Machine, MachineInput};

/// `training_envelope` as written.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvelopeEntry {
    /// Per input the model reads: [min, max] in training, in the channel's unit.
    #[serde(default)]
    pub inputs: BTreeMap<String, [f64; 2]>,
    /// Per output: the largest |predicted error| on the training rows, µm.
    #[serde(default)]
    pub max_abs_prediction_um: BTreeMap<String, f64>,
}

/// A problem with the key it concerns.
pub type Problem = (String, String);

impl EnvelopeEntry {
    /// Binds the envelope to a machine: every input a machine channel, every output an axis
    /// (`output_axis` maps an output's name; `None`: not applied, skipped), every figure
    /// finite and every range ordered.
    pub fn bind(
        &self,
        machine: &Machine,
        output_axis: impl Fn(&str) -> Option<usize>,
    ) -> Result<TrainingEnvelope, Problem> {
        let mut env = TrainingEnvelope {
            temperatures: vec![None; machine.temperatures.len()],
            operating: vec![None; machine.operating.len()],
            max_abs_um: vec![None; machine.axes.len()],
        };
        for (name, &[lo, hi]) in &self.inputs {
            let key = format!("training_envelope.inputs.{name}");
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err((
                    key,
                    format!("expected [min, max], finite and ordered, got [{lo}, {hi}]"),
                ));
            }
            let slot = match channel(machine, name) {
                Some(MachineInput::Temperature(c)) => &mut env.temperatures[c],
                Some(MachineInput::Operating(c)) => &mut env.operating[c],
                None => {
                    return Err((
                        key,
                        format!(
                            "machine `{}` has no temperature or operating channel `{name}`",
                            machine.name
                        ),
                    ))
                }
            };
            *slot = Some((lo, hi));
        }
        for (name, &m) in &self.max_abs_prediction_um {
            let key = format!("training_envelope.max_abs_prediction_um.{name}");
            if !(m.is_finite() && m >= 0.0) {
                return Err((key, format!("expected a finite value ≥ 0 µm, got {m}")));
            }
            if let Some(a) = output_axis(name) {
                env.max_abs_um[a] = Some(m);
            }
        }
        Ok(env)
    }

    /// Describes a bound envelope by the machine's names (outputs by axis name).
    pub fn from_envelope(env: &TrainingEnvelope, machine: &Machine) -> Self {
        let mut inputs = BTreeMap::new();
        for (c, r) in env.temperatures.iter().enumerate() {
            if let (Some((lo, hi)), Some(t)) = (r, machine.temperatures.get(c)) {
                inputs.insert(t.id.clone(), [*lo, *hi]);
            }
        }
        for (c, r) in env.operating.iter().enumerate() {
            if let (Some((lo, hi)), Some(o)) = (r, machine.operating.get(c)) {
                inputs.insert(o.id.clone(), [*lo, *hi]);
            }
        }
        let max_abs_prediction_um = env
            .max_abs_um
            .iter()
            .enumerate()
            .filter_map(|(a, m)| Some((machine.axes.get(a)?.name.clone(), (*m)?)))
            .collect();
        Self {
            inputs,
            max_abs_prediction_um,
        }
    }
}

/// The machine channel called `id`: a temperature channel first, else an operating one.
fn channel(machine: &Machine, id: &str) -> Option<MachineInput> {
    machine
        .temperature_index(id)
        .map(MachineInput::Temperature)
        .or_else(|| machine.operating_index(id).map(MachineInput::Operating))
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    fn repo(p: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
    }

    fn with_envelope(section: &str) -> Result<truepos_model::Model, truepos_files::InputError> {
        let machine = crate::machine_file::load(&repo("examples/vmc3/machine.toml"))
            .unwrap()
            .machine;
        let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
        crate::model_file::position::parse(
            Path::new("m.toml"),
            &format!("{text}\n{section}"),
            &machine,
        )
    }

    #[test]
    fn a_model_file_carries_its_training_envelope_both_ways() {
        let model = with_envelope(
            "[training_envelope]\ninputs = { x_slide_top = [19.5, 24.0], spindle_rpm = [0.0, 12000.0] }\nmax_abs_prediction_um = { Z = 38.5 }\n",
        )
        .unwrap();
        let env = model.envelope().unwrap();
        assert_eq!(env.temperatures[0], Some((19.5, 24.0)));
        assert_eq!(env.max_abs_um[2], Some(38.5));
        assert!(env.operating.contains(&Some((0.0, 12000.0))));
        // Written and read again: the same envelope.
        let machine = crate::machine_file::load(&repo("examples/vmc3/machine.toml"))
            .unwrap()
            .machine;
        let text = crate::model_file::position::ModelFile::from_model(&model, &machine).to_toml();
        assert!(text.contains("[training_envelope"), "{text}");
        let again =
            crate::model_file::position::parse(Path::new("m.toml"), &text, &machine).unwrap();
        assert_eq!(again.envelope(), model.envelope());
        // A file without one loads as before.
        assert!(with_envelope("").unwrap().envelope().is_none());
    }

    #[test]
    fn a_bad_envelope_names_its_key() {
        for (section, expect) in [
            (
                "[training_envelope]\ninputs = { nowhere = [1.0, 2.0] }\n",
                "`training_envelope.inputs.nowhere`: machine `vmc-3axis` has no temperature or operating channel `nowhere`",
            ),
            (
                "[training_envelope]\ninputs = { x_slide_top = [30.0, 20.0] }\n",
                "expected [min, max], finite and ordered, got [30, 20]",
            ),
            (
                "[training_envelope]\nmax_abs_prediction_um = { Z = -1.0 }\n",
                "expected a finite value ≥ 0 µm, got -1",
            ),
        ] {
            let e = with_envelope(section).unwrap_err().to_string();
            assert!(e.contains(expect), "{e}");
        }
    }
}
