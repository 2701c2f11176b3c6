//! `truepos fleet refit` end to end, on loopback with a real Mosquitto and PostgreSQL 15
//! (started and stopped here; missing, the test fails, it never skips): `truepos run --mqtt`
//! replays the example VMC's 4 h run at 500× with a probe event on Z every minute of run time
//! (measured = what the example model predicts at that row, ±0.5 µm of scatter), `truepos fleet
//! ingest` stores it; `fleet_probes` then holds every accepted probe event of the log, once.
//! A refit of the first minutes (too few probes) is refused with nothing registered; a refit of
//! everything registers a signed candidate whose parent is the active model, whose provenance
//! names the store, machine, range, rows and probes and whose validation is the fit's; `fleet
//! models get --trusted-keys` accepts it, and `fleet follow --once` makes it the shadow.

#[path = "support/mosquitto.rs"]
mod mosquitto;
#[path = "support/postgres.rs"]
mod postgres_cluster;
mod support;

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use mosquitto::Reaped;
use postgres_cluster::Postgres;
use support::{command, repo, scratch};
use truepos_model::CycleInput;

const MACHINE: &str = "vmc-3axis";

/// Runs the binary with a deadline of 120 s: (success, stdout, stderr).
fn truepos(args: &[&str]) -> (bool, String, String) {
    support::run_within(args, Duration::from_secs(120))
}

fn ok(r: (bool, String, String)) -> String {
    assert!(r.0, "{}{}", r.1, r.2);
    r.1
}

fn wait_until(secs: u64, what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(secs);
    while !done() {
        assert!(Instant::now() < deadline, "{what} within {secs} s");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The example run with a probe event on Z at every row after the first: measured = what the
/// example model predicts at the row's inputs, with ±0.5 µm of deterministic scatter.
fn probe_run(dir: &Path) -> PathBuf {
    let machine = truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml")).unwrap();
    let m = &machine.machine;
    let mut model = truepos_io::model_file::load(&repo("examples/vmc3/model.toml"), m)
        .unwrap()
        .model;
    let run = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = run.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let temps: Vec<usize> = m.temperatures.iter().map(|t| col(&t.id)).collect();
    let ops: Vec<usize> = m.operating.iter().map(|o| col(&o.id)).collect();
    let axes: Vec<usize> = m
        .axes
        .iter()
        .map(|a| col(&format!("{}_mm", a.name)))
        .collect();
    let z = m.axes.iter().position(|a| a.name == "Z").unwrap();
    let mut out = vec![format!("{},probe_z_mm,probe_dz_um", header.join(","))];
    for (i, line) in lines.enumerate() {
        let v: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
        let pick = |cols: &[usize]| cols.iter().map(|&c| v[c]).collect::<Vec<f64>>();
        let (t, p, o) = (pick(&temps), pick(&axes), pick(&ops));
        let e = model
            .step(
                0.0,
                &CycleInput {
                    temperatures_c: &t,
                    positions: &p,
                    operating: &o,
                },
            )
            .unwrap();
        let probe = if i == 0 {
            ",".to_string()
        } else {
            let scatter = 0.5 * (i as f64 * 2.3).sin();
            format!("{},{:.4}", p[z], e[z] + scatter)
        };
        out.push(format!("{line},{probe}"));
    }
    let path = dir.join("probes.csv");
    std::fs::write(&path, out.join("\n") + "\n").unwrap();
    path
}

/// The accepted probe events of a log: (data time in ms, measured dz in µm), in time order.
fn logged_probes(log: &Path) -> Vec<(i64, f64)> {
    let c = rusqlite::Connection::open(log).unwrap();
    let meta: String = c
        .query_row("SELECT value FROM meta WHERE key = 'service'", [], |r| {
            r.get(0)
        })
        .unwrap();
    let start = serde_json::from_str::<serde_json::Value>(&meta).unwrap()["started_unix_s"]
        .as_f64()
        .unwrap();
    let mut st = c
        .prepare("SELECT time_s, probe_dz_um FROM probes WHERE status = 'accepted' ORDER BY rowid")
        .unwrap();
    let rows = st
        .query_map([], |r| {
            let t: f64 = r.get(0)?;
            Ok((((start + t) * 1000.0).round() as i64, r.get(1)?))
        })
        .unwrap();
    rows.map(Result::unwrap).collect()
}

fn stored_probes(pg: &Postgres) -> Vec<(i64, f64)> {
    let text = pg.query(
        "SELECT round(extract(epoch FROM t) * 1000)::bigint, \"values\"->>'probe_dz_um' \
         FROM fleet_probes WHERE node_id = 'vmc-3axis' ORDER BY t",
    );
    text.lines()
        .filter(|l| !l.is_empty())
        .map(|l| {
            let (t, v) = l.split_once(',').unwrap();
            (t.parse().unwrap(), v.parse().unwrap())
        })
        .collect()
}

#[test]
fn a_machine_refitted_from_the_store_becomes_a_signed_candidate() {
    let dir = scratch("fleet-refit");
    let port = mosquitto::free_port();
    let _broker = mosquitto::start(&dir, port);
    let pg = Postgres::start(&dir);
    let url = format!("mqtt://127.0.0.1:{port}");
    let _ingest = Reaped(
        command()
            .args(["fleet", "ingest", "--mqtt", &url, "--db", &pg.url()])
            .args(["--duration-s", "240"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("ingest.err")).unwrap())
            .spawn()
            .unwrap(),
    );

    // The key, and the example model signed, registered and activated: the refit's parent.
    let key = dir.join("fleet.key");
    let key_s = key.to_str().unwrap();
    ok(truepos(&["sign", "--new-key", key_s]));
    let trusted = format!("{key_s}.pub");
    let active_dir = dir.join("active");
    std::fs::create_dir_all(&active_dir).unwrap();
    let active = active_dir.join("model.toml");
    std::fs::copy(repo("examples/vmc3/model.toml"), &active).unwrap();
    let active_s = active.to_str().unwrap();
    ok(truepos(&["sign", "--key", key_s, active_s]));
    let machine_file = "examples/vmc3/machine.toml";
    ok(truepos(&[
        "fleet",
        "models",
        "register",
        "--db",
        &pg.url(),
        "--machine",
        MACHINE,
        "--model",
        active_s,
        "--trusted-keys",
        &trusted,
        "--machine-file",
        machine_file,
    ]));
    wait_until(30, "the store's schema", || {
        pg.query("SELECT count(*) FROM pg_tables WHERE tablename = 'fleet_probes'") == "1"
    });
    std::thread::sleep(Duration::from_millis(500));
    ok(truepos(&[
        "fleet",
        "activate",
        "--db",
        &pg.url(),
        "--machine",
        MACHINE,
        "--version",
        "1",
    ]));

    // The service: the example's 4 h at 500× with its probes, published as it logs.
    let probes = probe_run(&dir);
    let log = dir.join("service.sqlite");
    let started = Instant::now();
    let run = truepos(&[
        "run",
        "--source",
        "replay:examples/vmc3/run.csv@500",
        "--source",
        &format!("probes:{}@500", probes.display()),
        "--period-ms",
        "100",
        "--log",
        log.to_str().unwrap(),
        "--mqtt",
        &url,
    ]);
    assert!(run.0, "{}{}", run.1, run.2);
    let run_s = started.elapsed().as_secs_f64();

    // Every accepted probe event of the log in fleet_probes, once, with its measured error.
    let logged = logged_probes(&log);
    assert!(
        logged.len() >= 100,
        "only {} probe events logged",
        logged.len()
    );
    wait_until(60, "every probe event in the store", || {
        pg.query("SELECT count(*) FROM fleet_probes") == logged.len().to_string()
    });
    let stored = stored_probes(&pg);
    assert_eq!(stored.len(), logged.len());
    for (s, l) in stored.iter().zip(&logged) {
        assert!(
            (s.0 - l.0).abs() <= 1,
            "probe at {} ms stored at {} ms",
            l.0,
            s.0
        );
        assert!((s.1 - l.1).abs() < 1e-9, "{s:?} vs {l:?}");
    }
    // The publisher's cursor covers the probes too.
    let cursor = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with(".mqtt-cursor"))
        .expect("a cursor file");
    let cursor: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cursor).unwrap()).unwrap();
    assert!(cursor["rows"]["probes"].as_i64().unwrap() > 0, "{cursor}");
    let seconds: i64 = pg
        .query("SELECT count(*) FROM fleet_seconds")
        .parse()
        .unwrap();

    // Too few probes: the first five minutes of the run. Refused, nothing registered.
    let until = pg.query("SELECT t FROM fleet_probes ORDER BY t OFFSET 5 LIMIT 1");
    let out = dir.join("refit");
    let out_s = out.to_str().unwrap();
    let db_url = pg.url();
    let refit = |extra: &[&str]| {
        let mut words = vec![
            "fleet",
            "refit",
            "--db",
            &db_url,
            "--machine",
            MACHINE,
            "--machine-file",
            machine_file,
            "--key",
            key_s,
            "--out",
            out_s,
        ];
        words.extend_from_slice(extra);
        truepos(&words)
    };
    let few = refit(&["--until", &until]);
    assert!(
        !few.0,
        "a refit on 5 probes was accepted: {}{}",
        few.1, few.2
    );
    assert!(
        few.2.contains("5 accepted probe event(s)") && few.2.contains("nothing registered"),
        "{}",
        few.2
    );
    assert_eq!(pg.query("SELECT count(*) FROM fleet_models"), "1");

    // Everything: a signed candidate, parent the active model.
    let started = Instant::now();
    let done = refit(&[]);
    let refit_s = started.elapsed().as_secs_f64();
    assert!(done.0, "{}{}", done.1, done.2);
    assert!(
        done.1
            .contains("registered as version 2 (candidate, parent 1)"),
        "{}",
        done.1
    );
    let row = pg.query(
        "SELECT state, parent_version, provenance->'refit'->>'probes', \
         provenance->'refit'->>'machine', provenance->'refit'->>'store', \
         provenance->'refit'->>'rows', provenance->'refit'->>'from' IS NOT NULL, \
         jsonb_array_length(validation->'metrics') \
         FROM fleet_models WHERE machine = 'vmc-3axis' AND version = 2",
    );
    let f: Vec<&str> = row.split(',').collect();
    assert_eq!(f[0], "candidate", "{row}");
    assert_eq!(f[1], "1", "{row}");
    assert_eq!(f[2], logged.len().to_string(), "{row}");
    assert_eq!(f[3], MACHINE, "{row}");
    assert_eq!(f[4], pg.url(), "{row}");
    assert!(f[5].parse::<i64>().unwrap() >= seconds, "{row}");
    assert_eq!(f[6], "t", "{row}");
    assert_eq!(f[7], "1", "{row}");
    let figures = pg.query(
        "SELECT m->>'target', m->>'rmse_um', m->>'uncompensated_rmse_um' \
         FROM fleet_models, jsonb_array_elements(validation->'metrics') m WHERE version = 2",
    );
    let g: Vec<&str> = figures.split(',').collect();
    assert_eq!(g[0], "probe_dz_um", "{figures}");
    let (rmse, uncompensated): (f64, f64) = (g[1].parse().unwrap(), g[2].parse().unwrap());
    assert!(
        rmse < 0.5 * uncompensated,
        "out of fold {rmse} µm against {uncompensated} µm uncompensated"
    );
    // The store's copy verifies under the key's trust list, and loads for the machine.
    let got = dir.join("got");
    ok(truepos(&[
        "fleet",
        "models",
        "get",
        "--db",
        &pg.url(),
        "--machine",
        MACHINE,
        "--version",
        "2",
        "--out",
        got.to_str().unwrap(),
        "--trusted-keys",
        &trusted,
    ]));
    // Stored as the active model's kind (TOML), so a follower of a TOML model file takes it.
    assert!(got.join("model.toml").is_file() && got.join("model.toml.sig").is_file());
    assert_eq!(
        std::fs::read(got.join("model.toml")).unwrap(),
        std::fs::read(out.join("model.toml")).unwrap()
    );
    // `fleet follow` shadows it like any candidate (one round beside the service's log and
    // model file, which holds the active version 1).
    let service = dir.join("service");
    std::fs::create_dir_all(&service).unwrap();
    std::fs::copy(&active, service.join("model.toml")).unwrap();
    std::fs::copy(
        active_dir.join("model.toml.sig"),
        service.join("model.toml.sig"),
    )
    .unwrap();
    ok(truepos(&[
        "fleet",
        "follow",
        "--db",
        &pg.url(),
        "--machine",
        MACHINE,
        "--machine-file",
        machine_file,
        "--log",
        log.to_str().unwrap(),
        "--model",
        service.join("model.toml").to_str().unwrap(),
        "--trusted-keys",
        &trusted,
        "--once",
    ]));
    assert_eq!(
        pg.query("SELECT state FROM fleet_models WHERE machine = 'vmc-3axis' AND version = 2"),
        "shadow"
    );
    eprintln!(
        "refit: {} probe events logged and stored, {seconds} seconds; run {run_s:.1} s; \
         refit {refit_s:.1} s: probe_dz_um out of fold {rmse:.2} µm against {uncompensated:.2} µm \
         uncompensated",
        logged.len()
    );
}
