//! `truepos report` writes an HTML report whose figures of merit are computed by hand here.

use std::process::Command;

mod support;
use support::repo;

/// The cross-slide example run with measured errors added: measured X = predicted X + 1 µm on
/// every row (predicted 4.5, 0, 9, 12, 8 → measured 5.5, 1, 10, 13, 9). Held out from
/// t = 120 s (rows 3–5): residual 1, 1, 1 → RMSE 1, max 1, peak-to-peak 0; uncompensated =
/// measured as taken for a position-dependent model (the residual's reference point) = 10, 13,
/// 9 → RMS √((100 + 169 + 81)/3) = √116.667 = 10.8012.
#[test]
fn report_metrics_and_files() {
    let dir = std::env::temp_dir().join(format!("truepos-report-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let original = std::fs::read_to_string(repo("examples/cross-slide/run.csv")).unwrap();
    let measured = [5.5, 1.0, 10.0, 13.0, 9.0];
    let mut text = String::new();
    for (i, line) in original.lines().enumerate() {
        if i == 0 {
            text.push_str(&format!("{line},x_measured_um\n"));
        } else {
            text.push_str(&format!("{line},{}\n", measured[i - 1]));
        }
    }
    let run = dir.join("run.csv");
    std::fs::write(&run, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_truepos"))
        .current_dir(repo(""))
        .args([
            "report",
            "--machine",
            "examples/cross-slide/machine.toml",
            "--model",
            "examples/cross-slide/model.toml",
            "--measured",
            "X=x_measured_um",
            "--test-from-s",
            "120",
            "--json",
            "--run",
        ])
        .arg(&run)
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
    let m = &v["channels"][0]["metrics"];
    assert!((m["rmse_um"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{v}");
    assert!((m["max_abs_um"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    assert!(m["peak_to_peak_um"].as_f64().unwrap().abs() < 1e-9);
    assert!((m["uncompensated_rmse_um"].as_f64().unwrap() - 10.801_234).abs() < 1e-5);
    let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
    assert!(html.contains("<svg"));
    assert!(html.contains("Validation protocol"));
    // For the shop floor: the conclusion first (1 − 1/10.80 = 91 %), and the model file named
    // with its SHA-256 and the truepos that made the report.
    assert!(
        html.contains("the model removes 91 % of the error"),
        "conclusion"
    );
    let bytes = std::fs::read(repo("examples/cross-slide/model.toml")).unwrap();
    let sha = truepos_io::model_file::position::sha256_hex(&bytes);
    assert!(html.contains(&format!("sha256 {sha}")), "model checksum");
    assert!(html.contains("by truepos "), "version");
    assert!(
        html.contains("dT_bed · bed(Z) · KFA(Z)"),
        "coefficient names"
    );
    // Coefficients grouped by the sensor they read, what the symbol stands for said once, each
    // value with its unit (the example model's K of the bed term is 4 µm/K).
    assert!(
        html.contains("<h3>bed_top (temperature)</h3><p>dT_bed = bed_top − bed_bottom</p>"),
        "coefficients grouped by input"
    );
    assert!(html.contains("(position-dependent)</td><td>4.000 µm/K</td>"));
    assert!(html.contains("<h3>constants</h3>"));
    for f in [
        "X__x_measured_um__over_time.svg",
        "residual_histogram.svg",
        "temperatures.svg",
        "correlation.svg",
    ] {
        assert!(dir.join("report").join(f).exists(), "{f}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn report_names_a_missing_measured_column() {
    let out = Command::new(env!("CARGO_BIN_EXE_truepos"))
        .current_dir(repo(""))
        .args([
            "report",
            "--machine",
            "examples/cross-slide/machine.toml",
            "--model",
            "examples/cross-slide/model.toml",
            "--run",
            "examples/cross-slide/run.csv",
            "--measured",
            "X=dx_um",
            "--out",
        ])
        .arg(std::env::temp_dir().join("truepos-report-missing"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("examples/cross-slide/run.csv:1:1: `dx_um`: missing column"),
        "{err}"
    );
}

/// One reference point (issue 28): a fitted dynamic model learnt the drift from each run's
/// first sample, so `report` takes its measured errors the same way — a measured column that
/// sits at 100 µm all day is no drift at all — while `--absolute` takes them as measured.
#[test]
fn a_dynamic_model_is_reported_on_the_drift_it_was_fitted_on() {
    let dir = std::env::temp_dir().join(format!("truepos-report-ref-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let original = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = original.lines();
    let mut text = format!("{},z_meas_um\n", lines.next().unwrap());
    for l in lines {
        text.push_str(&format!("{l},100\n"));
    }
    let run = dir.join("run.csv");
    std::fs::write(&run, text).unwrap();
    let rmse = |absolute: bool| -> f64 {
        let mut c = Command::new(env!("CARGO_BIN_EXE_truepos"));
        c.current_dir(repo(""))
            .args(["report", "--machine", "examples/vmc3/machine.toml"])
            .args([
                "--model",
                "tests/linuxcnc/model_d.json",
                "--measured",
                "Z=z_meas_um",
            ])
            .arg("--run")
            .arg(&run)
            .arg("--out")
            .arg(dir.join(format!("r{absolute}")))
            .arg("--json");
        if absolute {
            c.arg("--absolute");
        }
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["channels"][0]["metrics"]["rmse_um"].as_f64().unwrap()
    };
    let (relative, absolute) = (rmse(false), rmse(true));
    assert!(absolute - relative > 10.0, "{relative} vs {absolute}");
    let html = std::fs::read_to_string(dir.join("rfalse/report.html")).unwrap();
    assert!(html.contains("as the fit took it"), "protocol");
    // A fitted dynamic model's terms in words, under the sensor they read, with units.
    assert!(html.contains("<h3>spindle_front_bearing (temperature)</h3>"));
    assert!(
        html.contains("<td class=\"l\">rise, lagged τ = 1 h</td>"),
        "lag in words"
    );
    assert!(!html.contains("lp3600("), "the model file's symbol");
    std::fs::remove_dir_all(&dir).ok();
}

/// The drift plots read the run's clock when its time column holds date-times, and the figures
/// of merit are those of the same run timed in seconds: the axis changes, not the numbers.
#[test]
fn drift_plots_read_the_runs_clock() {
    let dir = std::env::temp_dir().join(format!("truepos-report-clock-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let original = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = original.lines();
    let header = lines.next().unwrap();
    let (mut seconds, mut clock) = (
        format!("{header},z_meas_um\n"),
        format!(
            "{},z_meas_um\n",
            header.replacen("time_s", "Zeitstempel", 1)
        ),
    );
    for (i, l) in lines.enumerate() {
        let (t, rest) = l.split_once(',').unwrap();
        let t: f64 = t.parse().unwrap();
        // The run starts on 4 March 2024 at 06:00; 30 µm of drift settling over the day.
        let s = 6.0 * 3600.0 + t;
        let (h, m, sec) = ((s / 3600.0) as u32, (s % 3600.0 / 60.0) as u32, s % 60.0);
        let z = 30.0 * (1.0 - (-(i as f64) / 60.0).exp());
        seconds.push_str(&format!("{l},{z}\n"));
        clock.push_str(&format!("04.03.2024 {h:02}:{m:02}:{sec:02},{rest},{z}\n"));
    }
    let report = |name: &str, text: &str, time: &str| -> serde_json::Value {
        let run = dir.join(format!("{name}.csv"));
        std::fs::write(&run, text).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_truepos"))
            .current_dir(repo(""))
            .args(["report", "--machine", "examples/vmc3/machine.toml"])
            .args([
                "--model",
                "tests/linuxcnc/model_d.json",
                "--measured",
                "Z=z_meas_um",
            ])
            .args(["--time", time, "--json", "--run"])
            .arg(&run)
            .arg("--out")
            .arg(dir.join(name))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let (by_seconds, by_clock) = (
        report("seconds", &seconds, "time_s"),
        report("clock", &clock, "Zeitstempel"),
    );
    assert_eq!(by_seconds["channels"], by_clock["channels"]);
    let svg = std::fs::read_to_string(dir.join("clock/Z__z_meas_um__over_time.svg")).unwrap();
    assert!(
        svg.contains("clock time, UTC (from 2024-03-04 06:00)"),
        "axis title"
    );
    assert!(svg.contains("\n08:00\n"), "a tick at 08:00");
    let plain = std::fs::read_to_string(dir.join("seconds/Z__z_meas_um__over_time.svg")).unwrap();
    assert!(plain.contains("time / h") && !plain.contains("clock time"));
    let html = std::fs::read_to_string(dir.join("clock/report.html")).unwrap();
    assert!(html.contains("Z (z_meas_um): drift over clock time — measured, predicted, residual"));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--all-runs`: two days of one file, timed by the clock, reported together. The drift plots
/// read the clock across both days (the night between them is a gap), each day's start is a
/// labelled line, and the pooled figures are the two days' own: for a static model the pooled
/// mean square is the days' mean squares weighted by their rows.
#[test]
fn all_runs_share_the_clock_and_their_starts_are_marked() {
    let dir = std::env::temp_dir().join(format!("truepos-report-days-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let original = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = original.lines();
    let header = lines.next().unwrap().replacen("time_s", "day,time", 1);
    let rows: Vec<&str> = lines.collect();
    let mut text = format!("{header},z_meas_um\n");
    for (day, date, wobble) in [
        ("monday", "2024-03-04", 1.0),
        ("tuesday", "2024-03-05", 3.0),
    ] {
        for (i, l) in rows.iter().enumerate() {
            let (t, rest) = l.split_once(',').unwrap();
            let s = 6.0 * 3600.0 + t.parse::<f64>().unwrap();
            let (h, m, sec) = ((s / 3600.0) as u32, (s % 3600.0 / 60.0) as u32, s % 60.0);
            let z = 20.0 + wobble * ((i % 7) as f64 - 3.0);
            text.push_str(&format!("{day},{date}T{h:02}:{m:02}:{sec:02},{rest},{z}\n"));
        }
    }
    let run = dir.join("days.csv");
    std::fs::write(&run, text).unwrap();
    let report = |extra: &[&str], out: &str| -> serde_json::Value {
        let out = Command::new(env!("CARGO_BIN_EXE_truepos"))
            .current_dir(repo(""))
            .args(["report", "--machine", "examples/vmc3/machine.toml"])
            .args([
                "--model",
                "examples/vmc3/model.toml",
                "--measured",
                "Z=z_meas_um",
            ])
            .args(["--run-column", "day", "--time", "time", "--json", "--run"])
            .arg(&run)
            .args(extra)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let rmse = |v: &serde_json::Value| v["channels"][0]["metrics"]["rmse_um"].as_f64().unwrap();
    let both = rmse(&report(&["--all-runs"], "both"));
    let (mon, tue) = (
        rmse(&report(&["--select-run", "monday"], "mon")),
        rmse(&report(&["--select-run", "tuesday"], "tue")),
    );
    // Both days have the same number of rows.
    let pooled = ((mon * mon + tue * tue) / 2.0).sqrt();
    assert!((both - pooled).abs() < 1e-9, "{both} vs {pooled}");
    let svg = std::fs::read_to_string(dir.join("both/Z__z_meas_um__over_time.svg")).unwrap();
    assert!(
        svg.contains("clock time, UTC (from 2024-03-04 06:00)"),
        "axis title"
    );
    for label in ["\nmonday\n", "\ntuesday\n", "start of a run"] {
        assert!(svg.contains(label), "{label}");
    }
    // More than a day on the axis: the ticks carry the day of the month.
    assert!(svg.contains("\n05. "), "day in the ticks");
    let html = std::fs::read_to_string(dir.join("both/report.html")).unwrap();
    assert!(html.contains("2 runs (monday, tuesday)"), "protocol");
    std::fs::remove_dir_all(&dir).ok();
}
