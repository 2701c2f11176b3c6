//! What the component should have sent in a cycle: the model the axis-combination rule selects for
//! the recorded axis configuration, its compensation, and the size of its position-dependent terms.

use truepos_model::{CycleInput, Machine, Model};
use truepos_runtime::model_set::{index_of, ModelEntry};
use truepos_runtime::AxisConfig;

use super::record::Sample;
use super::replay::Replay;

/// Span over the travel of each axis' compensation when one axis moves end to end (the others
/// where they are): the size of the position-dependent terms at these temperatures, µm.
pub fn position_span_um(
    model: &Model,
    machine: &Machine,
    s: &Sample,
    operating: &[f64],
) -> Vec<f64> {
    let axes = machine.axes.len();
    let mut span = vec![0.0f64; axes];
    let mut pos = s.nominal.clone();
    for (j, axis) in machine.axes.iter().enumerate() {
        let at = |p: f64, pos: &mut Vec<f64>| {
            pos[j] = p;
            model
                .evaluate(&CycleInput {
                    temperatures_c: &s.temperatures_c,
                    positions: pos,
                    operating,
                })
                .ok()
        };
        let lo = at(axis.travel_min, &mut pos);
        let hi = at(axis.travel_max, &mut pos);
        pos[j] = s.nominal[j];
        if let (Some(lo), Some(hi)) = (lo, hi) {
            for (a, sp) in span.iter_mut().enumerate() {
                *sp = sp.max((hi.compensation_um(a) - lo.compensation_um(a)).abs());
            }
        }
    }
    span
}

/// The model the axis-combination rule selects for path 1: the models whose axis-combination index
/// equals the index of the axes in path 1 (by axis number), `select` if it is one of them, else the
/// first; `None` if none matches.
pub fn expected_model(
    models: &[ModelEntry],
    limits: &[AxisConfig],
    axis_paths: &[i32],
    select: i32,
) -> Option<usize> {
    let mut in_path: Vec<usize> = (0..limits.len())
        .filter(|&a| axis_paths.get(a) == Some(&1))
        .collect();
    in_path.sort_by_key(|&a| limits[a].number);
    let target = index_of(in_path.iter().map(|&a| limits[a].code()));
    let matches = |i: &usize| models[*i].index == target;
    usize::try_from(select)
        .ok()
        .filter(|i| *i < models.len() && matches(i))
        .or_else(|| (0..models.len()).find(matches))
}

/// Each axis' target in cycle `s`, the `k`th recorded (µm): the compensation of the model the
/// axis-combination rule selects, as replayed on the recorded cycles (at the cycle's temperatures
/// and nominal positions, a dynamic model with its history), for an active axis in path 1; zero for
/// an axis in no path and for a component disabled or without a model (and for a hold, whose ramp
/// [`super::output_invariant`] works out). `None` where the model gave nothing.
pub fn targets_um(
    machine: &Machine,
    models: &[ModelEntry],
    replay: &Replay,
    limits: &[AxisConfig],
    s: &Sample,
    k: usize,
) -> Vec<Option<f64>> {
    let axes = machine.axes.len();
    let in_path = |a: usize| s.axis_paths.get(a) == Some(&1);
    if !s.active() {
        return vec![Some(0.0); axes];
    }
    let error_um =
        expected_model(models, limits, &s.axis_paths, s.select).and_then(|i| replay.error_um(i, k));
    (0..axes)
        .map(|a| match (error_um, in_path(a)) {
            (_, false) => Some(0.0),
            // 0 − e: the compensation, +0 for a zero error.
            (Some(e), true) => Some(0.0 - e[a]),
            (None, true) => None,
        })
        .collect()
}
