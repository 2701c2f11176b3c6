//! `truepos run` against a real OPC UA server on loopback: scripts/opcua_control.py (Python
//! asyncua, installed in .venv by scripts/setup_python.sh) is a simulated control that moves X,
//! serves its positions and temperatures, and applies ΔK = K0 + tanβ·(P − P0) every 20 ms from
//! the values truepos wrote. Without .venv's asyncua these tests fail; they never skip.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use truepos_controls::projection::{project, Form};
use truepos_model::{CycleInput, Model};

mod support;
use support::{command as truepos, repo, scratch};

/// The simulated control's temperatures (°C), by the vmc3 machine's sensor ids.
const TEMPS: [(&str, f64); 16] = [
    ("x_slide_top", 24.0),
    ("x_slide_bottom", 27.0),
    ("y_slide_top", 23.0),
    ("y_slide_bottom", 25.5),
    ("z_slide_front", 22.5),
    ("z_slide_rear", 24.5),
    ("column_front", 21.5),
    ("column_rear", 22.0),
    ("bed_top", 21.2),
    ("bed_bottom", 21.0),
    ("spindle_front_bearing", 35.0),
    ("spindle_rear_bearing", 30.0),
    ("spindle_motor", 40.0),
    ("head_left", 23.0),
    ("head_right", 23.5),
    ("ambient", 21.0),
];
const POS_Y: f64 = 250.0;
/// The vmc3 machine's operating channels (the model reads none).
const OPERATING: usize = 4;
const POS_Z: f64 = 300.0;
const USER: &str = "truepos:s3cret";

/// The simulated control, killed when dropped.
struct Control {
    child: Child,
    port: u16,
    record: PathBuf,
}

impl Drop for Control {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Starts the control on `port` with its certificate in `pki` (made on first use), recording
/// into `record`; waits until it listens.
fn start_control(port: u16, pki: &Path, record: &Path, extra: &[&str]) -> Control {
    let python = repo(".venv/bin/python");
    assert!(
        python.exists(),
        "{} is missing: run scripts/setup_python.sh (it installs asyncua in .venv)",
        python.display()
    );
    let mut cmd = Command::new(&python);
    cmd.arg(repo("scripts/opcua_control.py"))
        .args([
            "--port",
            &port.to_string(),
            "--user",
            USER,
            "--reader",
            "admin:admin",
        ])
        .arg("--pki")
        .arg(pki)
        .arg("--record")
        .arg(record)
        .args(["--pos-y", &POS_Y.to_string(), "--pos-z", &POS_Z.to_string()]);
    for (id, t) in TEMPS {
        cmd.args(["--temp", &format!("{id}={t}")]);
    }
    let mut child = cmd
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", python.display()));
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if line.contains("listening") {
                let _ = tx.send(());
            }
        }
    });
    let mut control = Control {
        child,
        port,
        record: record.to_path_buf(),
    };
    if rx.recv_timeout(Duration::from_secs(60)).is_err() {
        let status = control.child.try_wait();
        panic!("the simulated control did not start listening within 60 s ({status:?}); is asyncua in .venv (scripts/setup_python.sh)?");
    }
    control
}

/// The connection part of a sink or source configuration.
fn connection(port: u16, client_pki: &Path, user: &str, mode: &str) -> String {
    let (u, p) = user.split_once(':').unwrap();
    format!(
        "endpoint = \"opc.tcp://127.0.0.1:{port}/truepos-sim\"\nsecurity_policy = \"Basic256Sha256\"\nsecurity_mode = \"{mode}\"\npki_dir = \"{}\"\nuser = \"{u}\"\npassword = \"{p}\"\ntimeout_ms = 2000\nbackoff = {{ initial_ms = 200, max_ms = 1000 }}\n",
        client_pki.display()
    )
}

const SEA: &str = "ns=2;s=/NC/_N_AX_SEA_ACX/";

fn sink_mapping(conn: &str, y_tan_beta: &str) -> String {
    let mut s = format!("{conn}rate_hz = 10\n");
    for (u, axis) in ["X", "Y", "Z"].iter().enumerate() {
        let u = u + 1;
        let tan_beta = if *axis == "Y" {
            y_tan_beta.to_string()
        } else {
            format!("{SEA}$SA_TEMP_COMP_SLOPE[u{u}]")
        };
        s += &format!(
            "[[axis]]\naxis = \"{axis}\"\nk0 = \"{SEA}$SA_TEMP_COMP_ABS_VALUE[u{u}]\"\ntan_beta = \"{tan_beta}\"\np0 = \"{SEA}$SA_TEMP_COMP_REF_POSITION[u{u}]\"\np0_mm = 100.0\nmax_rate_um_per_s = 1000.0\n"
        );
    }
    s
}

fn source_config(conn: &str) -> String {
    let mut s = format!("{conn}sample_ms = 100\n");
    for (u, axis) in ["X", "Y", "Z"].iter().enumerate() {
        s += &format!(
            "[[channel]]\naxis = \"{axis}\"\nnode = \"ns=2;s=/Channel/MachineAxis/actToolBasePos[u1,{}]\"\n",
            u + 1
        );
    }
    for (id, _) in TEMPS {
        s += &format!("[[channel]]\ntemperature = \"{id}\"\nnode = \"ns=2;s=/Plc/Temp/{id}\"\n");
    }
    s
}

/// Writes the sink and source configurations of a run into `dir`: (sink, source).
fn configs(
    dir: &Path,
    port: u16,
    client_pki: &Path,
    user: &str,
    y_tan_beta: &str,
) -> (PathBuf, PathBuf) {
    let conn = connection(port, client_pki, user, "SignAndEncrypt");
    let sink = dir.join("sink.toml");
    let source = dir.join("source.toml");
    std::fs::write(&sink, sink_mapping(&conn, y_tan_beta)).unwrap();
    // The source reads over Sign only: both modes are exercised.
    std::fs::write(
        &source,
        source_config(&connection(port, client_pki, USER, "Sign")),
    )
    .unwrap();
    (sink, source)
}

fn run_truepos(sink: &Path, source: &Path, seconds: f64, extra: &[&str]) -> Output {
    truepos()
        .args([
            "run",
            "--machine",
            "examples/vmc3/machine.toml",
            "--models",
            "examples/vmc3/model.toml",
        ])
        .args([
            "--blend-s",
            "0",
            "--duration-s",
            &seconds.to_string(),
            "--json",
        ])
        .arg("--source")
        .arg(format!("opcua:{}", source.display()))
        .arg("--sink")
        .arg(format!("opcua:{}", sink.display()))
        .args(extra)
        .output()
        .unwrap()
}

/// Trusts the control: the certificate the client's first, refused connection put into
/// `rejected/` moves into `trusted/`, as a person would after checking it.
fn trust_rejected(client_pki: &Path) {
    let rejected = client_pki.join("rejected");
    let trusted = client_pki.join("trusted");
    std::fs::create_dir_all(&trusted).unwrap();
    let mut moved = 0;
    for e in std::fs::read_dir(&rejected).unwrap() {
        let p = e.unwrap().path();
        std::fs::rename(&p, trusted.join(p.file_name().unwrap())).unwrap();
        moved += 1;
    }
    assert_eq!(
        moved,
        1,
        "expected the control's certificate in {}",
        rejected.display()
    );
}

/// The control's record: (header, rows).
fn record(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .filter(|l| l.split(',').count() == header.len())
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

fn col(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).unwrap()
}

/// The model's compensation (µm) of every axis at X = `x` with Y, Z where the control holds them.
fn model_compensation(model: &Model, x: f64) -> Vec<f64> {
    let temps: Vec<f64> = TEMPS.iter().map(|t| t.1).collect();
    let e = model
        .evaluate(&CycleInput {
            temperatures_c: &temps,
            positions: &[x, POS_Y, POS_Z],
            operating: &[0.0; OPERATING],
        })
        .unwrap();
    e.error_um().iter().map(|v| -v).collect()
}

fn vmc3() -> (truepos_model::Machine, Model) {
    let machine = truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml"))
        .unwrap()
        .machine;
    let model = truepos_io::model_file::load(&repo("examples/vmc3/model.toml"), &machine)
        .unwrap()
        .model
        .as_static()
        .cloned()
        .unwrap();
    (machine, model)
}

/// The projection error of each axis' line at the control's temperatures (µm): what the
/// applied compensation may miss the model by.
fn projection_error(machine: &truepos_model::Machine, model: &Model) -> Vec<f64> {
    let temps: Vec<f64> = TEMPS.iter().map(|t| t.1).collect();
    let f = |p: &[f64]| -> Result<Vec<f64>, String> {
        Ok(model
            .evaluate(&CycleInput {
                temperatures_c: &temps,
                positions: p,
                operating: &[0.0; OPERATING],
            })
            .map_err(|e| e.to_string())?
            .error_um()
            .to_vec())
    };
    project(
        machine,
        &f,
        &[400.0, POS_Y, POS_Z],
        Form::Linear,
        &[100.0; 3],
    )
    .unwrap()
    .iter()
    .map(|p| p.along_error_um)
    .collect()
}

/// The control's speed along X, mm/s (the script's default).
const SPEED_X: f64 = 200.0;
/// How old the values the control applies may be: a write period (100 ms), the source's
/// sampling of the position (100 ms), the control's tick (20 ms) and round trips, with margin
/// for a loaded host (measured: 0.63 µm of Z, i.e. about 0.2 s of X's motion).
const LATENCY_S: f64 = 0.5;

/// What the applied compensation of each axis may miss the model by, µm: the projection error
/// along the axis' own travel, and for Y and Z the change of their compensation while X moves
/// during `LATENCY_S` — their dependence on X is a cross-axis term no per-axis line carries, so
/// K0 follows X only as fast as it is rewritten.
fn tolerance(machine: &truepos_model::Machine, model: &Model) -> Vec<f64> {
    let along = projection_error(machine, model);
    let dx = SPEED_X * LATENCY_S;
    (0..3)
        .map(|a| {
            let cross = if a == 0 {
                0.0
            } else {
                (0..=80)
                    .map(|k| {
                        let x = 10.0 * k as f64;
                        let x2 = (x + dx).min(800.0);
                        (model_compensation(model, x2)[a] - model_compensation(model, x)[a]).abs()
                    })
                    .fold(0.0, f64::max)
            };
            along[a] + cross + 0.01
        })
        .collect()
}

/// Rows of the record from `from_s` on: the largest |applied − model| per axis (µm) and the
/// number of rows checked.
fn worst_miss(path: &Path, model: &Model, from_s: f64, until_s: f64) -> (Vec<f64>, usize) {
    let (h, rows) = record(path);
    let mut worst = vec![0.0_f64; 3];
    let mut n = 0;
    for r in rows.iter().filter(|r| r[0] >= from_s && r[0] <= until_s) {
        let x = r[col(&h, "X_mm")];
        let want = model_compensation(model, x);
        for (a, axis) in ["X", "Y", "Z"].iter().enumerate() {
            let applied_um = 1000.0 * r[col(&h, &format!("{axis}_dk_mm"))];
            worst[a] = worst[a].max((applied_um - want[a]).abs());
        }
        n += 1;
    }
    (worst, n)
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// First contact, trust, then the compensation the control applies along X's whole travel
/// (0 → 800 → 0 mm at 200 mm/s) against the model, within the projection error.
#[test]
fn the_control_applies_the_models_line_along_the_whole_move() {
    let dir = scratch("opcua-e2e");
    let port = free_port();
    let control = start_control(port, &dir.join("server"), &dir.join("record.csv"), &[]);
    let client_pki = dir.join("client");
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );

    // An unknown server certificate is refused, saying where the trust list is.
    let first = run_truepos(&sink, &source, 2.0, &[]);
    let (_, err) = text(&first);
    assert!(
        err.contains("BadCertificateUntrusted") || err.contains("trust list"),
        "{err}"
    );
    assert!(
        err.contains(&client_pki.join("trusted").display().to_string()),
        "{err}"
    );
    trust_rejected(&client_pki);

    let started = Instant::now();
    let out = run_truepos(&sink, &source, 12.0, &[]);
    let wall = started.elapsed().as_secs_f64();
    let (json, err) = text(&out);
    assert!(out.status.success(), "{err}\n{json}");
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert_eq!(v["state"], "active", "{json}");
    // The writes' round trips, as the sink reports them at its end.
    let line = err
        .lines()
        .find(|l| l.contains("round trip p50"))
        .unwrap_or_else(|| panic!("{err}"));
    eprintln!("{line} (run of {wall:.1} s)");

    let (machine, model) = vmc3();
    let tolerance = tolerance(&machine, &model);
    // From 4 s of the control's clock on (its start, the session and the first writes are over),
    // until truepos stopped.
    let (h, rows) = record(&control.record);
    let written: Vec<&Vec<f64>> = rows
        .iter()
        .filter(|r| r[col(&h, "X_k0_mm")] != 0.0)
        .collect();
    assert!(!written.is_empty(), "the control never got K0");
    let from = written[0][0] + 0.5;
    let until = written.last().unwrap()[0];
    let (worst, n) = worst_miss(&control.record, &model, from, until);
    assert!(n > 200, "only {n} rows between {from} and {until} s");
    let xs: Vec<f64> = rows
        .iter()
        .filter(|r| r[0] >= from && r[0] <= until)
        .map(|r| r[col(&h, "X_mm")])
        .collect();
    let span =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 790.0, "X covered only {span} mm");
    eprintln!("largest |applied − model| X, Y, Z: {worst:.4?} µm over {n} control ticks (bounds {tolerance:.4?} µm)");
    for a in 0..3 {
        assert!(
            worst[a] <= tolerance[a],
            "axis {a}: the control applied up to {} µm off the model (projection error {} µm)",
            worst[a],
            tolerance[a]
        );
    }
    // The compensation is not trivially zero: X's changes along the travel by tens of µm.
    let dk = |x: f64| model_compensation(&model, x)[0];
    assert!((dk(800.0) - dk(0.0)).abs() > 10.0);
    // P0 is the mapping's.
    assert_eq!(written.last().unwrap()[col(&h, "X_p0_mm")], 100.0);
    std::fs::remove_dir_all(&dir).ok();
}

/// A client whose trust list holds the control's certificate, for the fault tests: the first,
/// refused connection puts it into `rejected/`, from where it is trusted.
fn trusted_client(dir: &Path, control: &Control) -> PathBuf {
    let client_pki = dir.join("client");
    let (sink, source) = configs(
        dir,
        control.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let first = run_truepos(&sink, &source, 1.5, &[]);
    assert!(!first.status.success());
    trust_rejected(&client_pki);
    client_pki
}

/// The server stops for 2 s and comes back (same certificate, same port): the session reopens,
/// writes resume, and the control applies the model's line again. The run reports the failure
/// and its recovery (non-zero exit: a sink failed during it), never a crash.
#[test]
fn a_server_restart_reopens_the_session_and_writes_resume() {
    let dir = scratch("opcua-restart");
    let port = free_port();
    let pki = dir.join("server");
    let control = start_control(port, &pki, &dir.join("before.csv"), &[]);
    let client_pki = trusted_client(&dir, &control);
    let (sink, source) = configs(
        &dir,
        port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let run = std::thread::spawn(move || run_truepos(&sink, &source, 16.0, &[]));
    std::thread::sleep(Duration::from_secs(5));
    drop(control);
    std::thread::sleep(Duration::from_secs(2));
    let after = start_control(port, &pki, &dir.join("after.csv"), &[]);
    let out = run.join().unwrap();
    let (json, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}\n{json}");
    assert!(err.contains("it recovered"), "{err}");
    let line = err.lines().find(|l| l.contains("round trip p50")).unwrap();
    assert!(
        line.contains("2 sessions") || line.contains("3 sessions"),
        "{line}"
    );
    let (machine, model) = vmc3();
    let tolerance = tolerance(&machine, &model);
    let (h, rows) = record(&after.record);
    let written: Vec<&Vec<f64>> = rows
        .iter()
        .filter(|r| r[col(&h, "X_k0_mm")] != 0.0)
        .collect();
    assert!(!written.is_empty(), "no write after the restart:\n{err}");
    let (worst, n) = worst_miss(
        &after.record,
        &model,
        written[0][0] + 0.5,
        written.last().unwrap()[0],
    );
    assert!(n > 20, "{n} rows after the restart");
    for a in 0..3 {
        assert!(
            worst[a] <= tolerance[a],
            "axis {a}: {} µm off after the restart",
            worst[a]
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A wrong password, a user without the write right, a node of the wrong type: each is named
/// (status, node), none crashes the run, and a refused value is never taken as applied.
#[test]
fn refused_sessions_and_writes_are_named_and_nothing_crashes() {
    let dir = scratch("opcua-refused");
    let control = start_control(
        free_port(),
        &dir.join("server"),
        &dir.join("record.csv"),
        &[],
    );
    let client_pki = trusted_client(&dir, &control);

    // A wrong password: the session is refused.
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        "truepos:wrong",
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let out = run_truepos(&sink, &source, 3.0, &[]);
    let (json, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}\n{json}");
    assert!(
        err.contains("BadUserAccessDenied") && err.contains("check the user and password"),
        "{err}"
    );

    // A user who may read but not write (a SINUMERIK user without the SeaWrite realm).
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        "admin:admin",
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let out = run_truepos(&sink, &source, 3.0, &[]);
    let (json, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}\n{json}");
    assert!(
        err.contains("BadUserAccessDenied") && err.contains("$SA_TEMP_COMP_REF_POSITION[u1]"),
        "{err}"
    );
    let (h, rows) = record(&control.record);
    assert!(
        rows.iter().all(|r| r[col(&h, "X_p0_mm")] == 0.0),
        "a refused user's write arrived"
    );

    // Y's tanβ mapped to an Int32 node: BadTypeMismatch named; X and Z are still written.
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_INT_NODE[u1]"),
    );
    let out = run_truepos(&sink, &source, 4.0, &[]);
    let (json, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}\n{json}");
    assert!(
        err.contains("BadTypeMismatch")
            && err.contains("$SA_INT_NODE[u1]")
            && err.contains("axis Y"),
        "{err}"
    );
    let (h, rows) = record(&control.record);
    assert!(
        rows.iter().any(|r| r[col(&h, "X_k0_mm")] != 0.0),
        "X was not written:\n{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A server that answers every write 300 ms late: writes go on, late, and the 1 ms cycle does
/// not notice. A server with another certificate than the trusted one is refused.
#[test]
fn a_slow_server_delays_writes_not_the_cycle_and_a_wrong_certificate_is_refused() {
    let dir = scratch("opcua-slow");
    let control = start_control(
        free_port(),
        &dir.join("server"),
        &dir.join("record.csv"),
        &["--slow-ms", "300"],
    );
    let client_pki = trusted_client(&dir, &control);
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let out = run_truepos(&sink, &source, 6.0, &[]);
    let (json, err) = text(&out);
    assert!(out.status.success(), "{err}\n{json}");
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    // The cycle: no overrun of its 1 ms period caused by the network (the host may still steal
    // time: the bound is far below the server's 300 ms).
    let late_max_us = v["late_max_us"].as_f64().unwrap();
    assert!(
        late_max_us < 100_000.0,
        "a cycle was {late_max_us} µs late\n{json}"
    );
    let line = err.lines().find(|l| l.contains("round trip p50")).unwrap();
    let p50: f64 = line
        .split("p50 ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(p50 >= 300.0, "{line}");
    let (h, rows) = record(&control.record);
    assert!(
        rows.iter().any(|r| r[col(&h, "X_k0_mm")] != 0.0),
        "no write arrived:\n{err}"
    );
    drop(control);

    // Another control on another port, with a certificate of its own (same application URI):
    // not in the trust list, refused.
    let other = start_control(
        free_port(),
        &dir.join("other-server"),
        &dir.join("other.csv"),
        &[],
    );
    let (sink, source) = configs(
        &dir,
        other.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let out = run_truepos(&sink, &source, 2.0, &[]);
    let (_, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("trust list"), "{err}");
    let (h, rows) = record(&other.record);
    assert!(
        rows.iter().all(|r| r[col(&h, "X_k0_mm")] == 0.0),
        "a write reached an untrusted server"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A temperature the model reads turns Bad on the server (BadSensorFailure, its last value
/// kept): the source marks the channel failed at once — not counted ok until it goes stale
/// (`max_age_s`, 10 s here, longer than the rest of the run) — compensation holds and ramps
/// down, and the sink writes that as a constant (tanβ 0), never a NaN.
#[test]
fn a_bad_status_on_a_sensor_node_is_an_invalid_input_never_a_number() {
    let dir = scratch("opcua-bad-sensor");
    // Control time: the first (refused) run and the trust take about 3 s; the fault at 9 s.
    let control = start_control(
        free_port(),
        &dir.join("server"),
        &dir.join("record.csv"),
        &["--bad-temp", "x_slide_top@9"],
    );
    let client_pki = trusted_client(&dir, &control);
    let (sink, source) = configs(
        &dir,
        control.port,
        &client_pki,
        USER,
        &format!("{SEA}$SA_TEMP_COMP_SLOPE[u2]"),
    );
    let machine = repo("examples/vmc3/machine.toml");
    let log = dir.join("log.sqlite");
    let out = truepos()
        .args([
            "run",
            "--models",
            "examples/vmc3/model.toml",
            "--blend-s",
            "0",
            "--hold-ramp-s",
            "2",
        ])
        .args(["--duration-s", "12", "--json", "--machine"])
        .arg(&machine)
        .arg("--log")
        .arg(&log)
        .arg("--source")
        .arg(format!("opcua:{}", source.display()))
        .arg("--sink")
        .arg(format!("opcua:{}", sink.display()))
        .output()
        .unwrap();
    let (json, err) = text(&out);
    assert!(out.status.success(), "{err}\n{json}");
    assert!(
        err.contains("/Plc/Temp/x_slide_top: status BadSensorFailure"),
        "{err}"
    );
    let events = truepos_runtime::log::read_events(&log).unwrap();
    assert!(
        events
            .iter()
            .any(|e| e.kind == "sensor-fault" && e.subject == "x_slide_top"),
        "{events:?}"
    );
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert_ne!(v["state"], "active", "{json}");
    // What the control holds at the end: finite, the slope gone (a constant while holding).
    let (h, rows) = record(&control.record);
    let last = rows.last().unwrap();
    for axis in ["X", "Y", "Z"] {
        assert!(last[col(&h, &format!("{axis}_dk_mm"))].is_finite());
    }
    assert_eq!(last[col(&h, "X_tan_beta")], 0.0, "{last:?}");
    std::fs::remove_dir_all(&dir).ok();
}
