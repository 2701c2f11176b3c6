//! `truepos status`: what a running (or ended) service is doing, for a person, read from its
//! log — the clock time of the last cycle, the state and why it is not active, the model per
//! path, the offsets to 0.01 µm, the positions, temperatures and operating state with units,
//! faults and the last events; `--follow` refreshes it in place until Ctrl-C.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::Duration;

use truepos_io::limits::finite_in;
use truepos_runtime::log::{self, LoggedEvent};

use crate::error::CliError;

/// Arguments of `truepos status`.
#[derive(clap::Args)]
pub struct StatusArgs {
    /// The service's log.
    #[arg(long)]
    log: PathBuf,
    /// Print as JSON.
    #[arg(long, conflicts_with = "follow")]
    json: bool,
    /// Refresh in place every --every-s seconds until Ctrl-C.
    #[arg(long)]
    follow: bool,
    /// Seconds between refreshes with --follow, 0.2–3600.
    #[arg(long, default_value_t = 1.0, value_parser = finite_in(0.2, 3600.0))]
    every_s: f64,
    /// With --follow: stop after this many refreshes (for scripts and tests).
    #[arg(long, hide = true)]
    times: Option<u64>,
}

pub fn show_status(args: StatusArgs) -> Result<(), CliError> {
    if args.json {
        println!("{}", snapshot(&args)?.json);
        return Ok(());
    }
    if !args.follow {
        print!("{}", snapshot(&args)?.text);
        return Ok(());
    }
    let terminal = std::io::stdout().is_terminal();
    let mut shown = 0u64;
    loop {
        let text = snapshot(&args)?.text;
        let mut out = std::io::stdout().lock();
        // Clear the screen and go home on a terminal; a pipe gets the snapshots one after another.
        let clear = if terminal { "\x1b[2J\x1b[H" } else { "" };
        let footer = format!("(every {} s; Ctrl-C to leave)\n", args.every_s);
        write!(out, "{clear}{text}{footer}").map_err(CliError::Stdout)?;
        out.flush().map_err(CliError::Stdout)?;
        shown += 1;
        if args.times.is_some_and(|n| shown >= n) {
            return Ok(());
        }
        std::thread::sleep(Duration::from_secs_f64(args.every_s));
    }
}

/// The status as text for a person and as JSON.
struct Snapshot {
    text: String,
    json: serde_json::Value,
}

/// One named value of the last cycle: its column, value (NaN when the log has none) and unit.
struct Value {
    name: String,
    value: f64,
    unit: &'static str,
}

fn snapshot(args: &StatusArgs) -> Result<Snapshot, CliError> {
    let (names, rows) = log::read_cycles(&args.log, Some(1))?;
    let events = log::read_events(&args.log)?;
    let meta = log::read_meta(&args.log)?.unwrap_or_default();
    let started = meta["started_unix_s"].as_f64();
    let clock = |t: f64| {
        started
            .and_then(|s| truepos_io::timestamp::format_utc(s + t))
            .unwrap_or_else(|| format!("{t:.1} s"))
    };
    let list = |key: &str| -> Vec<String> {
        meta[key]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|v| v.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default()
    };
    let (sensors, models) = (list("sensors"), list("models"));
    let last = rows.last();
    let LastCycle {
        state,
        time_s,
        offsets,
        positions,
        temperatures,
        operating,
        path_models,
    } = last_cycle(&names, last, &sensors, &models);
    let sensor_faults = sensor_faults(&events, &sensors, &temperatures);
    let links = link_faults(&events);
    let why = if state.is_empty() || state == "active" {
        Vec::new()
    } else {
        reasons(&events, &positions, &sensor_faults, &links, &clock)
    };
    let extrapolating = extrapolating(&events);
    let text = render(&Parts {
        machine: meta["machine"].as_str().unwrap_or("?"),
        log: &args.log,
        logged: last.is_some(),
        time_s,
        state: &state,
        why: &why,
        extrapolating: &extrapolating,
        path_models: &path_models,
        rows: [
            ("offsets", &offsets, 2, true),
            ("positions", &positions, 3, false),
            ("temperatures", &temperatures, 2, false),
            ("operating", &operating, 1, false),
        ],
        sensor_faults: &sensor_faults,
        links: &links,
        events: &events,
        clock: &clock,
    });
    let named = |v: &[Value]| -> serde_json::Map<String, serde_json::Value> {
        v.iter()
            .map(|x| (x.name.clone(), finite(x.value)))
            .collect()
    };
    let last_cycle = cycle_map(&names, last);
    let json = serde_json::json!({
        "last_cycle": last_cycle,
        "machine": meta["machine"],
        "time_s": finite(time_s),
        "clock_utc": last.map(|_| clock(time_s)),
        "state": state,
        "why": why,
        "extrapolating": extrapolating,
        "models": path_models.iter().map(|(p, m)| serde_json::json!({"path": p, "model": m})).collect::<Vec<_>>(),
        "offsets_um": named(&offsets),
        "positions": named(&positions),
        "temperatures_c": named(&temperatures),
        "operating": named(&operating),
        "events": events.len(),
        "bad_sensors": sensor_faults.iter().map(|(s, d)| serde_json::json!({"sensor": s, "reason": d})).collect::<Vec<_>>(),
        "failing": links.iter().map(|(s, d)| serde_json::json!({"what": s, "reason": d})).collect::<Vec<_>>(),
        "recent_events": events.iter().rev().take(5).collect::<Vec<_>>(),
    });
    Ok(Snapshot { text, json })
}

/// The last cycle's columns by what they are: the offsets, the axes' positions, the logged
/// sensors' temperatures, the operating channels (every other column) and per path the model
/// in effect; with the service state and time. A missing cycle gives NaN values.
struct LastCycle {
    state: String,
    time_s: f64,
    offsets: Vec<Value>,
    positions: Vec<Value>,
    temperatures: Vec<Value>,
    operating: Vec<Value>,
    path_models: Vec<(String, String)>,
}

/// Sorts the last cycle's columns (`names`, the cells `last`) into a [`LastCycle`]; `sensors`
/// tells temperatures from operating channels and `models` names the models by index.
fn last_cycle(
    names: &[String],
    last: Option<&Vec<String>>,
    sensors: &[String],
    models: &[String],
) -> LastCycle {
    let cell = |name: &str| -> Option<&String> {
        let c = names.iter().position(|n| n == name)?;
        last.map(|r| &r[c])
    };
    let number = |name: &str| {
        cell(name)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    let values = |pick: &dyn Fn(&str) -> Option<(String, &'static str)>| -> Vec<Value> {
        names
            .iter()
            .filter_map(|n| {
                let (name, unit) = pick(n)?;
                Some(Value {
                    name,
                    value: number(n),
                    unit,
                })
            })
            .collect()
    };
    let offsets = values(&|n| Some((n.strip_suffix("_offset_um")?.to_string(), "µm")));
    let positions = values(&|n| {
        n.strip_suffix("_mm")
            .map(|a| (a.to_string(), "mm"))
            .or_else(|| n.strip_suffix("_deg").map(|a| (a.to_string(), "°")))
    });
    let temperatures = values(&|n| {
        sensors
            .iter()
            .any(|s| s == n)
            .then(|| (n.to_string(), "°C"))
    });
    let known = |n: &str| {
        n == "time_s"
            || n == "state"
            || n.starts_with("model_path")
            || n.ends_with("_offset_um")
            || n.ends_with("_mm")
            || n.ends_with("_deg")
            || sensors.iter().any(|s| s == n)
    };
    let operating = values(&|n| (!known(n)).then(|| (n.to_string(), "")));
    let path_models: Vec<(String, String)> = names
        .iter()
        .filter(|n| n.starts_with("model_path"))
        .map(|n| {
            let path = n.trim_start_matches("model_path").to_string();
            let model = match cell(n).and_then(|v| v.parse::<f64>().ok()) {
                Some(i) if i >= 0.0 => models
                    .get(i as usize)
                    .cloned()
                    .unwrap_or_else(|| format!("model {i}")),
                _ if models.is_empty() => "none in effect".to_string(),
                _ => format!("none in effect (loaded: {})", models.join(", ")),
            };
            (path, model)
        })
        .collect();
    let state = cell("state").cloned().unwrap_or_default();
    LastCycle {
        state,
        time_s: number("time_s"),
        offsets,
        positions,
        temperatures,
        operating,
        path_models,
    }
}

/// What the text for a person is made of.
struct Parts<'a> {
    machine: &'a str,
    log: &'a std::path::Path,
    logged: bool,
    time_s: f64,
    state: &'a str,
    why: &'a [String],
    extrapolating: &'a [String],
    path_models: &'a [(String, String)],
    /// (title, values, decimals, signed) per line.
    rows: [(&'a str, &'a [Value], usize, bool); 4],
    sensor_faults: &'a [(String, String)],
    links: &'a [(String, String)],
    events: &'a [LoggedEvent],
    clock: &'a dyn Fn(f64) -> String,
}

fn render(p: &Parts<'_>) -> String {
    let mut text = format!("machine {} — log {}\n", p.machine, p.log.display());
    if !p.logged {
        text += "no cycle logged yet\n";
    } else {
        text += &format!(
            "last cycle: {} (service time {:.1} s)\n",
            (p.clock)(p.time_s),
            p.time_s
        );
        text += &format!("state: {}\n", p.state.to_uppercase());
        for w in p.why {
            text += &format!("  why: {w}\n");
        }
        for e in p.extrapolating {
            text += &format!("EXTRAPOLATING: {e}\n");
        }
        for (path, m) in p.path_models {
            text += &format!("path {path}: model {m}\n");
        }
        for (title, values, decimals, signed) in p.rows {
            if !values.is_empty() {
                text += &line(title, values, decimals, signed);
            }
        }
        if p.sensor_faults.is_empty() {
            text += "sensors: all good\n";
        }
    }
    for (s, d) in p.sensor_faults {
        text += &format!("sensor {s}: {d}\n");
    }
    for (what, d) in p.links {
        text += &format!("{what}: {d}\n");
    }
    if !p.events.is_empty() {
        text += "recent events:\n";
    }
    for e in p.events.iter().rev().take(5).rev() {
        text += &format!(
            "  {}  {:<18} {:<16} {}\n",
            (p.clock)(e.time_s),
            e.kind,
            e.subject,
            e.detail
        );
    }
    text
}

/// The last cycle as JSON, column by column (numbers as numbers, the state as text).
fn cycle_map(
    names: &[String],
    last: Option<&Vec<String>>,
) -> serde_json::Map<String, serde_json::Value> {
    let Some(row) = last else {
        return serde_json::Map::new();
    };
    names
        .iter()
        .zip(row)
        .map(|(n, v)| {
            let value = v
                .parse::<f64>()
                .map(serde_json::Value::from)
                .unwrap_or_else(|_| serde_json::Value::from(v.clone()));
            (n.clone(), value)
        })
        .collect()
}

fn finite(v: f64) -> serde_json::Value {
    if v.is_finite() {
        v.into()
    } else {
        serde_json::Value::Null
    }
}

/// `title: A 1.00 µm, B –` with `decimals` places (and the sign when `signed`); a value the log
/// lacks is a dash.
fn line(title: &str, values: &[Value], decimals: usize, signed: bool) -> String {
    let items: Vec<String> = values
        .iter()
        .map(|v| {
            let sep = if v.unit.is_empty() || v.unit == "°" {
                ""
            } else {
                " "
            };
            match (v.value.is_finite(), signed) {
                (false, _) => format!("{} –", v.name),
                (true, true) => format!("{} {:+.*}{sep}{}", v.name, decimals, v.value, v.unit),
                (true, false) => format!("{} {:.*}{sep}{}", v.name, decimals, v.value, v.unit),
            }
        })
        .collect();
    format!("{title}: {}\n", items.join(", "))
}

/// Paths whose model is beyond its training envelope now: the last `extrapolating` event of
/// each path not followed by its `extrapolation-ended`.
fn extrapolating(events: &[LoggedEvent]) -> Vec<String> {
    let mut open: Vec<(&str, String)> = Vec::new();
    for e in events {
        match e.kind.as_str() {
            "extrapolating" => {
                open.retain(|(p, _)| *p != e.subject);
                open.push((e.subject.as_str(), format!("{}: {}", e.subject, e.detail)));
            }
            "extrapolation-ended" => open.retain(|(p, _)| *p != e.subject),
            _ => {}
        }
    }
    open.into_iter().map(|(_, d)| d).collect()
}

/// Sensors faulty now: from the last fault or recovery event of each, and — since a sensor that
/// never delivered raises no event (the validator starts every channel as never updated) — a
/// sensor without a value in the last cycle.
fn sensor_faults(
    events: &[LoggedEvent],
    sensors: &[String],
    temperatures: &[Value],
) -> Vec<(String, String)> {
    let mut faults: Vec<(String, String)> = Vec::new();
    for e in events {
        match e.kind.as_str() {
            "sensor-fault" => {
                faults.retain(|(s, _)| s != &e.subject);
                faults.push((e.subject.clone(), e.detail.clone()));
            }
            "sensor-recovered" => faults.retain(|(s, _)| s != &e.subject),
            _ => {}
        }
    }
    for t in temperatures {
        if !t.value.is_finite()
            && sensors.contains(&t.name)
            && !faults.iter().any(|(s, _)| s == &t.name)
        {
            faults.push((t.name.clone(), "no value in the last logged cycle".into()));
        }
    }
    faults
}

/// Why the service is not active, as far as its log tells: positions missing or faulty, bad
/// sensors, lost sources, and the last state event's own words.
fn reasons(
    events: &[LoggedEvent],
    positions: &[Value],
    sensor_faults: &[(String, String)],
    links: &[(String, String)],
    clock: &dyn Fn(f64) -> String,
) -> Vec<String> {
    let mut why = Vec::new();
    let missing: Vec<&str> = positions
        .iter()
        .filter(|p| !p.value.is_finite())
        .map(|p| p.name.as_str())
        .collect();
    if !missing.is_empty() {
        why.push(format!(
            "no axis position for {} in the last cycle: a position-dependent model needs a source \
             that delivers them (the control, or a replay with position columns)",
            missing.join(", ")
        ));
    }
    let mut position_fault = None;
    for e in events {
        match e.kind.as_str() {
            "position-fault" => position_fault = Some(e),
            "position-recovered" => position_fault = None,
            _ => {}
        }
    }
    if let Some(e) = position_fault {
        why.push(format!(
            "position of {}: {} (since {})",
            e.subject,
            e.detail,
            clock(e.time_s)
        ));
    }
    for (s, d) in sensor_faults {
        why.push(format!("sensor {s}: {d}"));
    }
    for (what, d) in links.iter().filter(|(w, _)| w.starts_with("source")) {
        why.push(format!("{what}: {d}"));
    }
    let state_event = events
        .iter()
        .rev()
        .find(|e| matches!(e.kind.as_str(), "holding" | "no-model" | "disabled"));
    if let Some(e) = state_event {
        let detail = if e.detail.is_empty() {
            ""
        } else {
            e.detail.as_str()
        };
        why.push(format!(
            "{} {} since {}{}{detail}",
            e.kind,
            e.subject,
            clock(e.time_s),
            if detail.is_empty() { "" } else { ": " }
        ));
    }
    if why.is_empty() {
        why.push("the log does not say (see `truepos log`)".into());
    }
    why
}

/// Sources lost and sinks failing at the last event, and failures of the log itself: (what, why).
fn link_faults(events: &[log::LoggedEvent]) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    let mut log_failed = None;
    for e in events {
        match e.kind.as_str() {
            "sink-failed" | "sink-back" => {
                let what = format!("sink `{}`", e.subject);
                out.retain(|(w, _)| w != &what);
                if e.kind == "sink-failed" {
                    let why = format!("FAILING since {:.1} s: {}", e.time_s, e.detail);
                    out.push((what, why));
                }
            }
            "source-lost" | "source-back" => {
                let what = format!("source `{}`", e.subject);
                out.retain(|(w, _)| w != &what);
                if e.kind == "source-lost" {
                    out.push((what, format!("LOST since {:.1} s: {}", e.time_s, e.detail)));
                }
            }
            "log-failed" => log_failed = Some(e),
            // The logger writes both once the disk takes them again: while it still fails,
            // only the running service's status line and its exit message can tell.
            "log-resumed" => {
                let failed = log_failed.map_or(String::new(), |f| {
                    format!(" at {:.1} s ({})", f.time_s, f.detail)
                });
                let why = format!("writing FAILED{failed}; {}", e.detail);
                out.retain(|(w, _)| w != "log");
                out.push(("log".into(), why));
            }
            _ => {}
        }
    }
    out
}
