//! Where the model's inputs and the probe's numbers are in the log's probes table, and a
//! model's residuals on those rows.

use truepos_fleet_store::shadow_probes::ShadowProbe;
use truepos_model::config::MachineConfig;
use truepos_model::{CompensationModel, CycleInput};
use truepos_runtime::log;

/// Whether a probe at service time `time_s` was predicted by the model reloaded at `from_s`
/// (`None`: no reload awaited, every probe counts). The service stamps `model-reloaded` with
/// the time of the cycle before the reload (the reload runs before the next cycle), so a probe
/// of that same time carries the previous model's prediction: only probes strictly after it
/// count. A NaN time is before any reload.
fn after_reload(time_s: f64, from_s: Option<f64>) -> bool {
    match from_s {
        None => true,
        Some(f) => time_s > f,
    }
}

/// Where the model's inputs and the probe's numbers are in the log's probes table.
pub(super) struct Layout {
    /// Per machine axis: its name, probed position, measured error, the running model's
    /// prediction.
    axes: Vec<(String, usize, usize, usize)>,
    temperatures: Vec<usize>,
    operating: Vec<usize>,
}

impl Layout {
    pub(super) fn of(columns: &[String], machine: &MachineConfig) -> Result<Self, String> {
        let col = |name: &str| -> Result<usize, String> {
            columns.iter().position(|c| c == name).ok_or_else(|| {
                format!(
                    "the probes table has no column `{name}`; it has: {}",
                    columns.join(", ")
                )
            })
        };
        let m = &machine.machine;
        let mut axes = Vec::new();
        for a in &m.axes {
            let [pos, dev, pred] = log::probe_axis_columns(&a.name);
            axes.push((a.name.clone(), col(&pos)?, col(&dev)?, col(&pred)?));
        }
        Ok(Layout {
            axes,
            temperatures: m
                .temperatures
                .iter()
                .map(|t| col(&t.id))
                .collect::<Result<_, _>>()?,
            operating: m
                .operating
                .iter()
                .map(|o| col(&o.id))
                .collect::<Result<_, _>>()?,
        })
    }

    /// The residuals of `model` at each row's inputs (the probed positions, the cycle's
    /// temperatures and operating state), per measured axis with the running model's
    /// prediction; rows before `from_s` (service time) are left out. The model is evaluated
    /// as the service evaluates it (its training envelope applied).
    pub(super) fn residuals(
        &self,
        rows: &[&log::ProbeRow],
        model: &mut CompensationModel,
        started_unix_s: f64,
        from_s: Option<f64>,
    ) -> Vec<ShadowProbe> {
        let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
        let (mut t, mut o) = (Vec::new(), Vec::new());
        let mut out = Vec::new();
        for r in rows {
            if !after_reload(r.time_s, from_s) {
                continue;
            }
            let temperatures: Vec<f64> = self
                .temperatures
                .iter()
                .map(|&c| nan(r.values[c]))
                .collect();
            let operating: Vec<f64> = self.operating.iter().map(|&c| nan(r.values[c])).collect();
            let positions: Vec<f64> = self.axes.iter().map(|a| nan(r.values[a.1])).collect();
            let input = CycleInput {
                temperatures_c: &temperatures,
                positions: &positions,
                operating: &operating,
            };
            let Ok((error_um, _)) = model.step_guarded(0.0, &input, (&mut t, &mut o)) else {
                continue;
            };
            for (i, (name, _, dev, pred)) in self.axes.iter().enumerate() {
                let (Some(measured), Some(active)) = (r.values[*dev], r.values[*pred]) else {
                    continue;
                };
                let shadow = error_um.get(i).copied().unwrap_or(f64::NAN);
                if !(measured.is_finite() && active.is_finite() && shadow.is_finite()) {
                    continue;
                }
                out.push(ShadowProbe {
                    t_unix_s: started_unix_s + r.time_s,
                    axis: name.clone(),
                    measured_um: measured,
                    active_um: active,
                    shadow_um: shadow,
                    log_row: r.row,
                });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_probe_at_the_reload_time_is_the_previous_model_s() {
        // The reload stamped at 12.5 s: the probe of that cycle is the old model's.
        assert!(!after_reload(12.5, Some(12.5)));
        assert!(!after_reload(12.0, Some(12.5)));
        assert!(after_reload(12.6, Some(12.5)));
        assert!(!after_reload(f64::NAN, Some(12.5)));
        // No reload awaited: every probe counts.
        assert!(after_reload(0.0, None));
        assert!(after_reload(f64::NAN, None));
    }
}
