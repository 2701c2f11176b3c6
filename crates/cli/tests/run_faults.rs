//! `truepos run` and `truepos status` under faults of the log, the sinks and the sensors
//! (issue 11): each failure is an event and a state, and the run ends non-zero naming it.

use truepos_runtime::log;

mod support;
use support::{command as truepos, scratch};

/// Finding: `truepos run --sink csv:/dev/full` exited 0 with no message, and wrote 143 000
/// `sink-failed` events into the log. Now: one event with the reason, the state shows it, and
/// the run fails at the end naming the sink and the reason.
#[test]
fn a_sink_on_a_full_device_is_one_event_and_fails_the_run_naming_it() {
    let dir = scratch("full-sink");
    let db = dir.join("log.sqlite");
    let out = truepos()
        .args(["run", "--fast", "--period-ms", "10", "--duration-s", "600"])
        .args(["--sink", "csv:/dev/full", "--log"])
        .arg(&db)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("error: sink `csv /dev/full` failed at 0.0 s: No space left on device"),
        "{stderr}"
    );
    let events = log::read_events(&db).unwrap();
    let failed: Vec<_> = events.iter().filter(|e| e.kind == "sink-failed").collect();
    assert_eq!(failed.len(), 1, "{events:?}");
    assert_eq!(failed[0].subject, "csv /dev/full");
    assert!(failed[0].detail.contains("No space left"), "{events:?}");
    // Compensation went on: a monitoring file is not the path to the axes.
    let (names, rows) = log::read_cycles(&db, Some(1)).unwrap();
    let state = names.iter().position(|n| n == "state").unwrap();
    assert_eq!(rows[0][state], "active");
    let status = truepos()
        .args(["status", "--log"])
        .arg(&db)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&status.stdout);
    assert!(
        text.contains("sink `csv /dev/full`: FAILING since 0.0 s: No space left"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Finding: a second service pointed at the same log replaced its `meta` with another machine
/// and failed only at exit. Now it is refused at start, naming the file and both machines.
#[test]
fn a_run_on_the_log_of_another_machine_is_refused_at_start() {
    let dir = scratch("owner");
    let db = dir.join("log.sqlite");
    let first = truepos()
        .args([
            "run",
            "--fast",
            "--period-ms",
            "1000",
            "--duration-s",
            "10",
            "--log",
        ])
        .arg(&db)
        .output()
        .unwrap();
    assert!(first.status.success());
    let started = std::time::Instant::now();
    let second = truepos()
        .args(["run", "--fast", "--period-ms", "1000", "--log"])
        .arg(&db)
        .args(["--machine", "examples/cross-slide/machine.toml"])
        .args(["--models", "examples/cross-slide/model.toml"])
        .args(["--source", "replay:examples/cross-slide/run.csv"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "{stderr}");
    assert!(stderr.contains(&db.display().to_string()), "{stderr}");
    assert!(
        stderr.contains("`vmc-3axis`") && stderr.contains("`cross-slide-on-bed`"),
        "{stderr}"
    );
    // Refused before running: no cycle of the cross slide reached the log.
    assert!(started.elapsed().as_secs() < 20);
    let meta = log::read_meta(&db).unwrap().unwrap();
    assert_eq!(meta["machine"], "vmc-3axis");
    std::fs::remove_dir_all(&dir).ok();
}

/// Finding: `truepos status` printed "sensors: all good" although no value ever arrived (an
/// adapter down from the start raises no sensor event: every channel starts "never updated").
#[test]
fn status_does_not_call_sensors_good_that_never_delivered() {
    let dir = scratch("never");
    let db = dir.join("log.sqlite");
    let cfg = dir.join("shdr.toml");
    // Port 1 on the loopback: nothing listens, the connection is refused at once.
    std::fs::write(
        &cfg,
        "address = \"127.0.0.1:1\"\n[[channel]]\ndata_item = \"Tamb\"\ntemperature = \"ambient\"\n",
    )
    .unwrap();
    let out = truepos()
        .args(["run", "--period-ms", "10", "--duration-s", "1.5", "--log"])
        .arg(&db)
        .arg("--source")
        .arg(format!("shdr:{}", cfg.display()))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let status = truepos()
        .args(["status", "--log"])
        .arg(&db)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&status.stdout);
    assert!(!text.contains("all good"), "{text}");
    assert!(
        text.contains("sensor ambient: no value in the last logged cycle"),
        "{text}"
    );
    // The reason the source delivers nothing reaches the status.
    assert!(
        text.contains("LOST since") && text.contains("refused"),
        "{text}"
    );
    let json = truepos()
        .args(["status", "--json", "--log"])
        .arg(&db)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(v["bad_sensors"].as_array().unwrap().len(), 16, "{v}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A source configuration's mistake names the file, line, column and key, as every other input
/// names its mistakes — also one found after parsing (a time of 0, a channel the machine lacks).
#[test]
fn a_source_configurations_mistake_names_its_file_line_column_and_key() {
    let dir = scratch("source-config-file");
    let cfg = dir.join("modules.toml");
    // The configuration's text, then what `run` says of it after the file's name.
    let refused = |text: &str| {
        std::fs::write(&cfg, text).unwrap();
        let out = truepos()
            .args(["run", "--duration-s", "1", "--source"])
            .arg(format!("modbus:{}", cfg.display()))
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        let at = err
            .find(&cfg.display().to_string())
            .unwrap_or_else(|| panic!("{err}"));
        err[at + cfg.display().to_string().len()..].to_string()
    };
    let channel =
        "[[channel]]\ntemperature = \"ambient\"\nregister = 1\nencoding = \"int16-x0.1\"\n";
    let err = refused(&format!(
        "address = \"127.0.0.1:5020\"\npoll_ms = 0\n\n{channel}"
    ));
    assert!(
        err.starts_with(":2:1: `modbus.poll_ms`: expected a time of at least 1 ms"),
        "{err}"
    );
    let err = refused(&format!(
        "address = \"127.0.0.1:5020\"\n\n{channel}\n[[channel]]\nregister = 2\nencoding = \"int16-x0.1\"\ntemperature = \"no_such_sensor\"\n"
    ));
    assert!(
        err.starts_with(":11:1: `modbus.channel[2].temperature`:"),
        "{err}"
    );
}
