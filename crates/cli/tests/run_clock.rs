//! Replays and the twin on their own clock (issue 28, finding 4): with `@SPEED` the service runs
//! on the data's clock, so lags, blends and every other time-dependent state follow the
//! recorded time, and a run's outputs do not depend on how fast it plays.

use std::path::Path;

use truepos_runtime::log;

mod support;
use support::{command as truepos, repo, scratch};

/// A model of the twin's machine reading the spindle's front sensor, its 30-minute lag and the
/// X position, so that its output moves with the lag, the sensor and the axis.
const LAG_MODEL: &str = r#"format = "truepos-model"
version = 1
name = "lag-reader"
machine = "twin-vmc3"
description = "reads spindle_front, its 30-minute lag and the X position (test)"
axis_index = [101, 102, 103]

[[inputs.axes]]
name = "X"
travel = [0.0, 800.0]

[[inputs.axes]]
name = "Y"
travel = [0.0, 500.0]

[[inputs.axes]]
name = "Z"
travel = [0.0, 500.0]

[[inputs.differences]]
name = "dT_spindle_front"
plus = "spindle_front"
minus = "ambient"

[[inputs.differences]]
name = "dT_spindle_front_lag30min"
plus = "spindle_front_lag30min"
minus = "ambient"
plus_lag = "spindle_front, 1800 s"

[[part]]
name = "growth"
form = "regression"
axis = "Z"
constant_um = 0.0
terms = [
  { difference = "dT_spindle_front", k_um_per_k = -1.0 },
  { difference = "dT_spindle_front_lag30min", k_um_per_k = -20.0 },
]

[[part]]
name = "bending"
form = "position-dependent"

[[part.term]]
axis = "X"
difference = "dT_spindle_front"
k0_um_per_k = 0.0
position = [{ axis = "X", factor = "ratio", k_um_per_k = 2.0 }]
"#;

/// The logged cycles of a run: column names and rows of numbers (NaN for text and empty cells).
fn cycles(db: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let (names, rows) = log::read_cycles(db, None).unwrap();
    let rows = rows
        .iter()
        .map(|r| r.iter().map(|v| v.parse().unwrap_or(f64::NAN)).collect())
        .collect();
    (names, rows)
}

fn column(names: &[String], name: &str) -> usize {
    names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no column `{name}` in {names:?}"))
}

/// Runs `truepos run` with the lag model and `args`, logging every cycle.
fn run_logged(dir: &Path, name: &str, args: &[&str]) -> (Vec<String>, Vec<Vec<f64>>) {
    let model = dir.join("lag.model.toml");
    std::fs::write(&model, LAG_MODEL).unwrap();
    let db = dir.join(format!("{name}.sqlite"));
    let out = truepos()
        .args(["run", "--machine", "examples/twin/machine.toml", "--models"])
        .arg(&model)
        .args(["--log-every-s", "0", "--json", "--log"])
        .arg(&db)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    cycles(&db)
}

/// Six seconds of a run: the spindle's sensor steps up by 2.5 K at 1 s (within the noise band,
/// so no rate fault), X travels from 100 to 700 mm.
fn short_run(dir: &Path) -> std::path::PathBuf {
    let mut csv = String::from("time_s,X_mm,Y_mm,Z_mm,ambient,spindle_front\n");
    for i in 0..=24 {
        let t = i as f64 * 0.25;
        let spindle = if t < 1.0 { 21.0 } else { 23.5 };
        csv += &format!("{t},{},250,250,20.0,{spindle}\n", 100.0 + 100.0 * t);
    }
    let path = dir.join("short.csv");
    std::fs::write(&path, csv).unwrap();
    path
}

/// `@1` and `@600` give the same outputs and lags at the same data times (before the service
/// ran on the data's clock, `@600` logged 1/600 of the data time per cycle and its lags hardly
/// moved).
#[test]
fn a_replay_at_600_gives_the_outputs_of_speed_1_on_the_data_clock() {
    let dir = scratch("clock-speed");
    let run = short_run(&dir);
    let source = |speed: &str| format!("replay:{}@{speed}", run.display());
    let common = ["--period-ms", "50", "--blend-s", "2", "--source"];
    let started = std::time::Instant::now();
    let (names, slow) = run_logged(&dir, "at1", &[&common[..], &[&source("1")]].concat());
    let slow_took = started.elapsed().as_secs_f64();
    let started = std::time::Instant::now();
    let (names_fast, fast) = run_logged(&dir, "at600", &[&common[..], &[&source("600")]].concat());
    let fast_took = started.elapsed().as_secs_f64();
    assert_eq!(names, names_fast);
    // Both cover the six seconds of data, each in its own real time.
    assert!(slow_took > 5.0, "@1 took {slow_took} s");
    assert!(fast_took < slow_took / 2.0, "@600 took {fast_took} s");
    assert_eq!(slow.len(), fast.len(), "cycles logged");
    assert!(slow.len() >= 120, "{} cycles", slow.len());
    let t = column(&names, "time_s");
    let mut compared = 0;
    for (a, b) in slow.iter().zip(&fast) {
        assert!((a[t] - b[t]).abs() < 1e-9, "times {} and {}", a[t], b[t]);
        for (c, n) in names.iter().enumerate() {
            if a[c].is_nan() && b[c].is_nan() {
                continue;
            }
            assert!(
                (a[c] - b[c]).abs() <= 1e-9,
                "`{n}` at {} s: {} at @1, {} at @600",
                a[t],
                a[c],
                b[c]
            );
            compared += 1;
        }
    }
    assert!(compared > slow.len() * 5, "{compared} values compared");
    // The lag and the output moved over the run: the comparison saw them change.
    let lag = column(&names, "spindle_front_lag30min");
    let z = column(&names, "Z_offset_um");
    let last = fast.last().unwrap();
    assert!(
        last[lag] - fast[0][lag] > 0.005,
        "{} → {}",
        fast[0][lag],
        last[lag]
    );
    assert!(last[z].abs() > 10.0, "Z offset {}", last[z]);
    std::fs::remove_dir_all(&dir).ok();
}

/// The issue's case: the twin at speed, 100 simulated minutes. Before, `spindle_front` read
/// 37.2 °C while its 30-minute lag still read 21.4 °C (the lag ran on the service's clock, 60 ×
/// slower than the data's); now the lag is exactly a first-order lag of its sensor on the
/// data's clock, as `truepos fit` and `eval` compute it from the same rows.
#[test]
fn a_lag_follows_its_sensor_on_the_data_clock_at_3000_times_real_time() {
    let dir = scratch("clock-lag");
    let started = std::time::Instant::now();
    let (names, rows) = run_logged(
        &dir,
        "twin",
        &[
            "--source",
            "twin:mixed-shift-b@3000",
            "--period-ms",
            "1000",
            "--duration-s",
            "6000",
        ],
    );
    // 6000 s of data at 3000 × real time: about two seconds, not 100 minutes.
    assert!(started.elapsed().as_secs_f64() < 60.0);
    let t = column(&names, "time_s");
    assert!((rows.last().unwrap()[t] - 6000.0).abs() <= 1.0 + 1e-9);
    let machine = truepos_io::machine_file::load(&repo("examples/twin/machine.toml"))
        .unwrap()
        .machine;
    // The logged sensors, with the lagged channels recomputed from them on the logged times.
    let times: Vec<f64> = rows.iter().map(|r| r[t]).collect();
    let ids: Vec<usize> = machine
        .temperatures
        .iter()
        .map(|c| column(&names, &c.id))
        .collect();
    let mut temps: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            machine
                .temperatures
                .iter()
                .zip(&ids)
                .map(|(c, &i)| if c.lag.is_some() { f64::NAN } else { r[i] })
                .collect()
        })
        .collect();
    let ops: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            machine
                .operating
                .iter()
                .map(|o| r[column(&names, &o.id)])
                .collect()
        })
        .collect();
    truepos_io::cycles::fill_lags(&machine, &times, &mut temps, &ops);
    let sensor = column(&names, "spindle_front");
    let lag = column(&names, "spindle_front_lag30min");
    let lag_channel = machine
        .temperatures
        .iter()
        .position(|c| c.id == "spindle_front_lag30min")
        .unwrap();
    for (r, expected) in rows.iter().zip(&temps) {
        assert!(
            (r[lag] - expected[lag_channel]).abs() < 1e-9,
            "at {} s the lag reads {} °C, its sensor's lag on the data clock {} °C",
            r[t],
            r[lag],
            expected[lag_channel]
        );
    }
    // The service's clock is the data's: at every logged time the sensor reads what the twin's
    // own run (`truepos sim`, same scenario and seed, 3 decimals) holds at that time.
    let sim = dir.join("twin.csv");
    let (ok, _, err) = support::run(&[
        "sim",
        "--scenario",
        "mixed-shift-b",
        "--seed",
        "1",
        "-o",
        sim.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&sim).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let at = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (sim_t, sim_v) = (at("time_s"), at("spindle_front"));
    let twin: Vec<(f64, f64)> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[sim_t].parse().unwrap(), f[sim_v].parse().unwrap())
        })
        .collect();
    for r in &rows {
        let (when, v) = twin.iter().rev().find(|(ts, _)| *ts <= r[t]).unwrap();
        assert!(
            (r[sensor] - v).abs() < 0.002,
            "at {} s spindle_front reads {} °C, the twin's run {v} °C (at {when} s)",
            r[t],
            r[sensor]
        );
    }
    // After 100 minutes of warm-up the lag has followed most of its sensor's rise.
    let (first, last) = (&rows[0], rows.last().unwrap());
    let rise = last[sensor] - first[sensor];
    assert!(rise > 10.0, "spindle_front rose {rise} K");
    assert!(
        last[lag] - first[lag] > 0.5 * rise,
        "lag {} → {} while its sensor {} → {}",
        first[lag],
        last[lag],
        first[sensor],
        last[sensor]
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A run has one clock: recorded sources at different speeds, or a speed beside a source that
/// delivers in real time, are refused before anything runs.
#[test]
fn one_clock_per_run() {
    let (ok, _, err) = support::run(&[
        "run",
        "--fast",
        "--source",
        "replay:examples/vmc3/run.csv@60",
        "--source",
        "probes:examples/vmc3/run.csv@10",
    ]);
    assert!(!ok);
    assert!(err.contains("one clock") && err.contains("@10"), "{err}");
    let (ok, _, err) = support::run(&[
        "run",
        "--fast",
        "--source",
        "replay:examples/vmc3/run.csv@60",
        "--source",
        "modbus:nonexistent.toml",
    ]);
    assert!(!ok);
    assert!(
        err.contains("real time") && err.contains("modbus:nonexistent.toml"),
        "{err}"
    );
}
