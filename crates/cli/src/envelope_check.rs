//! Whether a model's largest prediction on the data a command runs it on lies beyond the
//! machine's safety envelope (`max_offset_um` per axis). The service would then hold the axis at
//! the limit (`clamped`), safe but not what the model's figures promise, so `truepos run` and
//! `truepos demo` say so at start, `truepos fit --machine` when it writes the model, and each
//! names the key to change.

use std::path::Path;

use truepos_model::{CompensationModel, RecordedRun, MAX_AXES};
use truepos_runtime::MachineConfig;

/// One axis whose predicted error goes beyond its envelope.
#[derive(Debug, Clone, PartialEq)]
pub struct Beyond {
    /// Axis index in the machine.
    pub axis: usize,
    /// The largest |predicted error| in µm.
    pub largest_um: f64,
    /// Time of the row where it is largest, s.
    pub at_s: f64,
}

/// The axes on which `model`, stepped through `rows` in order as the service steps it, predicts
/// an error larger than the axis' `max_offset_um`. Rows the model cannot evaluate (a sensor out
/// of range, no positions) are skipped: the service would not compensate from them either.
pub fn beyond(
    machine: &MachineConfig,
    model: &CompensationModel,
    rows: &RecordedRun,
) -> Vec<Beyond> {
    let mut model = model.clone();
    model.reset();
    let mut largest = [(0.0_f64, 0.0_f64); MAX_AXES];
    let mut last_s: Option<f64> = None;
    for (i, &t) in rows.time_s.iter().enumerate() {
        let dt = last_s.map_or(0.0, |l| t - l);
        let Ok(error_um) = model.step(dt, &rows.row(i)) else {
            continue;
        };
        last_s = Some(t);
        for (l, e) in largest.iter_mut().zip(error_um) {
            if e.abs() > l.0 {
                *l = (e.abs(), t);
            }
        }
    }
    machine
        .axes
        .iter()
        .zip(largest)
        .enumerate()
        .filter(|(_, (a, (e, _)))| *e > a.max_offset_um)
        .map(|(axis, (_, (largest_um, at_s)))| Beyond {
            axis,
            largest_um,
            at_s,
        })
        .collect()
}

/// One warning per axis beyond its envelope, in the words a user acts on: what the model
/// predicts where, what the service will do, and the key of the machine file to change.
pub fn warnings(
    machine: &MachineConfig,
    machine_file: &Path,
    model_name: &str,
    data: &str,
    beyond: &[Beyond],
) -> Vec<String> {
    beyond
        .iter()
        .map(|b| {
            let axis = &machine.machine.axes[b.axis].name;
            let limit = machine.axes[b.axis].max_offset_um;
            format!(
                "warning: model `{model_name}` predicts errors up to {:.1} µm on axis {axis} over {data} (at {:.0} s), beyond the axis' safety envelope of {limit} µm: the service will hold the compensation at ±{limit} µm there and the error beyond stays uncorrected. If the machine really drifts that far, raise `max_offset_um` in axis {axis}'s `[[axis]]` table of {}.",
                b.largest_um,
                b.at_s,
                machine_file.display()
            )
        })
        .collect()
}
