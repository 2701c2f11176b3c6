//! Probe events from the service's log: the accepted rows of its `probes` table, with the
//! inputs of their cycle as the service saw them (lagged channels as it computed them).
//! Rejected rows are counted, never used.

use std::path::Path;

use truepos_fit::reidentify::ProbeEvent;
use truepos_model::Machine;
use truepos_runtime::log;

use crate::error::CliError;

/// The accepted probe events of a log, and how many were rejected.
pub fn read(path: &Path, machine: &Machine) -> Result<(Vec<ProbeEvent>, usize), CliError> {
    let refuse = |m: String| CliError::refused(format!("{}: {m}", path.display()));
    match log::read_meta(path)? {
        Some(meta) if meta["machine"].as_str() != Some(machine.name.as_str()) => {
            return Err(refuse(format!(
                "this log belongs to machine `{}`, not to `{}`",
                meta["machine"].as_str().unwrap_or("(unnamed)"),
                machine.name
            )))
        }
        None => return Err(refuse("no service wrote this log (it has no meta)".into())),
        Some(_) => {}
    }
    let table = log::read_probes(path)?;
    let col = |name: &str| -> Result<usize, CliError> {
        table.columns.iter().position(|c| c == name).ok_or_else(|| {
            refuse(format!(
                "the probes table has no column `{name}`; it has: {}",
                table.columns.join(", ")
            ))
        })
    };
    let mut axes = Vec::new();
    for a in &machine.axes {
        let [pos, dev, _] = log::probe_axis_columns(&a.name);
        axes.push((col(&pos)?, col(&dev)?));
    }
    let temps = machine
        .temperatures
        .iter()
        .map(|t| col(&t.id))
        .collect::<Result<Vec<_>, _>>()?;
    let ops = machine
        .operating
        .iter()
        .map(|o| col(&o.id))
        .collect::<Result<Vec<_>, _>>()?;
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let mut events = Vec::new();
    let mut rejected = 0;
    for r in &table.rows {
        if !r.accepted {
            rejected += 1;
            continue;
        }
        events.push(ProbeEvent {
            time_s: r.time_s,
            place: format!("{}: probes row {}", path.display(), r.row),
            temperatures_c: temps.iter().map(|&c| nan(r.values[c])).collect(),
            operating: ops.iter().map(|&c| nan(r.values[c])).collect(),
            position_mm: axes.iter().map(|&(p, _)| nan(r.values[p])).collect(),
            measured_um: axes.iter().map(|&(_, d)| r.values[d]).collect(),
        });
    }
    Ok((events, rejected))
}
