//! `truepos fleet follow` beside a real `truepos run`, against a real PostgreSQL 15 on loopback
//! (started and stopped here; missing, the test fails, it never skips). The service replays the
//! example VMC's 4 h run at 200× with a probe event on Z every minute of run time, whose
//! measured error is what model B predicts at that row (the machine's "truth") with ±0.5 µm of
//! scatter; model A leaves the spindle's growth out, model D doubles it.
//!
//! A is active; B and a tampered C wait as candidates. The follower refuses C (retired, the
//! reason in the history, never shadowed), shadows B on the probes, activates it, writes it
//! into the service's model file, and the service reloads it (its log's `model-reloaded`).
//! Then D is activated by hand while no follower runs; `fleet follow --once` writes it, the
//! service reloads it, and a follower started afresh finds it in the file, judges it on the
//! probes from then on, worse than its parent B by more than the margin: rolled back, B
//! written again. E, a little worse than B, is shadowed and retired. Last, F, activated by
//! hand while the follower runs, is written, reloaded, judged on the probes after the reload
//! and rolled back. With no follower running, H is shadowed and retired by `fleet follow
//! --once` run again and again, each run going on from the cursor the last left.
//!
//! Beside it: a candidate signed by a key the follower's trust list lacks is left a candidate.

#[path = "support/postgres.rs"]
mod postgres_cluster;
mod support;

use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use postgres_cluster::Postgres;
use support::{command, repo, scratch};
use truepos_model::CycleInput;

const MACHINE: &str = "vmc-3axis";

/// Runs the binary with a deadline of 60 s: (success, stdout, stderr).
fn truepos(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    support::run_within(args, Duration::from_secs(60))
}

fn ok(r: (bool, String, String)) -> String {
    assert!(r.0, "{}{}", r.1, r.2);
    r.1
}

fn run_words(words: &[&str], paths: &[(&str, &Path)]) -> (bool, String, String) {
    let mut args: Vec<std::ffi::OsString> = words.iter().map(|w| (*w).into()).collect();
    for (flag, p) in paths {
        if !flag.is_empty() {
            args.push((*flag).into());
        }
        args.push(p.as_os_str().into());
    }
    let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
    truepos(&refs)
}

/// A copy of the example model with a text replaced, signed, in a directory of its own.
fn signed_model(dir: &Path, key: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let d = dir.join(name);
    std::fs::create_dir_all(&d).unwrap();
    let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    let path = d.join("model.toml");
    std::fs::write(
        &path,
        format!("# model {name}\n{}", text.replacen(from, to, 1)),
    )
    .unwrap();
    ok(run_words(&["sign", "--key"], &[("", key), ("", &path)]));
    path
}

/// The example run with a probe event on Z at every row after the first: measured = what
/// `truth` predicts at the row's inputs (the probed position: the row's).
fn probe_run(dir: &Path, truth: &Path) -> PathBuf {
    let machine = truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml")).unwrap();
    let m = &machine.machine;
    let mut model = truepos_io::model_file::load(truth, m).unwrap().model;
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
            // A probe's own scatter: ±0.5 µm, deterministic.
            let scatter = 0.5 * (i as f64 * 2.3).sin();
            format!("{},{:.4}", p[z], e[z] + scatter)
        };
        out.push(format!("{line},{probe}"));
    }
    let path = dir.join("probes.csv");
    std::fs::write(&path, out.join("\n") + "\n").unwrap();
    path
}

struct Fixture {
    pg: Postgres,
    key: PathBuf,
    trusted: PathBuf,
    machine_file: PathBuf,
}

impl Fixture {
    fn fleet(&self, words: &[&str], paths: &[(&str, &Path)]) -> String {
        let mut w = vec!["fleet"];
        w.extend(words);
        let url = self.pg.url();
        w.extend(["--db", &url]);
        ok(run_words(&w, paths))
    }

    fn register(&self, model: &Path) -> String {
        self.fleet(
            &["models", "register", "--machine", MACHINE],
            &[
                ("--model", model),
                ("--trusted-keys", &self.trusted),
                ("--machine-file", &self.machine_file),
            ],
        )
    }

    fn state(&self, version: i32) -> String {
        self.pg.query(&format!(
            "SELECT state FROM fleet_models WHERE machine = '{MACHINE}' AND version = {version}"
        ))
    }

    /// Waits (at most `secs`) until `version` is in `state`.
    fn wait_state(&self, version: i32, state: &str, secs: u64, why: &dyn Fn() -> String) {
        let deadline = Instant::now() + Duration::from_secs(secs);
        while self.state(version) != state {
            assert!(
                Instant::now() < deadline,
                "version {version} not {state} within {secs} s (it is {}): {}",
                self.state(version),
                why()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// `to_state|reason` of every change of a version, in order.
    fn history(&self, version: i32) -> Vec<String> {
        self.pg
            .query(&format!(
                "SELECT to_state || '|' || reason FROM fleet_model_changes \
                 WHERE machine = '{MACHINE}' AND version = {version} ORDER BY id"
            ))
            .lines()
            .map(String::from)
            .collect()
    }
}

/// Kills a child when the test ends, passing or not.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn reload_events(log: &Path) -> Vec<(f64, String, String)> {
    truepos_runtime::log::read_events(log)
        .unwrap_or_default()
        .into_iter()
        .filter(|e| e.kind.starts_with("model-reload"))
        .map(|e| (e.time_s, e.kind, e.detail))
        .collect()
}

/// The reloads that loaded.
fn reloaded(log: &Path) -> usize {
    reload_events(log)
        .iter()
        .filter(|e| e.1 == "model-reloaded")
        .count()
}

#[test]
fn the_follower_refuses_a_tampered_model_activates_a_better_one_and_rolls_back_a_worse_one() {
    let started = Instant::now();
    let dir = scratch("fleet-follow");
    let pg = Postgres::start(&dir);
    let key = dir.join("builder.key");
    ok(run_words(&["sign", "--new-key"], &[("", &key)]));
    let f = Fixture {
        trusted: dir.join("builder.key.pub"),
        machine_file: repo("examples/vmc3/machine.toml"),
        key,
        pg,
    };
    let spindle = "k_um_per_k = 3.1";
    let a = signed_model(&dir, &f.key, "a", spindle, "k_um_per_k = 0.0");
    let b = signed_model(&dir, &f.key, "b", spindle, spindle);
    let c = signed_model(&dir, &f.key, "c", spindle, "k_um_per_k = 3.0");
    let d = signed_model(&dir, &f.key, "d", spindle, "k_um_per_k = 6.2");
    let e = signed_model(&dir, &f.key, "e", spindle, "k_um_per_k = 3.6");
    let f6 = signed_model(&dir, &f.key, "f", spindle, "k_um_per_k = 7.0");
    let h = signed_model(&dir, &f.key, "h", spindle, "k_um_per_k = 3.7");
    let probes = probe_run(&dir, &b);

    // A rule that cannot decide is refused before anything is read.
    for (flag, value, word) in [
        ("--margin", "1.5", "--margin 1.5: give 0 to below 1"),
        ("--min-probes", "0", "--min-probes 0: give 1 to 1000000"),
    ] {
        let r = run_words(
            &[
                "fleet",
                "follow",
                "--db",
                &f.pg.url(),
                "--machine",
                MACHINE,
                flag,
                value,
            ],
            &[
                ("--machine-file", &f.machine_file),
                ("--log", &dir.join("none.sqlite")),
                ("--model", &a),
                ("--trusted-keys", &f.trusted),
            ],
        );
        assert!(!r.0 && r.2.contains(word), "{}", r.2);
    }

    // A active, B and C candidates; C's bytes changed in the store, its hash recomputed.
    f.register(&a);
    f.fleet(&["activate", "--machine", MACHINE, "--version", "1"], &[]);
    f.register(&b);
    f.register(&c);
    f.pg.query(
        "UPDATE fleet_models SET model = model || '\\x230a'::bytea, \
         sha256 = encode(sha256(model || '\\x230a'::bytea), 'hex') \
         WHERE machine = 'vmc-3axis' AND version = 3 RETURNING version",
    );

    // The service runs A from its model file.
    let service_dir = dir.join("service");
    std::fs::create_dir_all(&service_dir).unwrap();
    let model = service_dir.join("model.toml");
    let sig = service_dir.join("model.toml.sig");
    std::fs::copy(&a, &model).unwrap();
    std::fs::copy(a.with_file_name("model.toml.sig"), &sig).unwrap();
    let log = dir.join("service.sqlite");
    let replay = "replay:examples/vmc3/run.csv@200";
    let probe_source = format!("probes:{}@200", probes.display());
    let service = Killed(
        command()
            .args(["run", "--source", replay, "--source", &probe_source])
            .args(["--period-ms", "100", "--reload-on-change", "--models"])
            .arg(&model)
            .arg("--trusted-keys")
            .arg(&f.trusted)
            .arg("--log")
            .arg(&log)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let follower_out = dir.join("follow.out");
    let written = dir.join("written.txt");
    // The follower's command: --min-probes 4, a round every 0.2 s, each write recorded.
    let follow = || {
        let mut c = command();
        c.args(["fleet", "follow", "--db", &f.pg.url(), "--machine", MACHINE])
            .arg("--machine-file")
            .arg(&f.machine_file)
            .arg("--log")
            .arg(&log)
            .arg("--model")
            .arg(&model)
            .arg("--trusted-keys")
            .arg(&f.trusted)
            .args([
                "--min-probes",
                "4",
                "--margin",
                "0.1",
                "--interval-s",
                "0.2",
            ])
            .arg("--after-write")
            .arg(format!(
                "echo \"$TRUEPOS_MODEL_VERSION $TRUEPOS_MODEL\" >> {}",
                written.display()
            ))
            .stderr(Stdio::inherit());
        c
    };
    let follower = Killed(
        follow()
            .args(["--duration-s", "90"])
            .stdout(std::fs::File::create(&follower_out).unwrap())
            .spawn()
            .unwrap(),
    );
    let said = || std::fs::read_to_string(&follower_out).unwrap_or_default();

    // C refused: retired with the reason, never shadowed, nothing evaluated.
    f.wait_state(3, "retired", 30, &said);
    let c_history = f.history(3);
    assert_eq!(c_history.len(), 2, "{c_history:?}");
    assert!(
        c_history[1].starts_with("retired|refused by fleet follow: signature"),
        "{c_history:?}"
    );
    assert!(
        said().contains("version 3 refused by fleet follow"),
        "{}",
        said()
    );

    // B shadowed, then activated on the probes, written into the service's file and reloaded.
    f.wait_state(2, "active", 40, &said);
    let b_history = f.history(2);
    assert_eq!(b_history.len(), 3, "{b_history:?}");
    assert!(
        b_history[1].starts_with("shadow|fleet follow"),
        "{b_history:?}"
    );
    assert!(
        b_history[2].starts_with("active|fleet follow: better than version 1 in shadow"),
        "{b_history:?}"
    );
    assert_eq!(f.state(1), "retired");
    let deadline = Instant::now() + Duration::from_secs(20);
    while !reload_events(&log)
        .iter()
        .any(|e| e.1 == "model-reloaded" && e.2 == model.display().to_string())
    {
        assert!(
            Instant::now() < deadline,
            "B never reloaded: {:?}",
            reload_events(&log)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(std::fs::read(&model).unwrap(), std::fs::read(&b).unwrap());
    assert_eq!(
        std::fs::read_to_string(&sig).unwrap(),
        std::fs::read_to_string(b.with_file_name("model.toml.sig")).unwrap()
    );
    // The shadow's residuals: at least the minimum, B's RMS below 0.9 × A's.
    let figures = f.pg.query(
        "SELECT count(*), sqrt(avg((measured_um - active_um)^2)), \
                sqrt(avg((measured_um - shadow_um)^2)) \
         FROM fleet_shadow_probes WHERE machine = 'vmc-3axis' AND version = 2 AND active_version = 1",
    );
    let v: Vec<f64> = figures.split(',').map(|x| x.parse().unwrap()).collect();
    eprintln!(
        "shadow B beside A: {} residuals, RMS A {:.3} µm, B {:.3} µm",
        v[0], v[1], v[2]
    );
    assert!(v[0] >= 4.0 && v[2] < 0.9 * v[1], "{figures}");
    assert_eq!(
        f.pg.query("SELECT count(*) FROM fleet_shadow_probes WHERE version = 3"),
        "0"
    );

    // The follower watches what it activated: B judged against its parent A on the probes
    // after the reload, and kept.
    let deadline = Instant::now() + Duration::from_secs(20);
    while f.pg.query(
        "SELECT count(*) >= 4 FROM fleet_shadow_probes \
         WHERE machine = 'vmc-3axis' AND version = 1 AND active_version = 2",
    ) != "t"
    {
        assert!(
            Instant::now() < deadline,
            "B never judged against A: {}",
            said()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let figures = f.pg.query(
        "SELECT count(*), sqrt(avg((measured_um - active_um)^2)), \
                sqrt(avg((measured_um - shadow_um)^2)) \
         FROM fleet_shadow_probes WHERE machine = 'vmc-3axis' AND version = 1 AND active_version = 2",
    );
    eprintln!("B watched against A (residuals, RMS B, RMS A): {figures}");
    assert!(
        said().contains("version 2 watched against its parent, version 1"),
        "{}",
        said()
    );
    assert_eq!(f.state(2), "active");

    // D activated by hand while no follower runs; a follower run once writes it into the file
    // and exits (its watch gone with it); the follower started next finds D in the file,
    // judges it against its parent B on the probes from then on, and rolls back.
    drop(follower);
    let reloads_before = reloaded(&log);
    f.register(&d);
    f.fleet(
        &[
            "activate",
            "--machine",
            MACHINE,
            "--version",
            "4",
            "--reason",
            "by hand",
        ],
        &[],
    );
    let mut once = follow()
        .arg("--once")
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while once.try_wait().unwrap().is_none() {
        assert!(
            Instant::now() < deadline,
            "fleet follow --once ran over 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let once = once.wait_with_output().unwrap();
    let once_said = String::from_utf8_lossy(&once.stdout).to_string();
    assert!(once.status.success(), "{once_said}");
    assert!(once_said.contains("version 4 written to"), "{once_said}");
    assert!(
        once_said.contains("version 4 watched against its parent, version 2"),
        "{once_said}"
    );
    let follower_out = dir.join("follow-again.out");
    let follower = Killed(
        follow()
            .args(["--duration-s", "90"])
            .stdout(std::fs::File::create(&follower_out).unwrap())
            .spawn()
            .unwrap(),
    );
    let first_said = said();
    let said = || std::fs::read_to_string(&follower_out).unwrap_or_default();
    f.wait_state(4, "retired", 40, &said);
    assert_eq!(f.state(2), "active");
    let d_history = f.history(4);
    assert!(
        d_history.last().unwrap().starts_with(
            "retired|rolled back to version 2: fleet follow: version 4 worse than its parent 2"
        ),
        "{d_history:?}"
    );
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::fs::read(&model).unwrap() != std::fs::read(&b).unwrap()
        || reloaded(&log) < reloads_before + 2
    {
        assert!(
            Instant::now() < deadline,
            "B not back in the service: {:?}\n{}",
            reload_events(&log),
            said()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let figures = f.pg.query(
        "SELECT count(*), sqrt(avg((measured_um - active_um)^2)), \
                sqrt(avg((measured_um - shadow_um)^2)) \
         FROM fleet_shadow_probes WHERE machine = 'vmc-3axis' AND version = 2 AND active_version = 4",
    );
    let v: Vec<f64> = figures.split(',').map(|x| x.parse().unwrap()).collect();
    eprintln!(
        "D watched against B: {} residuals, RMS D {:.3} µm, B {:.3} µm",
        v[0], v[1], v[2]
    );
    assert!(v[0] >= 4.0 && v[1] > 1.1 * v[2], "{figures}");
    // Every reload loaded, but one that fell between the two renames (the old model read with
    // the new signature: refused, the running model stays), and that one followed by a good
    // one: never new bytes under an old signature.
    let events = reload_events(&log);
    for (i, e) in events.iter().enumerate() {
        if e.1 != "model-reloaded" {
            assert!(
                e.2.contains("the signature does not match the file")
                    && events[i + 1..].iter().any(|n| n.1 == "model-reloaded"),
                "{events:?}"
            );
        }
    }
    assert_eq!(events.last().map(|e| e.1.as_str()), Some("model-reloaded"));
    // E, a little worse than B, shadowed and retired after twice the minimum.
    f.register(&e);
    f.wait_state(5, "retired", 40, &said);
    let e_history = f.history(5);
    assert_eq!(e_history.len(), 3, "{e_history:?}");
    assert!(e_history[1].starts_with("shadow|"), "{e_history:?}");
    assert!(
        e_history[2].starts_with("retired|fleet follow: not better than version 2 by the margin"),
        "{e_history:?}"
    );
    assert_eq!(
        f.pg.query(
            "SELECT count(*) >= 8 FROM fleet_shadow_probes \
             WHERE machine = 'vmc-3axis' AND version = 5 AND active_version = 2"
        ),
        "t"
    );
    assert_eq!(f.state(2), "active");
    assert_eq!(std::fs::read(&model).unwrap(), std::fs::read(&b).unwrap());
    // A probe stored again is kept once (a follower that read the same log rows twice).
    let mut db = truepos_fleet_store::postgres::Client::connect(
        &f.pg.url(),
        truepos_fleet_store::postgres::NoTls,
    )
    .unwrap();
    let again = f.pg.query(
        "SELECT extract(epoch FROM t)::float8, axis, measured_um, active_um, shadow_um, log_row \
         FROM fleet_shadow_probes WHERE version = 5 ORDER BY t LIMIT 1",
    );
    let w: Vec<&str> = again.split(',').collect();
    let probe = truepos_fleet_store::shadow_probes::ShadowProbe {
        t_unix_s: w[0].parse().unwrap(),
        axis: w[1].to_string(),
        measured_um: w[2].parse().unwrap(),
        active_um: w[3].parse().unwrap(),
        shadow_um: w[4].parse().unwrap(),
        log_row: w[5].parse().unwrap(),
    };
    let rows = || f.pg.query("SELECT count(*) FROM fleet_shadow_probes");
    let before = rows();
    let new = truepos_fleet_store::shadow_probes::record(&mut db, MACHINE, 5, 2, &[probe]).unwrap();
    assert_eq!((new, rows()), (0, before));

    // F activated by hand while the follower runs: it writes F, waits for the service's
    // reload, judges F on the probes after it, and rolls back to B.
    f.register(&f6);
    f.fleet(
        &[
            "activate",
            "--machine",
            MACHINE,
            "--version",
            "6",
            "--reason",
            "by hand",
        ],
        &[],
    );
    f.wait_state(6, "retired", 40, &said);
    assert_eq!(f.state(2), "active");
    assert!(
        f.history(6).last().unwrap().starts_with(
            "retired|rolled back to version 2: fleet follow: version 6 worse than its parent 2"
        ),
        "{:?}",
        f.history(6)
    );
    let figures = f.pg.query(
        "SELECT count(*), sqrt(avg((measured_um - active_um)^2)), \
                sqrt(avg((measured_um - shadow_um)^2)) \
         FROM fleet_shadow_probes WHERE machine = 'vmc-3axis' AND version = 2 AND active_version = 6",
    );
    let v: Vec<f64> = figures.split(',').map(|x| x.parse().unwrap()).collect();
    eprintln!(
        "F watched against B: {} residuals, RMS F {:.3} µm, B {:.3} µm",
        v[0], v[1], v[2]
    );
    assert!(v[0] >= 4.0 && v[1] > 1.1 * v[2], "{figures}");
    let reloaded_f = said();
    assert!(
        reloaded_f.contains(&format!("the service reloaded {}", model.display())),
        "{reloaded_f}"
    );
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::fs::read(&model).unwrap() != std::fs::read(&b).unwrap() {
        assert!(Instant::now() < deadline, "B not written back");
        std::thread::sleep(Duration::from_millis(100));
    }

    // No follower running, H registered: `fleet follow --once` run again and again (as from
    // cron) shadows it and, each run reading the probes after the cursor the last one left
    // beside the log, retires it after twice the minimum.
    drop(follower);
    let last_said = said();
    f.register(&h);
    let deadline = Instant::now() + Duration::from_secs(40);
    let mut runs = 0;
    while f.state(7) != "retired" {
        assert!(
            Instant::now() < deadline,
            "H not retired by {runs} runs of --once: {:?}",
            f.history(7)
        );
        let mut once = follow()
            .arg("--once")
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let started = Instant::now();
        while once.try_wait().unwrap().is_none() {
            assert!(started.elapsed() < Duration::from_secs(60), "--once hung");
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(once.wait().unwrap().success());
        runs += 1;
        std::thread::sleep(Duration::from_millis(300));
    }
    let h_history = f.history(7);
    assert!(
        h_history[2].starts_with("retired|fleet follow: not better than version 2"),
        "{h_history:?}"
    );
    assert_eq!(
        f.pg.query(
            "SELECT count(*) >= 8 FROM fleet_shadow_probes \
             WHERE machine = 'vmc-3axis' AND version = 7 AND active_version = 2"
        ),
        "t"
    );
    eprintln!("H retired after {runs} runs of fleet follow --once");
    assert!(
        std::fs::read_to_string(log.with_file_name("service.sqlite.follow-cursor"))
            .unwrap()
            .contains("probes_row")
    );

    // --after-write ran after each file written (what pulses truepos-hal's reload pin).
    let m = model.display();
    assert_eq!(
        std::fs::read_to_string(&written).unwrap(),
        format!("2 {m}\n4 {m}\n2 {m}\n6 {m}\n2 {m}\n")
    );

    let out = last_said;
    assert!(first_said.contains("version 2 activated"), "{first_said}");
    assert!(
        out.contains("version 4 watched against its parent, version 2"),
        "{out}"
    );
    assert!(out.contains("version 4 rolled back to version 2"), "{out}");
    assert!(
        out.contains("version 2 is active again (a rollback): not watched"),
        "{out}"
    );
    drop(service);
    eprintln!("{out}");
    assert!(
        started.elapsed() < Duration::from_secs(150),
        "took {:?}",
        started.elapsed()
    );
}

/// A follower whose trust list lacks the key a candidate was signed with (another site's
/// follower may hold it) is set up wrong, not the model: the candidate stays a candidate.
#[test]
fn a_candidate_signed_by_a_key_the_follower_does_not_trust_is_left_a_candidate() {
    let dir = scratch("fleet-follow-local");
    let pg = Postgres::start(&dir);
    let key = dir.join("builder.key");
    let other = dir.join("other.key");
    ok(run_words(&["sign", "--new-key"], &[("", &key)]));
    ok(run_words(&["sign", "--new-key"], &[("", &other)]));
    // The store's door trusts both keys; the follower only the builder's.
    let both = dir.join("both.pub");
    let text = std::fs::read_to_string(dir.join("builder.key.pub")).unwrap()
        + &std::fs::read_to_string(dir.join("other.key.pub")).unwrap();
    std::fs::write(&both, text).unwrap();
    let f = Fixture {
        trusted: both,
        machine_file: repo("examples/vmc3/machine.toml"),
        key,
        pg,
    };
    let spindle = "k_um_per_k = 3.1";
    let a = signed_model(&dir, &f.key, "a", spindle, spindle);
    let x = signed_model(&dir, &other, "x", spindle, "k_um_per_k = 3.2");
    f.register(&a);
    f.fleet(&["activate", "--machine", MACHINE, "--version", "1"], &[]);
    f.register(&x);
    let model = dir.join("service.toml");
    std::fs::copy(&a, &model).unwrap();
    std::fs::copy(
        a.with_file_name("model.toml.sig"),
        dir.join("service.toml.sig"),
    )
    .unwrap();
    for _ in 0..2 {
        let out = f.fleet(
            &["follow", "--machine", MACHINE, "--once"],
            &[
                ("--machine-file", &f.machine_file),
                ("--log", &dir.join("none.sqlite")),
                ("--model", &model),
                ("--trusted-keys", &dir.join("builder.key.pub")),
            ],
        );
        assert!(
            out.contains("version 2 not taken: signed by") && out.contains("left a candidate"),
            "{out}"
        );
    }
    assert_eq!(f.state(2), "candidate");
    // Registered, nothing since.
    assert_eq!(f.history(2).len(), 1, "{:?}", f.history(2));
}

/// A service's log with a probes table as `truepos run` writes it (the example machine's
/// columns), its rows taken from the example run: a Z probe measured 1 µm off what it logged.
struct HandLog {
    conn: rusqlite::Connection,
    run: Vec<Vec<String>>,
    header: Vec<String>,
}

impl HandLog {
    fn create(path: &Path) -> Self {
        let text = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let run = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        let conn = rusqlite::Connection::open(path).unwrap();
        let machine = truepos_io::machine_file::load(&repo("examples/vmc3/machine.toml")).unwrap();
        let m = &machine.machine;
        let mut cols: Vec<String> = ["time_s", "status", "reason", "state"]
            .map(String::from)
            .to_vec();
        for a in &m.axes {
            cols.extend(truepos_runtime::log::probe_axis_columns(&a.name));
        }
        cols.extend(m.axes.iter().map(|a| format!("{}_mm", a.name)));
        cols.extend(m.temperatures.iter().map(|t| t.id.clone()));
        cols.extend(m.operating.iter().map(|o| o.id.clone()));
        let defs: Vec<String> = cols.iter().map(|c| format!("\"{c}\"")).collect();
        conn.execute_batch(&format!(
            "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
             CREATE TABLE events (time_s REAL NOT NULL, kind TEXT NOT NULL,
                 subject TEXT NOT NULL, detail TEXT NOT NULL);
             CREATE TABLE probes ({});",
            defs.join(", ")
        ))
        .unwrap();
        HandLog { conn, run, header }
    }

    /// The service (re)started at `unix_s`.
    fn start(&self, unix_s: f64) {
        self.conn
            .execute(
                "INSERT OR REPLACE INTO meta (key, value) VALUES ('service', ?1)",
                [serde_json::json!({ "started_unix_s": unix_s }).to_string()],
            )
            .unwrap();
    }

    /// A probe at service time `time_s` with the inputs of the example run's row `row`.
    fn probe(&self, time_s: f64, row: usize) {
        let v = |name: &str| -> f64 {
            let i = self.header.iter().position(|h| h == name).unwrap();
            self.run[row][i].parse().unwrap()
        };
        let mut names = vec!["time_s", "status", "reason", "state"];
        let mut values: Vec<rusqlite::types::Value> = vec![
            time_s.into(),
            "accepted".to_string().into(),
            String::new().into(),
            "compensating".to_string().into(),
        ];
        let (x, y, z) = (v("X_mm"), v("Y_mm"), v("Z_mm"));
        for (n, val) in [
            ("probe_x_mm", x),
            ("probe_y_mm", y),
            ("probe_z_mm", z),
            ("probe_dz_um", 11.0),
            ("predicted_dz_um", 10.0),
        ] {
            names.push(n);
            values.push(val.into());
        }
        let inputs: Vec<String> = self
            .header
            .iter()
            .filter(|h| *h != "time_s")
            .cloned()
            .collect();
        for h in &inputs {
            names.push(h);
            values.push(v(h).into());
        }
        let quoted: Vec<String> = names.iter().map(|n| format!("\"{n}\"")).collect();
        self.conn
            .execute(
                &format!(
                    "INSERT INTO probes ({}) VALUES ({})",
                    quoted.join(", "),
                    vec!["?"; names.len()].join(", ")
                ),
                rusqlite::params_from_iter(values),
            )
            .unwrap();
    }
}

/// A service started again appends a new run to its log, its service time from 0: the
/// follower stamps each probe with the start of its own run, and the reload time it kept from
/// the old run does not hold the new run's probes back (the file is the active model: the
/// new run loaded it at its start).
#[test]
fn a_new_run_in_the_log_is_judged_from_its_own_start() {
    let dir = scratch("fleet-follow-runs");
    let pg = Postgres::start(&dir);
    let key = dir.join("builder.key");
    ok(run_words(&["sign", "--new-key"], &[("", &key)]));
    let f = Fixture {
        trusted: dir.join("builder.key.pub"),
        machine_file: repo("examples/vmc3/machine.toml"),
        key,
        pg,
    };
    let spindle = "k_um_per_k = 3.1";
    let a = signed_model(&dir, &f.key, "a", spindle, spindle);
    let b = signed_model(&dir, &f.key, "b", spindle, "k_um_per_k = 3.3");
    f.register(&a);
    f.fleet(&["activate", "--machine", MACHINE, "--version", "1"], &[]);
    f.register(&b);
    let model = dir.join("service.toml");
    std::fs::copy(&a, &model).unwrap();
    std::fs::copy(
        a.with_file_name("model.toml.sig"),
        dir.join("service.toml.sig"),
    )
    .unwrap();
    let log_path = dir.join("service.sqlite");
    let log = HandLog::create(&log_path);
    log.start(1_000_000.0);
    for (i, t) in [10.0, 20.0, 30.0].into_iter().enumerate() {
        log.probe(t, i + 1);
    }
    let once = || {
        f.fleet(
            &["follow", "--machine", MACHINE, "--once"],
            &[
                ("--machine-file", &f.machine_file),
                ("--log", &log_path),
                ("--model", &model),
                ("--trusted-keys", &f.trusted),
            ],
        )
    };
    // B shadowed, the cursor at the log's end (row 3).
    let out = once();
    assert!(out.contains("version 2 in shadow"), "{out}");
    let cursor_file = dir.join("service.sqlite.follow-cursor");
    let mut cursor: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cursor_file).unwrap()).unwrap();
    assert_eq!(cursor["run_started_unix_s"], 1_000_000.0, "{cursor}");
    // The old run's reload at its 45 s (as if the follower had written a file then).
    cursor["reload"] = serde_json::json!({ "events_before": 0, "at_s": 45.0 });
    std::fs::write(&cursor_file, cursor.to_string()).unwrap();
    // The old run's tail (rows 4, 5), then the service started again 100 s later (rows 6, 7).
    log.probe(40.0, 4);
    log.probe(50.0, 5);
    log.start(1_000_100.0);
    log.probe(5.0, 6);
    log.probe(15.0, 7);
    let out = once();
    assert!(out.contains("the service started again"), "{out}");
    // Row 4 (before the old reload) is left out; row 5 carries the old run's start, 6 and 7
    // the new run's.
    let stored = f.pg.query(
        "SELECT log_row || ' ' || round(extract(epoch FROM t))::bigint FROM fleet_shadow_probes \
         WHERE version = 2 ORDER BY log_row",
    );
    assert_eq!(
        stored.lines().collect::<Vec<_>>(),
        ["5 1000050", "6 1000105", "7 1000115"],
        "{out}"
    );
    let cursor: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cursor_file).unwrap()).unwrap();
    assert_eq!(cursor["run_started_unix_s"], 1_000_100.0, "{cursor}");
    assert_eq!(cursor["probes_row"], 7, "{cursor}");
}

/// The store's active model refused by the follower (its bytes changed in the store) is not
/// written: the service runs the file it has, and the residuals are filed under that file's
/// version; a file the store does not hold at all files nothing.
#[test]
fn residuals_are_filed_under_the_version_the_file_holds() {
    let dir = scratch("fleet-follow-running");
    let pg = Postgres::start(&dir);
    let key = dir.join("builder.key");
    ok(run_words(&["sign", "--new-key"], &[("", &key)]));
    let f = Fixture {
        trusted: dir.join("builder.key.pub"),
        machine_file: repo("examples/vmc3/machine.toml"),
        key,
        pg,
    };
    let spindle = "k_um_per_k = 3.1";
    let a = signed_model(&dir, &f.key, "a", spindle, spindle);
    let b = signed_model(&dir, &f.key, "b", spindle, "k_um_per_k = 3.3");
    let c = signed_model(&dir, &f.key, "c", spindle, "k_um_per_k = 3.5");
    f.register(&a);
    f.fleet(&["activate", "--machine", MACHINE, "--version", "1"], &[]);
    f.register(&b);
    f.register(&c);
    f.fleet(&["activate", "--machine", MACHINE, "--version", "3"], &[]);
    f.pg.query(
        "UPDATE fleet_models SET model = model || '\\x230a'::bytea, \
         sha256 = encode(sha256(model || '\\x230a'::bytea), 'hex') \
         WHERE machine = 'vmc-3axis' AND version = 3 RETURNING version",
    );
    let model = dir.join("service.toml");
    std::fs::copy(&a, &model).unwrap();
    std::fs::copy(
        a.with_file_name("model.toml.sig"),
        dir.join("service.toml.sig"),
    )
    .unwrap();
    let log_path = dir.join("service.sqlite");
    let log = HandLog::create(&log_path);
    log.start(1_000_000.0);
    log.probe(10.0, 1);
    let once = || {
        f.fleet(
            &["follow", "--machine", MACHINE, "--once"],
            &[
                ("--machine-file", &f.machine_file),
                ("--log", &log_path),
                ("--model", &model),
                ("--trusted-keys", &f.trusted),
            ],
        )
    };
    let out = once();
    assert!(
        out.contains("active version 3 refused") && out.contains("version 2 in shadow"),
        "{out}"
    );
    log.probe(20.0, 2);
    log.probe(30.0, 3);
    let out = once();
    let filed = |f: &Fixture| {
        f.pg.query(
            "SELECT log_row || ' ' || active_version FROM fleet_shadow_probes \
             WHERE version = 2 ORDER BY log_row",
        )
    };
    assert_eq!(
        filed(&f).lines().collect::<Vec<_>>(),
        ["2 1", "3 1"],
        "{out}"
    );
    // Bytes the store does not hold: nothing filed, said.
    let mut text = std::fs::read_to_string(&a).unwrap();
    text.push_str("# changed by hand\n");
    std::fs::write(&model, text).unwrap();
    log.probe(40.0, 4);
    let out = once();
    assert!(out.contains("is no model of the store"), "{out}");
    assert_eq!(filed(&f).lines().count(), 2, "{out}");
    assert_eq!(f.state(3), "active");
}
