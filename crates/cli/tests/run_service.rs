//! `truepos run` as a process: a replay through the service into the log, the inspection
//! commands, and the log surviving SIGKILL at any moment.

use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use truepos_runtime::log;

mod support;
use support::{command as truepos, repo, scratch};

#[test]
fn fast_replay_logs_cycles_and_events_and_exports_a_run() {
    let dir = scratch("fast");
    let db = dir.join("log.sqlite");
    let out = truepos()
        .args(["run", "--fast", "--period-ms", "1000", "--json", "--log"])
        .arg(&db)
        .arg("--sink")
        .arg(format!("csv:{}", dir.join("offsets.csv").display()))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // The example run lasts 4 h: 14 400 s of service time at 1 s.
    assert!(v["cycles"].as_u64().unwrap() >= 14_400, "{v}");
    assert_eq!(v["state"], "active");
    assert_eq!(log::integrity_check(&db).unwrap(), "ok");
    let events = log::read_events(&db).unwrap();
    assert!(events
        .iter()
        .any(|e| e.kind == "model-selected" && e.detail == "vmc3-example"));
    // The example run is sound: no sensor fault, no holding.
    assert!(
        events.iter().all(|e| e.kind == "model-selected"),
        "{events:?}"
    );

    // `truepos log --csv` gives a run with the machine's column names.
    let run_csv = dir.join("run.csv");
    let st = truepos()
        .args(["log", "--log"])
        .arg(&db)
        .arg("--csv")
        .arg(&run_csv)
        .status()
        .unwrap();
    assert!(st.success());
    let text = std::fs::read_to_string(&run_csv).unwrap();
    let header = text.lines().next().unwrap();
    assert!(
        header.starts_with("time_s,state,model_path1,X_mm,Y_mm,Z_mm,x_slide_top"),
        "{header}"
    );
    assert!(
        header.ends_with("X_offset_um,Y_offset_um,Z_offset_um,X_target_um,Y_target_um,Z_target_um"),
        "{header}"
    );

    let status = truepos()
        .args(["status", "--json", "--log"])
        .arg(&db)
        .output()
        .unwrap();
    assert!(status.status.success());
    let s: serde_json::Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(s["last_cycle"]["state"], "active");
    assert!(s["bad_sensors"].as_array().unwrap().is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

/// Kill the service with SIGKILL at several moments; each time the file passes SQLite's
/// integrity check and holds every cycle up to at most one second before the kill.
#[test]
fn sigkill_loses_at_most_the_last_second_and_never_corrupts_the_log() {
    let dir = scratch("kill");
    for (i, after_ms) in [700u64, 1100, 1600, 2100, 2600].into_iter().enumerate() {
        let db = dir.join(format!("log{i}.sqlite"));
        let spawned = Instant::now();
        let mut child = truepos()
            .args(["run", "--period-ms", "1", "--log-every-s", "0.01", "--log"])
            .arg(&db)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(after_ms));
        child.kill().unwrap(); // SIGKILL on Unix
        let killed_after_s = spawned.elapsed().as_secs_f64();
        child.wait().unwrap();
        assert_eq!(log::integrity_check(&db).unwrap(), "ok", "kill {i}");
        let (names, rows) = log::read_cycles(&db, Some(1)).unwrap();
        let t = names.iter().position(|n| n == "time_s").unwrap();
        let last: f64 = rows.last().expect("cycles were logged")[t].parse().unwrap();
        // Service time starts when the files are loaded, a little after the spawn; allow 0.3 s
        // for that start-up on a loaded 2-core machine.
        let lost = killed_after_s - last;
        assert!(
            lost <= 1.0 + 0.3,
            "kill {i} after {killed_after_s:.2} s: last logged cycle at {last:.2} s"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The learning loop closed through the service: the twin records a day, `truepos fit` writes a
/// dynamic model file, `truepos run` loads it for the twin's machine and replays the day; the
/// offsets applied are the negated in-sample predictions of the model written. The service holds each sample until
/// the next one arrives while the fit lets each sample act over the interval before it, so the
/// two differ by one sample's worth of filter input (≈ 0.1 µm here), not more.
#[test]
fn a_fitted_dynamic_model_runs_in_the_service() {
    let dir = scratch("dynamic");
    let day = dir.join("day.csv");
    let st = truepos()
        .args(["sim", "--scenario", "spindle-warmup", "--seed", "1", "-o"])
        .arg(&day)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let model = dir.join("spindle.json");
    let predictions = dir.join("pred.csv");
    let st = truepos()
        .args(["fit", "--run"])
        .arg(&day)
        .args(["--target", "dx_um,dy_um,dz_um"])
        .args([
            "--inputs",
            "spindle_front,spindle_rear,spindle_motor,ambient,spindle_rpm",
        ])
        .args([
            "--machine-name",
            "twin-vmc3",
            "--family",
            "dynamic",
            "--ridge",
            "1e-3",
        ])
        .arg("--model")
        .arg(&model)
        .arg("--predictions")
        .arg(&predictions)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let offsets = dir.join("offsets.csv");
    let out = truepos()
        .args(["run", "--fast", "--period-ms", "1000", "--json"])
        .args(["--machine", "examples/twin/machine.toml", "--models"])
        .arg(&model)
        .arg("--source")
        .arg(format!("replay:{}", day.display()))
        .arg("--sink")
        .arg(format!("csv:{}", offsets.display()))
        .args(["--sink-every-s", "10"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["state"], "active", "{v}");

    let read = |p: &Path| -> (Vec<String>, Vec<Vec<String>>) {
        let text = std::fs::read_to_string(p).unwrap();
        let mut lines = text.lines();
        let header = lines
            .next()
            .unwrap()
            .split(',')
            .map(str::to_string)
            .collect();
        let rows = lines
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        (header, rows)
    };
    let (ph, prows) = read(&predictions);
    let (oh, orows) = read(&offsets);
    let col = |h: &[String], name: &str| h.iter().position(|c| c == name).unwrap();
    let mut predicted = std::collections::HashMap::new();
    // The rows no fold held out are predicted by the model written (the rest by the fold's
    // model, which the service never sees).
    for r in prows.iter().filter(|r| r[col(&ph, "held_out")] == "false") {
        let t: f64 = r[col(&ph, "time_s")].parse().unwrap();
        predicted.insert(t as i64, r.clone());
    }
    let mut compared = 0;
    for r in &orows {
        let t: f64 = r[col(&oh, "time_s")].parse().unwrap();
        // After the start-up blend (5 s); the day is sampled every 10 s.
        let Some(p) = predicted.get(&(t as i64)).filter(|_| t > 60.0) else {
            continue;
        };
        for (axis, target) in [("X", "dx_um"), ("Y", "dy_um"), ("Z", "dz_um")] {
            let offset: f64 = r[col(&oh, &format!("{axis}_offset_um"))].parse().unwrap();
            let pred: f64 = p[col(&ph, &format!("{target}_predicted"))].parse().unwrap();
            assert!(
                (offset + pred).abs() < 0.25,
                "t = {t} s, {axis}: offset {offset} µm, predicted error {pred} µm"
            );
        }
        compared += 1;
    }
    assert!(compared > 1000, "{compared}");

    // `truepos eval` steps the model through the rows as the fit did: the same numbers where the
    // fit predicted with the model written.
    let evaluated = dir.join("eval.csv");
    let st = truepos()
        .args(["eval", "--machine", "examples/twin/machine.toml", "--model"])
        .arg(&model)
        .arg("--run")
        .arg(&day)
        .arg("-o")
        .arg(&evaluated)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let (eh, erows) = read(&evaluated);
    assert_eq!(erows.len(), prows.len());
    let in_sample = |p: &&(&Vec<String>, &Vec<String>)| p.1[col(&ph, "held_out")] == "false";
    for (e, p) in erows
        .iter()
        .zip(&prows)
        .collect::<Vec<_>>()
        .iter()
        .filter(in_sample)
    {
        for (axis, target) in [("X", "dx_um"), ("Y", "dy_um"), ("Z", "dz_um")] {
            let a: f64 = e[col(&eh, &format!("{axis}_error_um"))].parse().unwrap();
            let b: f64 = p[col(&ph, &format!("{target}_predicted"))].parse().unwrap();
            assert!((a - b).abs() < 1e-5, "{axis}: eval {a} vs fit {b}");
        }
    }

    // `truepos report` on the held-out part (the last 40 % of the 8 h day, from 17,280 s) of
    // the same model: figures and the coefficient table of a dynamic model.
    let out = truepos()
        .args([
            "report",
            "--machine",
            "examples/twin/machine.toml",
            "--model",
        ])
        .arg(&model)
        .arg("--run")
        .arg(&day)
        .args([
            "--measured",
            "X=dx_um,Y=dy_um,Z=dz_um",
            "--test-from-s",
            "17280",
            "--json",
        ])
        .arg("--out")
        .arg(dir.join("report"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let z = &v["channels"][2]["metrics"];
    assert!(
        z["rmse_um"].as_f64().unwrap() < 0.5 * z["uncompensated_rmse_um"].as_f64().unwrap(),
        "{v}"
    );
    let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
    assert!(
        html.contains("spindle_front (temperature)") && html.contains("rise, lagged τ = 15 min"),
        "the dynamic coefficients are listed, grouped by input, in words"
    );
}

/// Runs `truepos` with `args`, killed after `limit`: a process still running then is a hang.
/// Returns the exit code and standard error.
fn bounded(args: &[&str], limit: Duration) -> (i32, String) {
    // A directory per call: tests run in parallel.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let err_path = scratch(&format!("bounded-{n}")).join("stderr");
    let mut child = truepos()
        .args(args)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "`truepos {}` still running after {limit:?}: a hang",
                args.join(" ")
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stderr = std::fs::read_to_string(&err_path).unwrap();
    (status.code().unwrap_or(-1), stderr)
}

/// Issue 11: `--period-ms 1e300` panicked in `Duration::from_secs_f64` (exit 101).
#[test]
fn a_huge_period_is_refused_naming_the_option_and_range() {
    let (code, err) = bounded(
        &["run", "--fast", "--period-ms", "1e300"],
        Duration::from_secs(10),
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--period-ms") && err.contains("[0.1, 10000]"),
        "{err}"
    );
}

/// Issue 11: `--period-ms 1e-7 --duration-s 1` spun forever (the period rounded to 0 ns).
#[test]
fn a_tiny_period_is_refused_not_spun_on() {
    let args = ["run", "--fast", "--period-ms", "1e-7", "--duration-s", "1"];
    let (code, err) = bounded(&args, Duration::from_secs(10));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--period-ms"), "{err}");
}

/// Issue 11: `--duration-s nan` never ended (no time is > NaN).
#[test]
fn a_nan_duration_is_refused() {
    let (code, err) = bounded(
        &["run", "--fast", "--duration-s", "nan"],
        Duration::from_secs(10),
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--duration-s") && err.contains("31536000"),
        "{err}"
    );
}

/// Issue 11: a replay at 1e-300 × real time never ended.
#[test]
fn a_vanishing_replay_speed_is_refused() {
    let spec = "replay:examples/vmc3/run.csv@1e-300";
    let (code, err) = bounded(
        &["run", "--fast", "--source", spec],
        Duration::from_secs(10),
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains(spec) && err.contains("[0.001, 1000000]"),
        "{err}"
    );
}

/// Issue 11: a twin scenario of 10⁹ hours grew `run --source twin:` to 1.7 GB before its first
/// cycle (and `sim` to 5.6 GB); now it is refused at the phase's line, at once.
#[test]
fn a_billion_hour_twin_scenario_is_refused_before_any_cycle() {
    let dir = scratch("billion");
    let sc = dir.join("billion.toml");
    std::fs::write(
        &sc,
        "[scenario]\nname = \"billion\"\n\n[[phase]]\nname = \"p\"\nduration_min = 6e10\n",
    )
    .unwrap();
    let source = format!("twin:{}", sc.display());
    let (code, err) = bounded(
        &["run", "--fast", "--source", &source],
        Duration::from_secs(10),
    );
    assert_eq!(code, 1, "{err}");
    let place = format!("{}:6:", sc.display());
    assert!(
        err.contains(&place) && err.contains("phase[0].duration_min"),
        "{err}"
    );
    let sc = sc.to_str().unwrap();
    let (code, err) = bounded(
        &["sim", "--scenario", sc, "-o", "-"],
        Duration::from_secs(10),
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("30 days"), "{err}");
}

/// Issue 11: a run whose first time is NaN was accepted (`eval` wrote NaN into `time_s`, `run`
/// never ended); now both refuse it at file:line:column.
#[test]
fn a_run_with_a_nan_first_time_is_refused_by_eval_and_run() {
    let dir = scratch("nan-time");
    let run = dir.join("run.csv");
    let text = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let rest = lines[1].split_once(',').unwrap().1.to_string();
    lines[1] = format!("NaN,{rest}");
    std::fs::write(&run, lines.join("\n") + "\n").unwrap();
    let place = format!("{}:2:1: `time_s`: expected a finite time", run.display());
    let run_arg = run.to_str().unwrap();
    let (code, err) = bounded(&["eval", "--run", run_arg], Duration::from_secs(20));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(&place), "{err}");
    let source = format!("replay:{run_arg}");
    let (code, err) = bounded(
        &["run", "--fast", "--source", &source],
        Duration::from_secs(20),
    );
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(&place), "{err}");
}
