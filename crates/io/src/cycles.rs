//! Recorded cycles of one machine in the run CSV form of `docs/formats.md`: the inputs of
//! [`truepos_model::Model::evaluate`], one row per cycle.

use std::path::Path;

use truepos_model::{LagFilters, LagSource, Machine, RecordedRun};

use crate::run::{Shape, Time};
use crate::table::{Number, Table, Value};
use crate::timestamp;
use crate::units::{self, Role, Unit};
use truepos_files::InputError;

/// The cycles of a run, in the machine's channel order: the recorded run and, for messages
/// about the file, the line of each row.
#[derive(Debug, Clone, PartialEq)]
pub struct Cycles {
    /// The rows: `time_s` is the row number when the run has no time column; temperatures and
    /// operating state are NaN where the run has no column for a channel the caller did not
    /// require.
    pub run: RecordedRun,
    /// Line in the file of each row.
    pub line: Vec<u64>,
}

/// Computes the lagged channels of every row from their sources, stepping the real-time
/// [`LagFilters`] with the rows' time steps, exactly as the control does every cycle.
pub fn fill_lags(
    machine: &Machine,
    time_s: &[f64],
    temperatures_c: &mut [Vec<f64>],
    operating: &[Vec<f64>],
) {
    let mut lags = LagFilters::new(machine);
    if lags.is_empty() {
        return;
    }
    let mut previous = None;
    for ((t, row), op) in time_s.iter().zip(temperatures_c.iter_mut()).zip(operating) {
        let dt = previous.map_or(0.0, |p| t - p);
        previous = Some(*t);
        lags.apply(dt, row, op);
    }
}

/// A recorded run's temperatures in the machine's channel order: `columns` names the values of
/// each row (a twin run's sensor ids, say); a measured channel the run lacks reads NaN, and the
/// lagged channels are computed by [`fill_lags`] with `operating` (one row per sample).
pub fn machine_temperatures<'a>(
    machine: &Machine,
    columns: &[String],
    time_s: &[f64],
    rows: impl IntoIterator<Item = &'a [f64]>,
    operating: &[Vec<f64>],
) -> Vec<Vec<f64>> {
    let index: Vec<Option<usize>> = machine
        .temperatures
        .iter()
        .map(|t| {
            columns
                .iter()
                .position(|c| *c == t.id)
                .filter(|_| t.lag.is_none())
        })
        .collect();
    let mut temps: Vec<Vec<f64>> = rows
        .into_iter()
        .map(|r| {
            index
                .iter()
                .map(|i| i.and_then(|i| r.get(i).copied()).unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    fill_lags(machine, time_s, &mut temps, operating);
    temps
}

/// Whether a run must hold the axis positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Positions {
    /// Every axis position column is required (models with position-dependent terms).
    Required,
    /// Missing position columns read as NaN (a model that reads no position, such as a fitted
    /// dynamic model, on a spindle test run per ISO 230-3 where no axis moves).
    Optional,
}

/// A row's time after `prev` (the previous row's): finite and strictly increasing, because the
/// lag filters step by the difference and a replay waits for the next time.
pub fn check_time(t: f64, prev: Option<f64>) -> Result<f64, String> {
    if !t.is_finite() {
        return Err(format!("expected a finite time in s, got {t}"));
    }
    match prev {
        Some(p) if t <= p => Err(format!("expected time to increase, got {t} after {p}")),
        _ => Ok(t),
    }
}

/// Reads a run CSV. Every axis position column is required, and so is every temperature
/// channel listed in `required_sensors` (the ones the model reads).
pub fn load(
    path: &Path,
    machine: &Machine,
    required_sensors: &[usize],
) -> Result<Cycles, InputError> {
    load_with(path, machine, required_sensors, Positions::Required)
}

/// [`load`], saying whether the axis positions are required.
pub fn load_with(
    path: &Path,
    machine: &Machine,
    required_sensors: &[usize],
    positions: Positions,
) -> Result<Cycles, InputError> {
    let (file, _) = truepos_files::read::open(path, truepos_files::RUN)?;
    read_with(path, file, machine, required_sensors, positions)
}

/// Reads a run CSV from any reader; `path` only names it in errors.
pub fn read(
    path: &Path,
    reader: impl std::io::Read,
    machine: &Machine,
    required_sensors: &[usize],
) -> Result<Cycles, InputError> {
    read_with(path, reader, machine, required_sensors, Positions::Required)
}

/// [`read`], saying whether the axis positions are required.
pub fn read_with(
    path: &Path,
    reader: impl std::io::Read,
    machine: &Machine,
    required_sensors: &[usize],
    positions_needed: Positions,
) -> Result<Cycles, InputError> {
    let table = crate::table::read_csv(path, reader, crate::table::CsvOptions::default())?;
    let options = Options {
        positions: positions_needed,
        ..Options::default()
    };
    from_table(&table, machine, required_sensors, &options)
}

/// How a run file is read for a machine, beyond its columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Whether the axis positions are required.
    pub positions: Positions,
    /// The file's separator and run column.
    pub shape: Shape,
    /// The time: `None` reads `time_s` when there is one and else numbers the rows (0, 1, 2 …);
    /// a named column must be there.
    pub time: Option<Time>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            positions: Positions::Required,
            shape: Shape::default(),
            time: None,
        }
    }
}

/// Reads every run of a run file (CSV, or a workbook's sheets) as `options` say: a run column
/// splits a table into runs, each named by its value (else by its file and sheet).
pub fn load_runs(
    path: &Path,
    machine: &Machine,
    required_sensors: &[usize],
    options: &Options,
) -> Result<Vec<(String, Cycles)>, InputError> {
    crate::run::read_shaped(path, None, &options.shape)?
        .into_iter()
        .map(|t| {
            let cycles = from_table(&t.table, machine, required_sensors, options)?;
            Ok((t.name(), cycles))
        })
        .collect()
}

/// A column of the table and the unit its values convert from.
type Source = Option<(usize, Unit, Role)>;

/// The columns a run's channels come from.
struct Sources {
    time: Option<usize>,
    positions: Vec<Source>,
    temperatures: Vec<Source>,
    operating: Vec<Option<usize>>,
}

/// Finds the machine's channels in the header (with or without a unit in the column name,
/// [`units::find_channel`]), each with the unit it converts from.
fn sources(
    table: &Table,
    machine: &Machine,
    required_sensors: &[usize],
    options: &Options,
) -> Result<Sources, InputError> {
    let header = &table.columns;
    let missing = |name: String, what: &str| {
        InputError::at(
            &table.file,
            table.header_line,
            1,
            name.clone(),
            format!(
                "missing column `{name}` ({what}); the header has: {}",
                header.join(", ")
            ),
        )
    };
    let source = |col: Option<usize>, role: Role| -> Result<Source, InputError> {
        col.map(|c| {
            units::for_role(&header[c], role)
                .map(|u| (c, u, role))
                .map_err(|e| table.header_at(c, e))
        })
        .transpose()
    };
    let time = match &options.time {
        None => header.iter().position(|h| h == "time_s"),
        Some(Time::Column(name)) => Some(
            header
                .iter()
                .position(|h| h == name)
                .ok_or_else(|| missing(name.clone(), "time"))?,
        ),
        Some(Time::Period(_)) => None,
    };
    let mut positions = Vec::new();
    for axis in &machine.axes {
        let name = axis.position_column();
        let col = header
            .iter()
            .position(|h| *h == name)
            .or_else(|| units::find_channel(header, &axis.name));
        if col.is_none() && options.positions == Positions::Required {
            return Err(missing(name, "axis position"));
        }
        let role = match axis.kind {
            truepos_model::AxisKind::Rotary => Role::Angle,
            _ => Role::Position,
        };
        positions.push(source(col, role)?);
    }
    let mut temperatures = Vec::new();
    for (i, t) in machine.temperatures.iter().enumerate() {
        // A lagged channel is computed from its source below, never read from the file.
        if let Some(lag) = t.lag {
            let (source_id, found) = match lag.source {
                LagSource::Temperature(s) => {
                    let id = &machine.temperatures[s].id;
                    (id, units::find_channel(header, id))
                }
                LagSource::Operating { channel, .. } => {
                    let id = &machine.operating[channel].id;
                    (id, header.iter().position(|h| h == id))
                }
            };
            if required_sensors.contains(&i) && found.is_none() {
                return Err(missing(
                    source_id.clone(),
                    "the source of a lagged channel the model reads",
                ));
            }
            temperatures.push(None);
            continue;
        }
        let col = units::find_channel(header, &t.id);
        if col.is_none() && required_sensors.contains(&i) {
            return Err(missing(t.id.clone(), "temperature the model reads"));
        }
        temperatures.push(source(col, Role::Temperature)?);
    }
    let operating = machine
        .operating
        .iter()
        .map(|o| header.iter().position(|h| *h == o.id))
        .collect();
    Ok(Sources {
        time,
        positions,
        temperatures,
        operating,
    })
}

/// The cycles of one table: the machine's channels found by name (`sources`) and converted
/// to °C and mm.
pub fn from_table(
    table: &Table,
    machine: &Machine,
    required_sensors: &[usize],
    options: &Options,
) -> Result<Cycles, InputError> {
    let path = table.file.as_path();
    let header = &table.columns;
    if header.iter().all(|h| h.is_empty()) {
        return Err(InputError::file(path, "empty file; expected a header row"));
    }
    let Sources {
        time: time_col,
        positions: position_cols,
        temperatures: temperature_cols,
        operating: operating_cols,
    } = sources(table, machine, required_sensors, options)?;
    let mut out = Cycles {
        run: RecordedRun::default(),
        line: Vec::new(),
    };
    let first_iso = time_col.and_then(|c| {
        let first = table.rows().next()?.cell(c)?;
        match first.value {
            Value::Text(t) => timestamp::parse(t).ok(),
            _ => None,
        }
    });
    for (row_index, row) in table.rows().enumerate() {
        if let Some(e) = table.width_error(row_index) {
            return Err(e);
        }
        let line = row.line() as u64;
        let cell = |col: usize| -> Result<f64, InputError> {
            match row.number(col) {
                Number::Value(v) => Ok(v),
                Number::Text(text) => {
                    Err(table.at(row_index, col, format!("expected a number, got `{text}`")))
                }
                Number::Empty => Err(table.at(row_index, col, "expected a number, got ``")),
            }
        };
        let converted = |src: &Source| -> Result<f64, InputError> {
            match *src {
                None => Ok(f64::NAN),
                Some((c, unit, role)) => Ok(unit.convert(cell(c)?, role).unwrap_or(f64::NAN)),
            }
        };
        let time = match (time_col, &options.time) {
            (Some(c), _) => {
                let t = match first_iso {
                    Some(first) => iso_seconds(table, row_index, c, first)?,
                    None => cell(c)?,
                };
                // Every row's time, the first and the last included: a NaN or infinite time
                // would end up in outputs, stall a replay or change the lag filters' steps.
                check_time(t, out.run.time_s.last().copied())
                    .map_err(|e| InputError::at(path, line as usize, c + 1, header[c].clone(), e))?
            }
            (None, Some(Time::Period(p))) => row_index as f64 * p,
            (None, _) => row_index as f64,
        };
        // Sensor and position values are passed on as read (NaN included): judging them is
        // the model's job, and a bad value must show as a failed cycle, not vanish here.
        let positions = position_cols
            .iter()
            .map(converted)
            .collect::<Result<_, _>>()?;
        let temperatures = temperature_cols
            .iter()
            .map(converted)
            .collect::<Result<_, _>>()?;
        let operating = operating_cols
            .iter()
            .map(|c| c.map_or(Ok(f64::NAN), cell))
            .collect::<Result<_, _>>()?;
        out.run.time_s.push(time);
        out.line.push(line);
        out.run.positions.push(positions);
        out.run.temperatures_c.push(temperatures);
        out.run.operating.push(operating);
    }
    if out.run.is_empty() {
        return Err(InputError::file(path, "no data rows after the header"));
    }
    let run = &mut out.run;
    fill_lags(
        machine,
        &run.time_s,
        &mut run.temperatures_c,
        &run.operating,
    );
    Ok(out)
}

/// Seconds since the first row of an ISO 8601 time cell.
fn iso_seconds(table: &Table, row: usize, col: usize, first: i128) -> Result<f64, InputError> {
    let ns =
        match table.row(row).cell(col).map(|c| c.value) {
            Some(Value::Text(t)) => timestamp::parse(t).map_err(|e| table.at(row, col, e))?,
            _ => return Err(table.at(
                row,
                col,
                "expected an ISO 8601 date-time as in the first row, got a number or an empty cell",
            )),
        };
    Ok((ns - first) as f64 / 1e9)
}
