//! A fit as the model description `truepos_io` writes: the trained model of the last training
//! part, its inputs by name and kind, the axis each target compensates, and where it came from
//! (runs, settings, choices) with its validation figures.

use std::fmt;
use std::str::FromStr;

use truepos_io::dynamic_model_file::{DynamicModelFile, InputEntry};

use crate::dataset::Dataset;
use crate::settings::Settings;
use crate::validate::Outcome;

/// `<target>=<axis>`: the machine axis a target compensates (`ch5_um=Z`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TargetAxis {
    /// Target name.
    pub target: String,
    /// Machine axis name.
    pub axis: String,
}

impl FromStr for TargetAxis {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.split_once('=') {
            Some((target, axis)) => Ok(Self {
                target: target.trim().to_string(),
                axis: axis.trim().to_string(),
            }),
            None => Err(format!(
                "expected <target>=<axis>, e.g. ch5_um=Z, got `{s}`"
            )),
        }
    }
}

/// A model file that cannot be made as asked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExportError {
    /// An axis was given for a target the dataset does not have.
    UnknownTarget {
        /// The name given.
        target: String,
        /// The dataset's targets.
        targets: Vec<String>,
    },
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownTarget { target, targets } => write!(
                f,
                "no target `{target}`; the targets are {}",
                targets.join(", ")
            ),
        }
    }
}

impl std::error::Error for ExportError {}

/// The dynamic model file of a fit for `machine`; `created_by` names the tool and version.
/// A target without an entry in `axes` keeps the axis its name implies, if any (see
/// `truepos_io::dynamic_model_file`).
pub fn model_file(
    dataset: &Dataset,
    settings: &Settings,
    outcome: &Outcome,
    machine: &str,
    axes: &[TargetAxis],
    created_by: &str,
) -> Result<DynamicModelFile, ExportError> {
    let trained = &outcome.trained;
    let inputs = trained
        .inputs
        .iter()
        .map(|&i| InputEntry {
            name: dataset.input_names[i].clone(),
            kind: dataset.input_kinds[i],
        })
        .collect();
    let mut file = DynamicModelFile::new(
        machine,
        &trained.model,
        inputs,
        &dataset.target_names,
        serde_json::json!({
            "created_by": created_by,
            "runs": dataset.runs.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
            "fitted_on": "the training part of the (last) validation fold",
            "settings": settings,
            "choices": trained.choices,
        }),
        serde_json::to_value(&outcome.validation).unwrap_or_default(),
    );
    for a in axes {
        let output = file
            .outputs
            .iter_mut()
            .find(|o| o.name == a.target)
            .ok_or_else(|| ExportError::UnknownTarget {
                target: a.target.clone(),
                targets: dataset.target_names.clone(),
            })?;
        output.axis = Some(a.axis.clone());
    }
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_target_axis_reads_target_equals_axis() {
        assert_eq!(
            " ch5_um = Z".parse(),
            Ok(TargetAxis {
                target: "ch5_um".into(),
                axis: "Z".into()
            })
        );
        assert_eq!(
            "ch5_um".parse::<TargetAxis>().unwrap_err(),
            "expected <target>=<axis>, e.g. ch5_um=Z, got `ch5_um`"
        );
    }
}
