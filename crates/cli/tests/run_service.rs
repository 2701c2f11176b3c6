//! `truepos run` as a process: a replay through the service into the log, the inspection
//! commands, and the log surviving SIGKILL at any moment.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use truepos_runtime::log;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("truepos-run-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn truepos() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_truepos"));
    c.current_dir(repo(""));
    c
}

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
        header.ends_with("X_offset_um,Y_offset_um,Z_offset_um"),
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
