//! Defaults that fit the machine (issue 28, finding 3): the demo's test day replayed through
//! `truepos run` gives the figures `truepos demo` prints, and a model that would run into the
//! envelope is named at start with the key to change.

use std::path::Path;

mod support;
use support::{command as truepos, repo, scratch};

/// A CSV file as a header and rows of cells.
fn table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

/// RMS per direction of the residual at the tool's path: the twin's error (`d<axis>_um` of the
/// day) plus the offset the service sent (`<AXIS>_offset_um`, the compensation = −error) in the
/// first cycle that saw the day's row.
fn path_rmse(day: &Path, offsets: &Path) -> [f64; 3] {
    let (dh, drows) = table(day);
    let (oh, orows) = table(offsets);
    let dcol = |n: &str| dh.iter().position(|h| h == n).unwrap();
    let ocol = |n: &str| oh.iter().position(|h| h == n).unwrap();
    let times: Vec<f64> = orows.iter().map(|r| r[0].parse().unwrap()).collect();
    let mut se = [0.0; 3];
    let mut n = 0;
    for r in &drows {
        let t: f64 = r[dcol("time_s")].parse().unwrap();
        let j = times.partition_point(|&o| o < t - 1e-9);
        let Some(o) = orows.get(j) else { continue };
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let error: f64 = r[dcol(&format!("d{axis}_um"))].parse().unwrap();
            let offset: f64 = o[ocol(&format!("{}_offset_um", axis.to_uppercase()))]
                .parse()
                .unwrap();
            se[a] += (error + offset).powi(2);
        }
        n += 1;
    }
    assert!(n > 1000, "{n} rows of the day joined");
    se.map(|s| (s / n as f64).sqrt())
}

#[test]
fn the_demo_day_replayed_through_run_reaches_the_demo_figures() {
    let dir = scratch("demo-replay");
    // The demo: its models and its printed figures (the test day is the twin's
    // `mixed-shift-b` with seed 2).
    let out = truepos()
        .args(["demo", "--json", "--out"])
        .arg(dir.join("demo"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    // The twin's machine file states Z's envelope from what the twin drifts: nothing to say.
    assert!(!err.contains("max_offset_um"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let printed: Vec<f64> = v["position_dependent"]["figures"]["path_rmse_um"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let day = dir.join("B.csv");
    let (ok, _, err) = support::run(&[
        "sim",
        "--scenario",
        "mixed-shift-b",
        "--seed",
        "2",
        "-o",
        day.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let model = dir.join("demo/position-dependent.model.toml");
    let replay = |machine: &Path, offsets: &Path| {
        let out = truepos()
            .args(["run", "--machine"])
            .arg(machine)
            .arg("--models")
            .arg(&model)
            .arg("--source")
            .arg(format!("replay:{}", day.display()))
            .args([
                "--fast",
                "--period-ms",
                "1000",
                "--sink-every-s",
                "0",
                "--json",
            ])
            .arg("--sink")
            .arg(format!("csv:{}", offsets.display()))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let twin_machine = repo("examples/twin/machine.toml");
    let offsets = dir.join("offsets.csv");
    let err = replay(&twin_machine, &offsets);
    assert!(!err.contains("warning"), "{err}");
    let got = path_rmse(&day, &offsets);
    for a in 0..3 {
        assert!(
            (got[a] - printed[a]).abs() <= 0.5,
            "direction {a}: run {got:?} µm, demo {printed:?} µm"
        );
    }
    // The same machine with the default envelope on Z (100 µm): `run` says at start that the
    // model goes beyond it, on which axis, and which key to raise; the figures then miss.
    let text = std::fs::read_to_string(&twin_machine).unwrap();
    let default_z = text.replace("max_offset_um = 150.0\n", "");
    assert_ne!(
        default_z, text,
        "the twin's machine file states Z's envelope"
    );
    let machine_100 = dir.join("machine-100.toml");
    std::fs::write(&machine_100, default_z).unwrap();
    let clamped = dir.join("clamped.csv");
    let err = replay(&machine_100, &clamped);
    assert!(
        err.contains("warning")
            && err.contains("axis Z")
            && err.contains("100 µm")
            && err.contains("max_offset_um")
            && err.contains("machine-100.toml"),
        "{err}"
    );
    assert!(!err.contains("axis X") && !err.contains("axis Y"), "{err}");
    let held = path_rmse(&day, &clamped);
    assert!(held[2] > printed[2] + 0.5, "{held:?} vs {printed:?}");
    std::fs::remove_dir_all(&dir).ok();
}
