//! Models as fleet objects and `truepos fleet status`, against a real PostgreSQL 15 on loopback
//! (started and stopped here; missing, the test fails, it never skips): a signed model is
//! registered as a candidate, an unsigned, a tampered and an implausible one are refused with
//! nothing written, a first and a second generation are activated, a rollback returns to the
//! first, a rollback without a parent is refused, `fleet models get` writes a model and its
//! signature that `truepos run --trusted-keys` loads, and `fleet status` shows the machine
//! after a birth, seconds and a fault went into the store through the ingester's own code.

#[path = "support/postgres.rs"]
mod postgres_cluster;
mod support;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use postgres_cluster::Postgres;
use support::{repo, scratch};

/// Runs the binary with a deadline of 60 s: (success, stdout, stderr).
fn truepos(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    support::run_within(args, Duration::from_secs(60))
}

fn os(words: &[&str]) -> Vec<std::ffi::OsString> {
    words.iter().map(|w| (*w).into()).collect()
}

/// The binary with `fleet …` words, `--db` and extra paths.
fn fleet(pg: &Postgres, words: &[&str], paths: &[(&str, &Path)]) -> (bool, String, String) {
    let mut args = os(&["fleet"]);
    args.extend(os(words));
    args.extend(os(&["--db", &pg.url()]));
    for (flag, p) in paths {
        args.push((*flag).into());
        args.push(p.as_os_str().into());
    }
    let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
    truepos(&refs)
}

fn ok(r: (bool, String, String)) -> String {
    assert!(r.0, "{}{}", r.1, r.2);
    r.1
}

fn refused(r: (bool, String, String), words: &[&str]) -> String {
    assert!(!r.0, "not refused: {}", r.1);
    for w in words {
        assert!(r.2.contains(w), "`{w}` not in: {}", r.2);
    }
    r.2
}

fn sign(key: &Path, model: &Path) {
    let r = truepos(&[
        "sign".as_ref(),
        "--key".as_ref(),
        key.as_os_str(),
        model.as_os_str(),
    ]);
    ok(r);
}

/// A copy of the example model in a directory of its own, with a text replaced.
fn model_in(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let d = dir.join(name);
    std::fs::create_dir_all(&d).unwrap();
    let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    let path = d.join("model.toml");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

struct Fixture {
    pg: Postgres,
    dir: PathBuf,
    key: PathBuf,
    trusted: PathBuf,
    machine_file: PathBuf,
}

impl Fixture {
    fn register(&self, model: &Path) -> (bool, String, String) {
        fleet(
            &self.pg,
            &["models", "register", "--machine", "vmc-3axis"],
            &[
                ("--model", model),
                ("--trusted-keys", &self.trusted),
                ("--machine-file", &self.machine_file),
            ],
        )
    }

    fn models(&self) -> usize {
        self.pg
            .query("SELECT count(*) FROM fleet_models")
            .parse()
            .unwrap()
    }

    /// (version, state, parent) of every model, by version.
    fn states(&self) -> String {
        self.pg.query(
            "SELECT version, state, coalesce(parent_version::text, '-') FROM fleet_models \
             WHERE machine = 'vmc-3axis' ORDER BY version",
        )
    }
}

#[test]
fn a_signed_model_is_registered_activated_rolled_back_fetched_and_the_fleet_seen() {
    let started = Instant::now();
    let dir = scratch("fleet-models");
    let pg = Postgres::start(&dir);
    let key = dir.join("builder.key");
    ok(truepos(&[
        "sign".as_ref(),
        "--new-key".as_ref(),
        key.as_os_str(),
    ]));
    let f = Fixture {
        trusted: dir.join("builder.key.pub"),
        machine_file: repo("examples/vmc3/machine.toml"),
        key,
        dir,
        pg,
    };
    // The schema comes with the first command.
    let listed = ok(fleet(&f.pg, &["models", "list", "--json"], &[]));
    assert_eq!(listed.trim(), r#"{"models":[]}"#);

    refusals_write_nothing(&f);
    let (v1, v2) = generations(&f);
    fetched_model_runs(&f, &v1, &v2);
    status_shows_the_machine(&f);
    activations_at_once_run_one_after_the_other(&f);
    assert!(
        started.elapsed() < Duration::from_secs(120),
        "took {:?}",
        started.elapsed()
    );
}

fn refusals_write_nothing(f: &Fixture) {
    let unsigned = model_in(&f.dir, "unsigned", "", "");
    let r = f.register(&unsigned);
    refused(
        r,
        &[&unsigned.display().to_string(), "no signature readable"],
    );

    let tampered = model_in(&f.dir, "tampered", "", "");
    sign(&f.key, &tampered);
    let text = std::fs::read_to_string(&tampered).unwrap();
    std::fs::write(&tampered, format!("{text}#\n")).unwrap();
    let r = f.register(&tampered);
    refused(
        r,
        &[&tampered.display().to_string(), "does not match the file"],
    );

    // Signed, but no machine has a k0 of 10⁶ µm/K: the service's admission refuses it.
    let implausible = model_in(
        &f.dir,
        "implausible",
        "k0_um_per_k = 2.0",
        "k0_um_per_k = 1e6",
    );
    sign(&f.key, &implausible);
    let r = f.register(&implausible);
    refused(r, &[&implausible.display().to_string(), "admission"]);

    assert_eq!(f.models(), 0);
    assert_eq!(f.pg.query("SELECT count(*) FROM fleet_model_changes"), "0");
}

/// Two generations through activate and rollback; returns their files.
fn generations(f: &Fixture) -> (PathBuf, PathBuf) {
    let v1 = model_in(&f.dir, "v1", "", "");
    sign(&f.key, &v1);
    let out = ok(f.register(&v1));
    assert!(out.contains("registered as version 1 (candidate)"), "{out}");
    refused(f.register(&v1), &["registered already, as version 1"]);
    refused(
        fleet(&f.pg, &["rollback", "--machine", "vmc-3axis"], &[]),
        &["has no active model"],
    );
    ok(fleet(
        &f.pg,
        &["activate", "--machine", "vmc-3axis", "--version", "1"],
        &[],
    ));
    refused(
        fleet(&f.pg, &["rollback", "--machine", "vmc-3axis"], &[]),
        &["version 1 has no parent"],
    );
    assert_eq!(f.states(), "1,active,-");

    let v2 = model_in(&f.dir, "v2", "k0_um_per_k = 2.0", "k0_um_per_k = 2.5");
    sign(&f.key, &v2);
    let out = ok(f.register(&v2));
    assert!(out.contains("version 2 (candidate, parent 1)"), "{out}");
    refused(
        fleet(
            &f.pg,
            &["activate", "--machine", "vmc-3axis", "--version", "1"],
            &[],
        ),
        &["version 1 is active"],
    );
    refused(
        fleet(
            &f.pg,
            &["activate", "--machine", "vmc-3axis", "--version", "9"],
            &[],
        ),
        &["no model version 9"],
    );
    ok(fleet(
        &f.pg,
        &[
            "models",
            "shadow",
            "--machine",
            "vmc-3axis",
            "--version",
            "2",
        ],
        &[],
    ));
    let out = ok(fleet(
        &f.pg,
        &[
            "activate",
            "--machine",
            "vmc-3axis",
            "--version",
            "2",
            "--reason",
            "beat v1 on probes",
        ],
        &[],
    ));
    assert!(
        out.contains("version 2 is active, version 1 retired"),
        "{out}"
    );
    assert_eq!(f.states(), "1,retired,-\n2,active,1");

    let out = ok(fleet(&f.pg, &["rollback", "--machine", "vmc-3axis"], &[]));
    assert!(
        out.contains("version 2 retired, version 1 is active again"),
        "{out}"
    );
    assert_eq!(f.states(), "1,active,-\n2,retired,1");
    refused(
        fleet(&f.pg, &["rollback", "--machine", "vmc-3axis"], &[]),
        &["no parent"],
    );
    // The history: every state each version entered, in order, with the reason given.
    let history = f.pg.query(
        "SELECT version, coalesce(from_state, '-'), to_state FROM fleet_model_changes ORDER BY id",
    );
    assert_eq!(
        history,
        "1,-,candidate\n1,candidate,active\n2,-,candidate\n2,candidate,shadow\n\
         1,active,retired\n2,shadow,active\n2,active,retired\n1,retired,active"
    );
    assert_eq!(
        f.pg.query(
            "SELECT count(*) FROM fleet_model_changes WHERE reason LIKE '%beat v1 on probes'"
        ),
        "2"
    );
    let history: serde_json::Value = serde_json::from_str(&ok(fleet(
        &f.pg,
        &["models", "history", "--machine", "vmc-3axis", "--json"],
        &[],
    )))
    .unwrap();
    let changes = history["changes"].as_array().unwrap();
    assert_eq!(changes.len(), 8, "{history}");
    assert_eq!(changes[7]["from"], "retired");
    assert_eq!(changes[7]["to"], "active");
    assert_eq!(changes[7]["reason"], "`truepos fleet rollback`");
    // What the file carries, and its hash.
    let listed: serde_json::Value = serde_json::from_str(&ok(fleet(
        &f.pg,
        &["models", "list", "--json", "--machine", "vmc-3axis"],
        &[],
    )))
    .unwrap();
    let first = &listed["models"][0];
    assert_eq!(first["state"], "active");
    assert!(first["provenance"]["created_by"].is_string(), "{first}");
    let sha = truepos_fleet_store::models::sha256_hex(&std::fs::read(&v1).unwrap());
    assert_eq!(first["sha256"], sha.as_str());
    (v1, v2)
}

fn fetched_model_runs(f: &Fixture, v1: &Path, v2: &Path) {
    let out_dir = f.dir.join("fetched");
    std::fs::create_dir_all(&out_dir).unwrap();
    ok(fleet(
        &f.pg,
        &["models", "get", "--machine", "vmc-3axis"],
        &[("--out", &out_dir)],
    ));
    let got = out_dir.join("model.toml");
    assert_eq!(std::fs::read(&got).unwrap(), std::fs::read(v1).unwrap());
    let r = truepos(&[
        "run".as_ref(),
        "--fast".as_ref(),
        "--duration-s".as_ref(),
        "1".as_ref(),
        "--models".as_ref(),
        got.as_os_str(),
        "--trusted-keys".as_ref(),
        f.trusted.as_os_str(),
    ]);
    assert!(r.0, "{}", r.2);
    // A version by number replaces both files.
    ok(fleet(
        &f.pg,
        &["models", "get", "--machine", "vmc-3axis", "--version", "2"],
        &[("--out", &out_dir)],
    ));
    assert_eq!(std::fs::read(&got).unwrap(), std::fs::read(v2).unwrap());
    let sig = std::fs::read_to_string(out_dir.join("model.toml.sig")).unwrap();
    assert_eq!(
        sig,
        std::fs::read_to_string(v2.with_extension("toml.sig")).unwrap()
    );
    refused(
        fleet(
            &f.pg,
            &[
                "models",
                "get",
                "--machine",
                "vmc-3axis",
                "--state",
                "candidate",
            ],
            &[("--out", &out_dir)],
        ),
        &["has no candidate model"],
    );
    tampered_rows_are_not_written(f, &out_dir);
}

/// The store is not trusted: a model changed in its row is not written out.
fn tampered_rows_are_not_written(f: &Fixture, out_dir: &Path) {
    let got = out_dir.join("model.toml");
    let before = std::fs::read(&got).unwrap();
    let get = |keys: bool| {
        let mut paths = vec![("--out", out_dir)];
        if keys {
            paths.push(("--trusted-keys", f.trusted.as_path()));
        }
        fleet(&f.pg, &["models", "get", "--machine", "vmc-3axis"], &paths)
    };
    ok(get(true));
    let active = std::fs::read(&got).unwrap();
    f.pg.query("UPDATE fleet_models SET model = model || '\\x23'::bytea WHERE state = 'active'");
    refused(get(false), &["do not match their sha256"]);
    f.pg.query(
        "UPDATE fleet_models SET sha256 = encode(sha256(model), 'hex') WHERE state = 'active'",
    );
    refused(get(true), &["refused", "does not match the file"]);
    assert_eq!(std::fs::read(&got).unwrap(), active);
    assert_ne!(before, active);
    // Without a trust list the changed bytes are written, and a service refuses them.
    ok(get(false));
    let r = truepos(&[
        "run".as_ref(),
        "--fast".as_ref(),
        "--duration-s".as_ref(),
        "1".as_ref(),
        "--models".as_ref(),
        got.as_os_str(),
        "--trusted-keys".as_ref(),
        f.trusted.as_os_str(),
    ]);
    assert!(!r.0 && r.2.contains("does not match the file"), "{}", r.2);
}

/// A birth, two seconds (the last all compensating) and a sensor fault, through the ingester.
fn ingest_a_short_session(url: &str) {
    use truepos_fleet::sparkplug::{Metric, Payload, Value};
    use truepos_fleet_store::ingest::Ingester;
    use truepos_fleet_store::postgres::{Client, NoTls};
    let mut db = Client::connect(url, NoTls).unwrap();
    truepos_fleet_store::schema::migrate(&mut db).unwrap();
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64;
    let aliased = |name: &str, alias: u64, value: Value| Metric {
        alias: Some(alias),
        ..Metric::new(name, value)
    };
    let birth = Payload {
        timestamp_ms: now_ms - 3000,
        seq: Some(0),
        metrics: vec![
            Metric::new("bdSeq", Value::UInt64(0)),
            Metric::new("Properties/Machine", Value::String("vmc-3axis".into())),
            aliased("Cycles", 1, Value::Null(7)),
            aliased("Active cycles", 2, Value::Null(7)),
            aliased("Event/Kind", 3, Value::Null(12)),
            aliased("Event/Subject", 4, Value::Null(12)),
            aliased("Event/Detail", 5, Value::Null(12)),
        ],
    };
    let at = |t_ms: u64, alias: u64, value: Value| Metric {
        alias: Some(alias),
        timestamp_ms: Some(t_ms),
        ..Metric::new("", value)
    };
    let second = |t_ms: u64, active: u32| Payload {
        timestamp_ms: t_ms,
        seq: Some(1),
        metrics: vec![
            at(t_ms, 1, Value::UInt32(10)),
            at(t_ms, 2, Value::UInt32(active)),
        ],
    };
    let text = |s: &str| Value::String(s.into());
    let fault = Payload {
        timestamp_ms: now_ms - 1500,
        seq: Some(3),
        metrics: vec![
            at(now_ms - 1500, 3, text("sensor-fault")),
            at(now_ms - 1500, 4, text("t1")),
            at(now_ms - 1500, 5, text("stuck")),
        ],
    };
    let mut ingester = Ingester::default();
    let topic = |kind: &str| format!("spBv1.0/truepos/{kind}/vmc-3axis");
    for (kind, p) in [
        ("NBIRTH", birth),
        ("NDATA", second(now_ms - 2000, 0)),
        ("NDATA", fault),
        ("NDATA", second(now_ms - 1000, 10)),
    ] {
        let outcome = ingester.handle(&mut db, &topic(kind), &p.encode()).unwrap();
        assert!(
            !matches!(outcome, truepos_fleet_store::ingest::Outcome::Skipped(_)),
            "{outcome:?}"
        );
    }
}

fn status_shows_the_machine(f: &Fixture) {
    // Known only by its models so far.
    let s: serde_json::Value =
        serde_json::from_str(&ok(fleet(&f.pg, &["status", "--json"], &[]))).unwrap();
    assert_eq!(s["machines"][0]["online"], serde_json::Value::Null, "{s}");
    assert_eq!(s["machines"][0]["active_model"], 1, "{s}");

    ingest_a_short_session(&f.pg.url());
    let s: serde_json::Value =
        serde_json::from_str(&ok(fleet(&f.pg, &["status", "--json"], &[]))).unwrap();
    let machines = s["machines"].as_array().unwrap();
    assert_eq!(machines.len(), 1, "{s}");
    let m = &machines[0];
    assert_eq!(m["machine"], "vmc-3axis");
    assert_eq!(m["group"], "truepos");
    assert_eq!(m["online"], true);
    assert_eq!(m["compensating"], "yes");
    assert_eq!(m["faults_last_hour"], 1);
    assert_eq!(m["active_model"], 1);
    assert!(m["last_message_utc"].is_string(), "{m}");
    let table = ok(fleet(&f.pg, &["status"], &[]));
    let row = table
        .lines()
        .find(|l| l.starts_with("vmc-3axis"))
        .unwrap_or_else(|| panic!("{table}"));
    for word in ["online", "v1 active", "yes", " 1 "] {
        assert!(row.contains(word), "`{word}` not in {row}");
    }
    // The death after the birth: offline.
    f.pg.query("UPDATE fleet_nodes SET died_at = now()");
    let s: serde_json::Value =
        serde_json::from_str(&ok(fleet(&f.pg, &["status", "--json"], &[]))).unwrap();
    assert_eq!(s["machines"][0]["online"], false, "{s}");
}

/// Two operators activating two candidates at the same moment: one after the other, each
/// replacing the active model of its moment, never two active.
fn activations_at_once_run_one_after_the_other(f: &Fixture) {
    for (name, k0) in [("v3", "2.1"), ("v4", "2.2")] {
        let m = model_in(
            &f.dir,
            name,
            "k0_um_per_k = 2.0",
            &format!("k0_um_per_k = {k0}"),
        );
        sign(&f.key, &m);
        ok(f.register(&m));
    }
    let url = f.pg.url();
    let both: Vec<_> = ["3", "4"]
        .into_iter()
        .map(|v| {
            let url = url.clone();
            std::thread::spawn(move || {
                let args = [
                    "fleet",
                    "activate",
                    "--db",
                    &url,
                    "--machine",
                    "vmc-3axis",
                    "--version",
                    v,
                ];
                let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
                truepos(&refs)
            })
        })
        .collect();
    for t in both {
        ok(t.join().unwrap());
    }
    let states = f.states();
    let active: Vec<&str> = states.lines().filter(|l| l.contains(",active,")).collect();
    assert_eq!(active.len(), 1, "{states}");
    // The later one replaced the earlier, which replaced version 1.
    let (first, second) = if active[0].starts_with("4,") {
        ("3", "4")
    } else {
        ("4", "3")
    };
    assert!(states.contains(&format!("{first},retired,1")), "{states}");
    assert!(
        states.contains(&format!("{second},active,{first}")),
        "{states}"
    );
}
