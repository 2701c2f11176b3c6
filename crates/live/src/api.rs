//! The documents the server sends, built from a [`Snapshot`] and the [`Info`]: the state as
//! JSON (`/api/state` and every `state` message of `/events`) and the Prometheus text
//! exposition (`/metrics`).

use std::fmt::Write;

use serde_json::{json, Value};
use truepos_runtime::live::{fault_name, PathView, Snapshot, FAULT_CODES};
use truepos_runtime::replay::state_name;

use crate::info::Info;
use crate::work::WorkFigures;

/// A number for JSON: `null` when it is not finite.
fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

fn path_state(p: PathView) -> &'static str {
    match p {
        PathView::Model(_) => "active",
        PathView::Holding => "holding",
        PathView::NoModel => "no-model",
        PathView::Disabled => "disabled",
    }
}

/// Service time since a source last delivered (0 while it delivers; infinite: not since start).
fn source_age_s(s: &Snapshot, i: usize) -> f64 {
    let last = s.sources_last_ok_s.get(i).copied().unwrap_or(f64::NAN);
    if last.is_nan() {
        f64::INFINITY
    } else {
        (s.time_s - last).max(0.0)
    }
}

/// The state as JSON; `work`: the cycle's work over the last minute; `wall_unix_s`: when it
/// was read.
pub fn state_json(s: &Snapshot, info: &Info, work: &WorkFigures, wall_unix_s: f64) -> Value {
    let axes: Vec<Value> = s
        .axes
        .iter()
        .enumerate()
        .map(|(a, v)| {
            json!({
                "name": info.axes.get(a).map_or("", |i| i.name.as_str()),
                "offset": num(v.offset_um),
                "target": num(v.target_um),
                "position": num(v.position),
                "clamping": v.clamping,
                "clamps": v.clamps,
                "blending": v.blending,
            })
        })
        .collect();
    let temperatures: Vec<Value> = s
        .temperatures
        .iter()
        .enumerate()
        .map(|(i, t)| {
            json!({
                "id": info.temperatures.get(i).map_or("", |c| c.id.as_str()),
                "value": num(t.value_c),
                "validation": fault_name(t.fault),
                "figure": num(t.figure),
                "age_s": num(t.age_s),
            })
        })
        .collect();
    let operating: Vec<Value> = s
        .operating
        .iter()
        .enumerate()
        .map(|(i, v)| json!({"id": info.operating.get(i).map_or("", |c| c.id.as_str()), "value": num(*v)}))
        .collect();
    let paths: Vec<Value> = s
        .paths
        .iter()
        .enumerate()
        .map(|(p, (view, extrapolating))| {
            let model = match view {
                PathView::Model(m) => Some(*m),
                _ => None,
            };
            let blending = s.axes.iter().enumerate().any(|(a, v)| {
                v.blending && info.axes.get(a).is_some_and(|i| i.path as usize == p + 1)
            });
            json!({
                "path": p + 1,
                "state": path_state(*view),
                "model": model.and_then(|m| info.models.get(m)),
                "generation": model.and_then(|m| s.generations.get(m)),
                "blending": blending,
                "extrapolating": extrapolating,
            })
        })
        .collect();
    let sources: Vec<Value> = s
        .sources_ok
        .iter()
        .enumerate()
        .map(|(i, ok)| json!({"name": info.sources.get(i), "ok": ok, "age_s": num(source_age_s(s, i))}))
        .collect();
    let sinks: Vec<Value> = s
        .sinks
        .iter()
        .enumerate()
        .map(|(i, (failing, failed))| {
            json!({"name": info.sinks.get(i), "failing": failing, "failed_writes": failed})
        })
        .collect();
    json!({
        "seq": s.seq,
        "wall_unix_s": wall_unix_s,
        "time_s": num(s.time_s),
        "state": state_name(s.state),
        "clamped": s.clamped || s.axes.iter().any(|a| a.clamping),
        "extrapolating": s.extrapolating,
        "cycles": s.cycles,
        "late_cycles": s.late_cycles,
        "cycle_work_us": num(s.cycle_work_us),
        "cycle_work": {
            "window_s": work.window_s, "cycles": work.cycles, "p50_us": num(work.p50_us),
            "p99_us": num(work.p99_us), "max_us": num(work.max_us),
        },
        "axes": axes,
        "temperatures": temperatures,
        "operating": operating,
        "paths": paths,
        "sources": sources,
        "sinks": sinks,
        "generations": s.generations,
        "log": s.log.map(|l| json!({"failing": l.failing, "pending": l.pending, "dropped": l.dropped})),
        "dropped": {"records": s.records_dropped, "events": s.events_dropped, "probes": s.probes_dropped},
    })
}

/// A label value in the text format: backslash, double quote and line feed escaped.
fn label(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// A sample value in the text format.
fn value(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else if v == f64::INFINITY {
        "+Inf".into()
    } else if v == f64::NEG_INFINITY {
        "-Inf".into()
    } else {
        format!("{v}")
    }
}

/// Writes one metric family: its help, type and samples (`(labels, value)`).
fn family(out: &mut String, name: &str, kind: &str, help: &str, samples: &[(String, f64)]) {
    let _ = writeln!(out, "# HELP {name} {help}");
    let _ = writeln!(out, "# TYPE {name} {kind}");
    for (labels, v) in samples {
        if labels.is_empty() {
            let _ = writeln!(out, "{name} {}", value(*v));
        } else {
            let _ = writeln!(out, "{name}{{{labels}}} {}", value(*v));
        }
    }
}

fn one(v: f64) -> Vec<(String, f64)> {
    vec![(String::new(), v)]
}

fn flag(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

/// The Prometheus text exposition (format 0.0.4) of the service's health: base units (metres,
/// radians, seconds, degrees Celsius), counters ending in `_total`.
pub fn metrics(s: &Snapshot, info: &Info, work: &WorkFigures) -> String {
    let mut o = String::with_capacity(8192);
    service_families(&mut o, s);
    work_family(&mut o, work);
    axis_families(&mut o, s, info);
    sensor_families(&mut o, s, info);
    link_families(&mut o, s, info);
    o
}

fn service_families(o: &mut String, s: &Snapshot) {
    family(
        o,
        "truepos_up",
        "gauge",
        "1 while the service publishes its state.",
        &one(1.0),
    );
    family(
        o,
        "truepos_service_time_seconds",
        "gauge",
        "Service time of the latest cycle.",
        &one(s.time_s),
    );
    family(
        o,
        "truepos_cycles_total",
        "counter",
        "Cycles run.",
        &one(s.cycles as f64),
    );
    family(
        o,
        "truepos_late_cycles_total",
        "counter",
        "Cycles that finished more than one period after their deadline.",
        &one(s.late_cycles as f64),
    );
    family(
        o,
        "truepos_cycle_work_seconds",
        "gauge",
        "Work of the latest cycle.",
        &one(s.cycle_work_us * 1e-6),
    );
    let states = ["active", "holding", "disabled", "no-model"];
    let now = state_name(s.state);
    let samples: Vec<(String, f64)> = states
        .iter()
        .map(|st| (format!("state=\"{st}\""), flag(*st == now)))
        .collect();
    family(
        o,
        "truepos_compensation_state",
        "gauge",
        "1 for the overall state of compensation now, 0 for the others.",
        &samples,
    );
    family(
        o,
        "truepos_compensation_active",
        "gauge",
        "1 while every path compensates with a model.",
        &one(flag(now == "active")),
    );
    family(
        o,
        "truepos_clamped",
        "gauge",
        "1 while the safety envelope clamps an axis.",
        &one(flag(s.clamped || s.axes.iter().any(|a| a.clamping))),
    );
    family(
        o,
        "truepos_extrapolating",
        "gauge",
        "1 while a model runs beyond its training envelope.",
        &one(flag(s.extrapolating)),
    );
}

/// The cycle's work as a summary: quantiles over the last minute, sum and count since start.
fn work_family(o: &mut String, w: &WorkFigures) {
    let name = "truepos_cycle_work_window_seconds";
    let _ = writeln!(
        o,
        "# HELP {name} Work of the cycles: quantiles over the last minute (0.5, 0.99 within 9 %; 1: the largest), sum and count since start."
    );
    let _ = writeln!(o, "# TYPE {name} summary");
    for (q, v) in [("0.5", w.p50_us), ("0.99", w.p99_us), ("1", w.max_us)] {
        let _ = writeln!(o, "{name}{{quantile=\"{q}\"}} {}", value(v * 1e-6));
    }
    let _ = writeln!(o, "{name}_sum {}", value(w.total_us * 1e-6));
    let _ = writeln!(o, "{name}_count {}", w.total_cycles);
}

fn axis_families(o: &mut String, s: &Snapshot, info: &Info) {
    let by_axis = |f: &dyn Fn(usize) -> f64, rotary: bool| -> Vec<(String, f64)> {
        info.axes
            .iter()
            .enumerate()
            .filter(|(_, a)| a.rotary == rotary)
            .map(|(i, a)| (format!("axis=\"{}\"", label(&a.name)), f(i)))
            .collect()
    };
    let axis = |i: usize| s.axes.get(i).copied().unwrap_or_default();
    family(
        o,
        "truepos_axis_offset_metres",
        "gauge",
        "Offset sent to a linear axis.",
        &by_axis(&|i| axis(i).offset_um * 1e-6, false),
    );
    family(
        o,
        "truepos_axis_target_metres",
        "gauge",
        "Target of a linear axis before blending and the envelope.",
        &by_axis(&|i| axis(i).target_um * 1e-6, false),
    );
    if info.axes.iter().any(|a| a.rotary) {
        family(
            o,
            "truepos_axis_offset_radians",
            "gauge",
            "Offset sent to a rotary axis.",
            &by_axis(&|i| axis(i).offset_um * 1e-6, true),
        );
        family(
            o,
            "truepos_axis_target_radians",
            "gauge",
            "Target of a rotary axis before blending and the envelope.",
            &by_axis(&|i| axis(i).target_um * 1e-6, true),
        );
    }
    let all_axes = |f: &dyn Fn(usize) -> f64| -> Vec<(String, f64)> {
        info.axes
            .iter()
            .enumerate()
            .map(|(i, a)| (format!("axis=\"{}\"", label(&a.name)), f(i)))
            .collect()
    };
    family(
        o,
        "truepos_axis_clamps_total",
        "counter",
        "Times the safety envelope began clamping an axis.",
        &all_axes(&|i| axis(i).clamps as f64),
    );
    family(
        o,
        "truepos_axis_clamping",
        "gauge",
        "1 while the safety envelope clamps the axis.",
        &all_axes(&|i| flag(axis(i).clamping)),
    );
}

fn sensor_families(o: &mut String, s: &Snapshot, info: &Info) {
    let faults: Vec<(String, f64)> = FAULT_CODES
        .iter()
        .skip(1)
        .map(|&c| {
            let n = s.temperatures.iter().filter(|t| t.fault == c).count();
            (format!("kind=\"{}\"", fault_name(c)), n as f64)
        })
        .collect();
    family(
        o,
        "truepos_sensor_faults",
        "gauge",
        "Temperature channels failing validation now, by kind of fault.",
        &faults,
    );
    let temps = |f: &dyn Fn(usize) -> f64| -> Vec<(String, f64)> {
        info.temperatures
            .iter()
            .enumerate()
            .map(|(i, c)| (format!("sensor=\"{}\"", label(&c.id)), f(i)))
            .collect()
    };
    let t = |i: usize| s.temperatures.get(i).copied().unwrap_or_default();
    family(
        o,
        "truepos_temperature_celsius",
        "gauge",
        "Latest reading of a temperature channel.",
        &temps(&|i| t(i).value_c),
    );
    family(
        o,
        "truepos_sensor_ok",
        "gauge",
        "1 while a temperature channel passes validation.",
        &temps(&|i| flag(t(i).fault == 0)),
    );
    family(
        o,
        "truepos_sensor_age_seconds",
        "gauge",
        "Time since a temperature channel's last update (+Inf: never updated).",
        &temps(&|i| t(i).age_s),
    );
}

/// The families of what the service is linked to: its sources, sinks, model set and log.
fn link_families(o: &mut String, s: &Snapshot, info: &Info) {
    source_families(o, s, info);
    sink_families(o, s, info);
    model_families(o, s, info);
    queue_families(o, s);
}

/// Per source: whether it delivers, and for how long it has not.
fn source_families(o: &mut String, s: &Snapshot, info: &Info) {
    let sources: Vec<(String, f64)> = info
        .sources
        .iter()
        .enumerate()
        .map(|(i, n)| {
            (
                format!("source=\"{}\"", label(n)),
                flag(s.sources_ok.get(i).copied().unwrap_or(false)),
            )
        })
        .collect();
    family(
        o,
        "truepos_source_up",
        "gauge",
        "1 while a source delivers.",
        &sources,
    );
    let ages: Vec<(String, f64)> = info
        .sources
        .iter()
        .enumerate()
        .map(|(i, n)| (format!("source=\"{}\"", label(n)), source_age_s(s, i)))
        .collect();
    family(
        o,
        "truepos_source_age_seconds",
        "gauge",
        "Service time since a source last delivered (0 while it delivers, +Inf: not since start).",
        &ages,
    );
}

/// Per sink: whether it fails now, and how many cycles' output it has not taken.
fn sink_families(o: &mut String, s: &Snapshot, info: &Info) {
    let sinks = |f: &dyn Fn(usize) -> f64| -> Vec<(String, f64)> {
        info.sinks
            .iter()
            .enumerate()
            .map(|(i, n)| (format!("sink=\"{}\"", label(n)), f(i)))
            .collect()
    };
    let sink = |i: usize| s.sinks.get(i).copied().unwrap_or((false, 0));
    family(
        o,
        "truepos_sink_failing",
        "gauge",
        "1 while a sink fails to take the output.",
        &sinks(&|i| flag(sink(i).0)),
    );
    family(
        o,
        "truepos_sink_failed_writes_total",
        "counter",
        "Cycles whose output a sink did not take.",
        &sinks(&|i| sink(i).1 as f64),
    );
}

/// Per model of the set its generation (reloads), and per path the model it compensates with.
fn model_families(o: &mut String, s: &Snapshot, info: &Info) {
    let models: Vec<(String, f64)> = info
        .models
        .iter()
        .enumerate()
        .map(|(i, n)| {
            (
                format!("model=\"{}\"", label(n)),
                s.generations.get(i).copied().unwrap_or(1) as f64,
            )
        })
        .collect();
    family(
        o,
        "truepos_model_generation",
        "gauge",
        "Generation of a model of the set: 1 as started, one more per reload.",
        &models,
    );
    let paths: Vec<(String, f64)> = s
        .paths
        .iter()
        .enumerate()
        .map(|(p, (v, _))| {
            (
                format!("path=\"{}\"", p + 1),
                match v {
                    PathView::Model(m) => *m as f64,
                    _ => -1.0,
                },
            )
        })
        .collect();
    family(
        o,
        "truepos_path_model",
        "gauge",
        "Index of the model a path compensates with (0 first of the set), -1 for none.",
        &paths,
    );
}

/// What the cycle could not queue for the log, and the logger's own state when there is one.
fn queue_families(o: &mut String, s: &Snapshot) {
    let dropped = [
        ("records", s.records_dropped),
        ("events", s.events_dropped),
        ("probes", s.probes_dropped),
    ];
    let samples: Vec<(String, f64)> = dropped
        .iter()
        .map(|(k, v)| (format!("what=\"{k}\""), *v as f64))
        .collect();
    family(
        o,
        "truepos_queue_dropped_total",
        "counter",
        "Items the cycle could not queue for the log.",
        &samples,
    );
    if let Some(l) = s.log {
        family(
            o,
            "truepos_log_failing",
            "gauge",
            "1 while writing the log fails.",
            &one(flag(l.failing)),
        );
        family(
            o,
            "truepos_log_pending",
            "gauge",
            "Records, events and probe events waiting to be written.",
            &one(l.pending as f64),
        );
        family(
            o,
            "truepos_log_dropped_total",
            "counter",
            "Records, events and probe events the logger dropped.",
            &one(l.dropped as f64),
        );
    }
}
