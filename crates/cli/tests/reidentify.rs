//! `truepos reidentify` end to end on the twin: a model fitted on day A of the reference twin,
//! a drifted machine on day B (its spindle grows 40 % more per kelvin) whose first hours of
//! probe measurements go through the command as a run CSV; the new model loads through the one
//! door and its error on the later probes of the day is lower. Then the refusals: a model that
//! is good enough is kept (exit 3, nothing written), and bad probe files are located.

mod support;

use std::path::{Path, PathBuf};
use std::process::Output;

use sha2::{Digest, Sha256};
use support::{command, repo, scratch};
use truepos_fit::position_model::{fit_structure, structure, Family, Observation};
use truepos_io::model_file::position::ModelFile;
use truepos_model::{CycleInput, Machine, Model};
use truepos_sim::{Scenario, SimRun, Twin};

const MACHINE: &str = "examples/twin/machine.toml";

fn machine() -> Machine {
    truepos_io::machine_file::load(&repo(MACHINE))
        .unwrap()
        .machine
}

/// Temperatures of every row in the machine's channel order, lagged channels computed.
fn temperatures(run: &SimRun, machine: &Machine) -> Vec<Vec<f64>> {
    let time: Vec<f64> = run.rows.iter().map(|r| r.time_s).collect();
    let operating = vec![vec![f64::NAN; machine.operating.len()]; run.rows.len()];
    truepos_io::cycles::machine_temperatures(
        machine,
        &run.sensor_ids,
        &time,
        run.rows.iter().map(|r| r.temperatures_c.as_slice()),
        &operating,
    )
}

/// Day A's position-dependent model (all axes) fitted on the tool's path.
fn day_a_model(machine: &Machine) -> (Model, SimRun) {
    let day_a = Twin::reference()
        .run(&Scenario::builtin("mixed-shift").unwrap(), 1)
        .unwrap();
    let temps = temperatures(&day_a, machine);
    let op = vec![f64::NAN; machine.operating.len()];
    let all: Vec<usize> = (0..machine.differences.len()).collect();
    let s = structure("drift", machine, Family::AllAxes, &all, &[0, 1, 2], true).unwrap();
    let mut obs = Vec::new();
    for (i, row) in day_a.rows.iter().enumerate() {
        for a in 0..3 {
            obs.push(Observation {
                input: CycleInput {
                    temperatures_c: &temps[i],
                    positions: &row.position_mm,
                    operating: &op,
                },
                axis: a,
                error_um: row.error_um[a],
            });
        }
    }
    (fit_structure(&s, machine, obs).unwrap().model, day_a)
}

fn write_model(model: &Model, machine: &Machine, path: &Path) {
    std::fs::write(path, ModelFile::from_model(model, machine).to_toml()).unwrap();
}

fn write_run(run: &SimRun, rows: std::ops::Range<usize>, path: &Path) {
    let mut part = run.clone();
    part.rows = run.rows[rows].to_vec();
    part.states.clear();
    part.write_csv(std::fs::File::create(path).unwrap(), false)
        .unwrap();
}

fn reidentify(model: &Path, run: &Path, out: &Path, json: bool) -> Output {
    let mut c = command();
    c.args(["reidentify", "--machine", MACHINE, "--model"])
        .arg(model)
        .arg("--run")
        .arg(run)
        .arg("--out")
        .arg(out);
    if json {
        c.arg("--json");
    }

    c.output().unwrap()
}

/// RMS of measured − predicted over the probe measurements of rows `from..`.
fn probe_rmse(
    model: &truepos_model::CompensationModel,
    run: &SimRun,
    temps: &[Vec<f64>],
    from: usize,
    axes: std::ops::Range<usize>,
) -> f64 {
    let op = vec![f64::NAN; 5];
    let (mut se, mut n) = (0.0, 0);
    for (i, row) in run.rows.iter().enumerate().skip(from) {
        let Some(p) = &row.probe else { continue };
        let input = CycleInput {
            temperatures_c: &temps[i],
            positions: &p.position_mm,
            operating: &op,
        };
        let predicted = model.as_static().unwrap().evaluate(&input).unwrap();
        for a in axes.clone() {
            se += (p.measured_um[a] - predicted.error_um()[a]).powi(2);
            n += 1;
        }
    }
    assert!(n > 50, "too few later probes: {n}");
    (se / n as f64).sqrt()
}

#[test]
fn probes_of_a_drifted_day_give_a_model_that_is_better_on_later_probes() {
    let machine = machine();
    let dir = scratch("reidentify");
    let (original, day_a) = day_a_model(&machine);
    let old = dir.join("old.toml");
    write_model(&original, &machine, &old);

    let mut drifted = Twin::reference();
    drifted.spindle_growth_length_mm *= 1.4;
    let day_b = drifted
        .run(&Scenario::builtin("mixed-shift-b").unwrap(), 2)
        .unwrap();
    let split = day_b.rows.len() / 2;
    let probes = dir.join("probes.csv");
    write_run(&day_b, 0..split, &probes);
    let new = dir.join("new.toml");

    // Screen and JSON agree; both runs write the same file.
    let screen = reidentify(&old, &probes, &new, false);
    let text = String::from_utf8_lossy(&screen.stdout).to_string();
    assert!(
        screen.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&screen.stderr)
    );
    let out = reidentify(&old, &probes, &new, true);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    println!("{text}{v:#}");
    assert_eq!(v["status"], "switched");
    let old_w = v["window"]["old_rmse_um"].as_f64().unwrap();
    let new_w = v["window"]["new_rmse_um"].as_f64().unwrap();
    assert!(new_w < old_w, "{v}");
    assert!(
        text.contains(&format!(
            "old model {old_w:.2} µm RMS, new model {new_w:.2} µm RMS"
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("{} probe events", v["data"]["events"])),
        "{text}"
    );

    // Provenance names the parent by file and hash, and the data window.
    let written: toml::Table = std::fs::read_to_string(&new).unwrap().parse().unwrap();
    let p = &written["provenance"];
    let sha: String = Sha256::digest(std::fs::read(&old).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(p["parent"]["sha256"].as_str(), Some(sha.as_str()));
    assert_eq!(p["parent"]["file"].as_str(), Some(old.to_str().unwrap()));
    assert_eq!(p["generation"].as_integer(), Some(2));
    assert_eq!(
        p["data"]["events"].as_integer(),
        v["data"]["events"].as_i64()
    );
    assert_eq!(
        p["data"]["first_time_s"].as_float(),
        v["data"]["first_time_s"].as_f64()
    );
    assert_eq!(
        p["data"]["last_time_s"].as_float(),
        v["data"]["last_time_s"].as_f64()
    );
    assert!(v["data"]["last_time_s"].as_f64().unwrap() <= day_b.rows[split - 1].time_s);

    // The new model loads through the one door and is better on the later half's probes.
    let loaded = truepos_io::model_file::load(&new, &machine).unwrap().model;
    let before = truepos_io::model_file::load(&old, &machine).unwrap().model;
    let temps = temperatures(&day_b, &machine);
    for a in 0..3 {
        println!(
            "axis {a}: original {:.2}, re-identified {:.2}",
            probe_rmse(&before, &day_b, &temps, split, a..a + 1),
            probe_rmse(&loaded, &day_b, &temps, split, a..a + 1)
        );
    }
    // The drift is the spindle's growth, along Z: there the error falls most.
    let dz = (
        probe_rmse(&before, &day_b, &temps, split, 2..3),
        probe_rmse(&loaded, &day_b, &temps, split, 2..3),
    );
    assert!(
        dz.1 < 0.5 * dz.0,
        "dz: re-identified {:.2} µm vs original {:.2} µm",
        dz.1,
        dz.0
    );
    let (e_old, e_new) = (
        probe_rmse(&before, &day_b, &temps, split, 0..3),
        probe_rmse(&loaded, &day_b, &temps, split, 0..3),
    );
    println!("later probes: original {e_old:.2} µm RMS, re-identified {e_new:.2} µm RMS");
    assert!(
        e_new < 0.7 * e_old,
        "re-identified {e_new:.2} µm vs original {e_old:.2} µm"
    );

    // The same probes through the service: replayed with the run, logged, re-identified from
    // the log. Every event reaches the log, and the model from it is better on later probes.
    let db = dir.join("service.sqlite");
    let replay = format!("replay:{}", probes.display());
    let probe_source = format!("probes:{}", probes.display());
    let served = command()
        .args(["run", "--fast", "--machine", MACHINE, "--models"])
        .arg(&old)
        .args([
            "--source",
            &replay,
            "--source",
            &probe_source,
            "--period-ms",
            "1000",
            "--log",
        ])
        .arg(&db)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        served.status.success(),
        "{}",
        String::from_utf8_lossy(&served.stderr)
    );
    let logged = truepos_runtime::log::read_probes(&db).unwrap();
    assert_eq!(
        logged.rows.len() as u64,
        v["data"]["events"].as_u64().unwrap()
    );
    assert!(
        logged.rows.iter().all(|r| r.accepted),
        "{:?}",
        logged.rows.iter().find(|r| !r.accepted)
    );
    let from_log = dir.join("from-log.toml");
    let out = command()
        .args(["reidentify", "--machine", MACHINE, "--model"])
        .arg(&old)
        .arg("--log")
        .arg(&db)
        .arg("--out")
        .arg(&from_log)
        .arg("--json")
        .output()
        .unwrap();
    let lv: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    println!("from the log: {lv}");
    assert_eq!(lv["status"], "switched", "{lv}");
    // A machine description the model and the log were not made for is refused.
    let other = command()
        .args([
            "reidentify",
            "--machine",
            "examples/vmc3/machine.toml",
            "--model",
        ])
        .arg(&old)
        .arg("--log")
        .arg(&db)
        .arg("--out")
        .arg(dir.join("other.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&other.stderr);
    assert_eq!(other.status.code(), Some(1), "{err}");
    let via_log = truepos_io::model_file::load(&from_log, &machine)
        .unwrap()
        .model;
    let e_log = probe_rmse(&via_log, &day_b, &temps, split, 0..3);
    println!("later probes: re-identified from the service's log {e_log:.2} µm RMS");
    assert!(
        e_log < 0.7 * e_old,
        "from the log {e_log:.2} µm vs original {e_old:.2} µm"
    );

    // A second re-identification starts from the first: generation 3, its parent the new file.
    let third = dir.join("third.toml");
    let later = dir.join("later.csv");
    write_run(&day_b, split..day_b.rows.len(), &later);
    let again = reidentify(&new, &later, &third, true);
    let v: serde_json::Value = serde_json::from_slice(&again.stdout).unwrap();
    if v["status"] == "switched" {
        let t: toml::Table = std::fs::read_to_string(&third).unwrap().parse().unwrap();
        assert_eq!(t["provenance"]["generation"].as_integer(), Some(3));
    } else {
        assert_eq!(again.status.code(), Some(3), "{v}");
    }

    // On the machine the model was fitted on, its error stays below the threshold: kept.
    let day_a_probes = dir.join("day-a.csv");
    write_run(&day_a, 0..day_a.rows.len(), &day_a_probes);
    let kept_out = dir.join("kept.toml");
    let kept = reidentify(&old, &day_a_probes, &kept_out, true);
    let v: serde_json::Value = serde_json::from_slice(&kept.stdout).unwrap();
    assert_eq!(kept.status.code(), Some(3), "{v}");
    assert_eq!(v["status"], "kept");
    assert!(v["reason"].as_str().unwrap().contains("threshold"), "{v}");
    assert!(!kept_out.exists(), "a kept model writes nothing");
}

/// Bad probe files: each error names file, line, column and the column.
#[test]
fn bad_probe_files_are_located() {
    let machine = machine();
    let dir = scratch("reidentify-bad");
    let m = Model::new("zero", &machine, vec![]).unwrap();
    let old = dir.join("old.toml");
    write_model(&m, &machine, &old);
    let day = Twin::reference()
        .run(&Scenario::builtin("spindle-warmup").unwrap(), 1)
        .unwrap();
    let good = dir.join("good.csv");
    write_run(&day, 0..day.rows.len(), &good);
    let text = std::fs::read_to_string(&good).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let dz = header.iter().position(|h| *h == "probe_dz_um").unwrap();
    let probe_line = lines
        .iter()
        .position(|l| !l.split(',').nth(dz).unwrap_or("").is_empty() && !l.starts_with("time_s"))
        .expect("the warm-up probes");
    let with = |value: &str| -> PathBuf {
        let mut ls: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        let mut cells: Vec<String> = ls[probe_line].split(',').map(String::from).collect();
        cells[dz] = value.into();
        ls[probe_line] = cells.join(",");
        let p = dir.join(format!("bad-{}.csv", value.replace(['.', '-'], "_")));
        std::fs::write(&p, ls.join("\n") + "\n").unwrap();
        p
    };
    for (value, expect) in [
        ("abc", "got `abc`"),
        ("NaN", "got NaN"),
        ("5e4", "within ±1000"),
    ] {
        let bad = with(value);
        let out = reidentify(&old, &bad, &dir.join("x.toml"), false);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{value}: {err}");
        // Columns of a CSV table count fields.
        let place = format!(
            "{}:{}:{}: `probe_dz_um`",
            bad.display(),
            probe_line + 1,
            dz + 1
        );
        assert!(
            err.contains(&place) && err.contains(expect),
            "{value}: {err} (expected {place})"
        );
    }
    // A file without probe columns.
    let plain = dir.join("plain.csv");
    let cut: Vec<String> = lines
        .iter()
        .map(|l| l.split(',').take(dz - 5).collect::<Vec<_>>().join(","))
        .collect();
    std::fs::write(&plain, cut.join("\n") + "\n").unwrap();
    let out = reidentify(&old, &plain, &dir.join("x.toml"), false);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no probe measurement column"), "{err}");
    assert!(!dir.join("x.toml").exists());
    // A fitted dynamic model is refused by name.
    let out = command()
        .args([
            "reidentify",
            "--machine",
            MACHINE,
            "--model",
            "tests/linuxcnc/model_d.json",
            "--run",
        ])
        .arg(&good)
        .args(["--out"])
        .arg(dir.join("x.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
}

/// `truepos run --reload-on-change` takes a rewritten model file without a restart and refuses
/// a broken one, naming it, while the running model stays; both are events of the log.
#[test]
fn a_running_service_reloads_a_rewritten_model_file() {
    let dir = scratch("run-reload");
    let machine = truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml"))
        .unwrap()
        .machine;
    let original =
        truepos_io::model_file::position::load(&repo("examples/vmc3/model.toml"), &machine)
            .unwrap();
    let model = dir.join("model.toml");
    let write = |m: &Model| {
        let tmp = dir.join("model.tmp");
        std::fs::write(&tmp, ModelFile::from_model(m, &machine).to_toml()).unwrap();
        std::fs::rename(&tmp, &model).unwrap();
    };
    write(&original);
    let db = dir.join("service.sqlite");
    let child = command()
        .args(["run", "--machine", "examples/vmc3/machine.toml", "--models"])
        .arg(&model)
        .args([
            "--source",
            "replay:examples/vmc3/run.csv@100",
            // On the data's clock: 12 000 s of the run in 120 s, a cycle every 10 ms.
            "--duration-s",
            "12000",
            "--period-ms",
            "1000",
            "--reload-on-change",
            "--json",
            "--log",
        ])
        .arg(&db)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Waits (up to 20 s) until the log holds what `ready` looks for.
    let wait_for = |ready: &dyn Fn() -> bool| {
        let start = std::time::Instant::now();
        while !ready() {
            assert!(start.elapsed().as_secs() < 20, "timed out");
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    };
    let logged = |kind: &str| {
        truepos_runtime::log::read_events(&db)
            .map(|e| e.iter().any(|e| e.kind == kind))
            .unwrap_or(false)
    };
    // The service runs (the reload thread started before the first cycle).
    wait_for(&|| truepos_runtime::log::read_cycles(&db, Some(1)).is_ok_and(|c| !c.1.is_empty()));
    let theta: Vec<f64> = original.parameters().iter().map(|p| p * 1.5).collect();
    write(&original.with_parameters(&machine, &theta).unwrap());
    wait_for(&|| logged("model-reloaded"));
    let tmp = dir.join("model.tmp");
    std::fs::write(&tmp, "format = \"truepos-model\"\nversion = 1\nname = \n").unwrap();
    std::fs::rename(&tmp, &model).unwrap();
    wait_for(&|| logged("model-reload-failed"));
    // SIGTERM, as a service manager stops it: the run ends normally.
    let killed = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("reloaded {}", model.display())),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!(
            "reload refused, the running model stays: {}:3:",
            model.display()
        )),
        "{stderr}"
    );
    let events = truepos_runtime::log::read_events(&db).unwrap();
    let kinds: Vec<&str> = events.iter().map(|e| e.kind.as_str()).collect();
    assert!(kinds.contains(&"model-reloaded"), "{kinds:?}");
    assert!(kinds.contains(&"model-reload-failed"), "{kinds:?}");
    std::fs::remove_dir_all(&dir).ok();
}
