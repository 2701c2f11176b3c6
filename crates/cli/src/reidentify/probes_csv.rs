//! Probe events from a run CSV: the rows of a run (time, axis positions, temperatures,
//! operating state) of which some carry a probe measurement in the columns
//! `probe_<axis>_mm` (where the probe touched) and `probe_d<axis>_um` (the measured error), the
//! axis name in lower case — the columns `truepos sim` writes. Every row drives the lagged
//! channels; only rows with a measured error are events.

use std::path::Path;

use truepos_files::InputError;
use truepos_fit::reidentify::ProbeEvent;
use truepos_io::cycles::{self, Positions};
use truepos_io::table::{self, Number, Table};
use truepos_model::Machine;
use truepos_runtime::probe::{MAX_PROBE_DEVIATION_UM, PROBE_TRAVEL_MARGIN_MM};

use crate::error::CliError;

/// Column names of the probed position and the measured error of an axis.
pub fn probe_columns(axis: &str) -> (String, String) {
    let a = axis.to_lowercase();
    (format!("probe_{a}_mm"), format!("probe_d{a}_um"))
}

/// Reads the probe events of a run CSV; `sensors` are the temperature channels the model
/// reads (required in the file).
pub fn read(
    path: &Path,
    machine: &Machine,
    sensors: &[usize],
) -> Result<Vec<ProbeEvent>, CliError> {
    let bytes = crate::write::read(path, truepos_files::RUN)?;
    parse(path, &bytes, machine, sensors)
}

/// [`read`] on a file's bytes; `path` names it in errors.
pub fn parse(
    path: &Path,
    bytes: &[u8],
    machine: &Machine,
    sensors: &[usize],
) -> Result<Vec<ProbeEvent>, CliError> {
    let cyc = cycles::read_with(path, bytes, machine, sensors, Positions::Optional)?;
    let table = table::parse_csv(path, bytes, table::CsvOptions::default())?;
    let cols: Vec<(Option<usize>, Option<usize>)> = machine
        .axes
        .iter()
        .map(|a| {
            let (p, d) = probe_columns(&a.name);
            (table.column(&p), table.column(&d))
        })
        .collect();
    if cols.iter().all(|c| c.1.is_none()) {
        let names: Vec<String> = machine
            .axes
            .iter()
            .map(|a| probe_columns(&a.name).1)
            .collect();
        return Err(InputError::at(
            path,
            table.header_line,
            1,
            "",
            format!(
                "no probe measurement column; expected at least one of {} (the measured error \
                 in µm) beside probe_<axis>_mm (where the probe touched)",
                names.join(", ")
            ),
        )
        .into());
    }
    if table.len() != cyc.run.time_s.len() {
        return Err(CliError::refused(format!(
            "{}: {} data rows read as a table but {} as cycles",
            path.display(),
            table.len(),
            cyc.run.time_s.len()
        )));
    }
    let mut events = Vec::new();
    for (i, row) in table.rows().enumerate() {
        let mut measured = vec![None; machine.axes.len()];
        for (a, (_, dev)) in cols.iter().enumerate() {
            let Some(c) = *dev else { continue };
            measured[a] = deviation(&table, i, c)?;
        }
        if measured.iter().all(Option::is_none) {
            continue;
        }
        let mut position = Vec::with_capacity(machine.axes.len());
        for (a, (pos, _)) in cols.iter().enumerate() {
            position.push(probed_position(
                &table,
                machine,
                i,
                a,
                *pos,
                cyc.run.positions[i][a],
            )?);
        }
        events.push(ProbeEvent {
            time_s: cyc.run.time_s[i],
            place: format!("{}:{}", path.display(), row.line()),
            temperatures_c: cyc.run.temperatures_c[i].clone(),
            operating: cyc.run.operating[i].clone(),
            position_mm: position,
            measured_um: measured,
        });
    }
    Ok(events)
}

/// The probe events of a run CSV as the service's probe replay plays them: (run time, event),
/// and the run's first time (the replay's zero).
pub fn read_inputs(
    path: &Path,
    machine: &Machine,
) -> Result<(Vec<(f64, truepos_runtime::probe::ProbeInput)>, f64), CliError> {
    let bytes = crate::write::read(path, truepos_files::RUN)?;
    let start = cycles::read_with(path, &bytes[..], machine, &[], Positions::Optional)?
        .run
        .time_s
        .first()
        .copied()
        .unwrap_or(0.0);
    let events = read(path, machine, &[])?
        .into_iter()
        .map(|ev| {
            let mut p = truepos_runtime::probe::ProbeInput::EMPTY;
            for (a, (pos, m)) in ev.position_mm.iter().zip(&ev.measured_um).enumerate() {
                if a < p.position_mm.len() {
                    p.position_mm[a] = *pos;
                    p.deviation_um[a] = m.unwrap_or(f64::NAN);
                    p.measured[a] = m.is_some();
                }
            }
            (ev.time_s, p)
        })
        .collect();
    Ok((events, start))
}

/// A measured error: empty (not measured) or a finite number within the bound.
fn deviation(table: &Table, row: usize, col: usize) -> Result<Option<f64>, InputError> {
    let number = table.row(row).number(col);
    match number {
        Number::Empty => Ok(None),
        Number::Value(v) if v.is_finite() && v.abs() <= MAX_PROBE_DEVIATION_UM => Ok(Some(v)),
        Number::Value(v) => Err(table.at(
            row,
            col,
            format!(
                "expected the measured error in µm, a finite number within ±{MAX_PROBE_DEVIATION_UM}, got {v}"
            ),
        )),
        Number::Text(t) => Err(table.at(
            row,
            col,
            format!("expected the measured error in µm (a number, or empty where not measured), got `{t}`"),
        )),
    }
}

/// Where the probe touched on axis `a`: its `probe_<axis>_mm` cell, or the row's axis position
/// when the file has no such column; finite and within the axis' travel.
fn probed_position(
    table: &Table,
    machine: &Machine,
    row: usize,
    a: usize,
    col: Option<usize>,
    axis_position: f64,
) -> Result<f64, InputError> {
    let axis = &machine.axes[a];
    let (lo, hi) = (
        axis.travel_min - PROBE_TRAVEL_MARGIN_MM,
        axis.travel_max + PROBE_TRAVEL_MARGIN_MM,
    );
    let expect = format!(
        "expected the probed position of axis {} in mm within its travel [{}, {}]",
        axis.name, axis.travel_min, axis.travel_max
    );
    let Some(col) = col else {
        if axis_position.is_finite() && (lo..=hi).contains(&axis_position) {
            return Ok(axis_position);
        }
        let (p, _) = probe_columns(&axis.name);
        return Err(InputError::at(
            &table.file,
            table.row(row).line(),
            1,
            p.clone(),
            format!(
                "{expect}: the file has no column `{p}` and the row's {} is {axis_position}",
                axis.position_column()
            ),
        ));
    };
    match table.row(row).cell(col).map(|c| c.value.number()) {
        Some(Number::Value(v)) if v.is_finite() && (lo..=hi).contains(&v) => Ok(v),
        Some(Number::Value(v)) => Err(table.at(row, col, format!("{expect}, got {v}"))),
        Some(Number::Text(t)) => Err(table.at(row, col, format!("{expect}, got `{t}`"))),
        Some(Number::Empty) | None => Err(table.at(
            row,
            col,
            format!("{expect}; the cell is empty on a row with a measured error"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn machine() -> Machine {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vmc3/machine.toml");
        truepos_io::machine_file::load(&path).unwrap().machine
    }

    /// What a probe cell may hold: numbers in and out of bounds, the non-finite spellings,
    /// text, an empty cell, a decimal comma.
    fn cell() -> impl Strategy<Value = String> {
        prop_oneof![
            (-2000.0..2000.0f64).prop_map(|v| format!("{v}")),
            Just(String::new()),
            Just("NaN".to_string()),
            Just("inf".to_string()),
            Just("-1e400".to_string()),
            Just("abc".to_string()),
            Just("\"1,5\"".to_string()),
            (-100.0..1200.0f64).prop_map(|v| format!("{v:.3}")),
        ]
    }

    proptest! {
        /// Any content of the probe columns: events whose values are within bounds, or an error
        /// at file:line:column naming a probe column; never a panic.
        #[test]
        fn probe_cells_give_checked_events_or_a_located_error(
            rows in proptest::collection::vec((cell(), cell(), cell()), 1..20)
        ) {
            let m = machine();
            let sensors: Vec<String> = m
                .temperatures
                .iter()
                .filter(|t| t.lag.is_none())
                .map(|t| t.id.clone())
                .collect();
            let mut text = format!(
                "time_s,X_mm,Y_mm,Z_mm,{},probe_x_mm,probe_dx_um,probe_dz_um\n",
                sensors.join(",")
            );
            for (i, (px, dx, dz)) in rows.iter().enumerate() {
                let temps = vec!["21.0"; sensors.len()].join(",");
                text += &format!("{i},100,100,100,{temps},{px},{dx},{dz}\n");
            }
            let path = Path::new("probes.csv");
            match parse(path, text.as_bytes(), &m, &[]) {
                Ok(events) => {
                    for ev in &events {
                        prop_assert!(ev.measured_um.iter().any(Option::is_some));
                        for v in ev.measured_um.iter().flatten() {
                            prop_assert!(v.is_finite() && v.abs() <= MAX_PROBE_DEVIATION_UM);
                        }
                        for (a, p) in ev.position_mm.iter().enumerate() {
                            let ax = &m.axes[a];
                            prop_assert!(p.is_finite());
                            prop_assert!(*p >= ax.travel_min - PROBE_TRAVEL_MARGIN_MM);
                            prop_assert!(*p <= ax.travel_max + PROBE_TRAVEL_MARGIN_MM);
                        }
                    }
                }
                Err(e) => {
                    let e = e.to_string();
                    prop_assert!(e.starts_with("probes.csv:"), "{}", e);
                    prop_assert!(e.contains("`probe_"), "{}", e);
                }
            }
        }
    }
}
