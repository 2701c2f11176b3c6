//! The error over the working volume for the report: a position-dependent model judged where
//! it matters, over the machine's travel rather than only along the path a run happened to take.

use truepos_model::{AxisKind, CycleInput, Machine, Model};
use truepos_report::{VolumeDirection, VolumeMap};

/// Grid positions per axis in the report's maps.
pub const GRID: usize = 9;

/// The three axes spanning the grid: the machine's first three linear axes (an axis missing on
/// a machine with fewer is a single plane, named "—").
pub fn grid_axes(machine: &Machine) -> [Option<usize>; 3] {
    let mut linear = (0..machine.axes.len()).filter(|&a| machine.axes[a].kind == AxisKind::Linear);
    [linear.next(), linear.next(), linear.next()]
}

/// An empty map over the travel of the grid axes; the caller fills the directions.
pub fn empty_map(machine: &Machine, moment: String, labels: (String, Option<String>)) -> VolumeMap {
    let axes = grid_axes(machine);
    let name = |a: Option<usize>| a.map_or("—".to_string(), |a| machine.axes[a].name.clone());
    let coords = |a: Option<usize>| match a {
        Some(a) => {
            VolumeMap::axis_positions(machine.axes[a].travel_min, machine.axes[a].travel_max, GRID)
        }
        None => vec![0.0],
    };
    VolumeMap {
        moment,
        axes: axes.map(name),
        coords: axes.map(coords),
        labels,
        directions: Vec::new(),
    }
}

/// The model's predicted error of each axis at every grid point, with the temperatures and
/// operating state of one row and the other axes where that row had them.
fn predicted_over(
    map: &VolumeMap,
    machine: &Machine,
    model: &Model,
    row: &CycleInput<'_>,
) -> Vec<Vec<f64>> {
    let axes = grid_axes(machine);
    let mut out = vec![Vec::new(); machine.axes.len()];
    let mut pos = row.positions.to_vec();
    for p in map.points() {
        for (k, a) in axes.iter().enumerate() {
            if let Some(a) = a {
                pos[*a] = p[k];
            }
        }
        let input = CycleInput {
            positions: &pos,
            ..*row
        };
        let e = model.evaluate(&input).map(|c| c.error_um().to_vec());
        for (a, v) in out.iter_mut().enumerate() {
            v.push(
                e.as_ref()
                    .ok()
                    .and_then(|e| e.get(a).copied())
                    .unwrap_or(f64::NAN),
            );
        }
    }
    out
}

/// Measured (or simulated) error over the volume before compensation, and after it: `truth`
/// gives the error of the first three axes at a grid point; the residual is truth − the
/// model's prediction with the temperatures and operating state of `row`.
pub fn before_after(
    machine: &Machine,
    moment: String,
    truth: impl Fn([f64; 3]) -> [f64; 3],
    model: &Model,
    row: &CycleInput<'_>,
) -> VolumeMap {
    let mut map = empty_map(
        machine,
        moment,
        ("uncompensated".into(), Some("after compensation".into())),
    );
    let predicted = predicted_over(&map, machine, model, row);
    let truth: Vec<[f64; 3]> = map.points().map(truth).collect();
    let axes = grid_axes(machine);
    map.directions = (0..3)
        .filter_map(|k| Some((k, axes[k]?)))
        .map(|(k, a)| VolumeDirection {
            name: format!(
                "d{} ({})",
                machine.axes[a].name.to_lowercase(),
                machine.axes[a].name
            ),
            before: truth.iter().map(|t| t[k]).collect(),
            after: Some(
                truth
                    .iter()
                    .zip(&predicted[a])
                    .map(|(t, p)| t[k] - p)
                    .collect(),
            ),
        })
        .collect();
    map
}

/// A position-dependent model's predicted error over the volume at the row of a run where it
/// is largest at the travel's corners (the state the compensation has most to do): the error
/// the compensation removes there. Only an error the model gives is shown; the after-state is
/// unknown without a measurement over the volume. `None` when the model reads no position.
pub fn of_model(
    machine: &Machine,
    model: &Model,
    rows: &[CycleInput<'_>],
    time_s: &[f64],
) -> Option<VolumeMap> {
    if !depends_on_position(model) || rows.is_empty() {
        return None;
    }
    let corners = {
        let mut m = empty_map(machine, String::new(), (String::new(), None));
        m.coords = m.coords.map(|c| vec![c[0], c[c.len() - 1]]);
        m
    };
    let size = |i: usize| {
        predicted_over(&corners, machine, model, &rows[i])
            .iter()
            .flatten()
            .filter(|v| v.is_finite())
            .fold(0.0_f64, |m, v| m.max(v.abs()))
    };
    let worst = (0..rows.len())
        .step_by(rows.len().div_ceil(500))
        .max_by(|&a, &b| size(a).total_cmp(&size(b)))?;
    let moment = format!(
        "at t = {:.2} h of the run, where the model's error at the travel's corners is largest",
        time_s[worst] / 3600.0
    );
    let mut map = empty_map(
        machine,
        moment,
        (
            "predicted error (the compensation applies its negative)".into(),
            None,
        ),
    );
    let values = predicted_over(&map, machine, model, &rows[worst]);
    let targets: Vec<usize> = (0..machine.axes.len())
        .filter(|&a| {
            model
                .parts()
                .iter()
                .any(|p| p.summands.iter().any(|s| s.axis == a))
        })
        .collect();
    map.directions = targets
        .into_iter()
        .map(|a| VolumeDirection {
            name: format!("error of {}", machine.axes[a].name),
            before: values[a].clone(),
            after: None,
        })
        .collect();
    Some(map)
}

/// Whether any term of the model varies with an axis position (its position terms or a bed
/// factor); the prior art's position-independent form has nothing to map.
fn depends_on_position(model: &Model) -> bool {
    model
        .parts()
        .iter()
        .flat_map(|p| &p.summands)
        .any(|s| !s.position_terms.is_empty() || s.bed_multiplier.is_some())
}
