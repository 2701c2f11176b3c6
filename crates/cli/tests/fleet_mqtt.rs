//! `truepos run --mqtt`: the log forwarded as Sparkplug B through a real broker (Debian's
//! Mosquitto, installed by scripts/install_system_deps.sh, started here on a free loopback port
//! and stopped at the end) to a host application nobody here wrote (PyPI's paho-mqtt and
//! pysparkplug in .venv, scripts/sparkplug_listen.py). The broker is killed and restarted
//! mid-run, then the service itself is killed (its NDEATH comes as the MQTT will) and
//! `truepos fleet publish` forwards what it left. Checked: every second of the log arrived
//! once with the log's min/mean/max, every event arrived, births, sequence numbers, deaths,
//! the replay marked historical, and the service compensated through the outage. Without
//! Mosquitto or the listener's packages the test fails; it never skips.

use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[path = "support/mosquitto.rs"]
mod mosquitto;
#[path = "support/postgres.rs"]
mod postgres_cluster;
mod support;
use mosquitto::{free_port, start as start_broker, Reaped};
use postgres_cluster::{run_ok, Postgres};
use support::{command as truepos, repo, scratch};

fn start_listener(port: u16, out: &Path) -> Reaped {
    let python = repo(".venv/bin/python");
    assert!(
        python.exists(),
        "{} is missing: run scripts/setup_python.sh (it installs paho-mqtt and pysparkplug)",
        python.display()
    );
    let mut child = Command::new(python)
        .arg(repo("scripts/sparkplug_listen.py"))
        .args([
            &port.to_string(),
            out.to_str().unwrap(),
            "truepos-test-host",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(l);
        }
    });
    let line = rx.recv_timeout(Duration::from_secs(30));
    assert_eq!(
        line.as_deref(),
        Ok("subscribed"),
        "the Sparkplug listener did not subscribe within 30 s; are paho-mqtt and pysparkplug in .venv (scripts/setup_python.sh)?"
    );
    Reaped(child)
}

fn messages(out: &Path) -> Vec<serde_json::Value> {
    // The broker redelivers to the listener's persistent session what it had not recorded as
    // acknowledged before it was killed (MQTT's DUP): the same message, same payload timestamp
    // and seq, which a host drops. (A message truepos sent again has a new timestamp and seq.)
    let mut seen = std::collections::HashSet::new();
    std::fs::read_to_string(out)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|x| {
            let key = format!(
                "{} {} {} {}",
                x["topic"], x["seq"], x["timestamp"], x["bdSeq"]
            );
            seen.insert(key)
        })
        .collect()
}

/// Waits until `done` holds for the messages received, at most `secs`.
fn wait_for(out: &Path, secs: u64, what: &str, done: impl Fn(&[serde_json::Value]) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(secs);
    while !done(&messages(out)) {
        assert!(Instant::now() < deadline, "within {secs} s: {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn count(m: &[serde_json::Value], kind: &str) -> usize {
    m.iter().filter(|x| x["type"] == kind).count()
}

/// The log's seconds as SQL computes them: (second, cycles, per column (min, mean, max)).
type LogSeconds = BTreeMap<i64, (u32, Vec<(String, Option<[f64; 3]>)>)>;

fn log_seconds(db: &Path) -> (LogSeconds, Vec<(f64, String)>) {
    let c = rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .unwrap();
    let cols: Vec<String> = c
        .prepare("SELECT name FROM pragma_table_info('cycles')")
        .unwrap()
        .query_map([], |r| r.get(0))
        .unwrap()
        .map(Result::unwrap)
        .filter(|n: &String| {
            let not_sent = n.starts_with("model_path") || n.ends_with("_target_um");
            n != "time_s" && n != "state" && !not_sent
        })
        .collect();
    let select: Vec<String> = cols
        .iter()
        .map(|n| format!("min(\"{n}\"), sum(\"{n}\") / count(\"{n}\"), max(\"{n}\")"))
        .collect();
    let sql = format!(
        "SELECT CAST(time_s AS INTEGER) AS s, count(*), {} FROM cycles GROUP BY s ORDER BY s",
        select.join(", ")
    );
    let mut out = LogSeconds::new();
    let mut stmt = c.prepare(&sql).unwrap();
    let mut rows = stmt.query([]).unwrap();
    while let Some(r) = rows.next().unwrap() {
        let s: i64 = r.get(0).unwrap();
        let n: u32 = r.get(1).unwrap();
        let stats = cols
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let v = |k: usize| r.get::<_, Option<f64>>(2 + 3 * i + k).unwrap();
                let st = v(0).map(|lo| [lo, v(1).unwrap(), v(2).unwrap()]);
                (name.clone(), st)
            })
            .collect();
        out.insert(s, (n, stats));
    }
    let events = c
        .prepare("SELECT time_s, kind FROM events ORDER BY rowid")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    (out, events)
}

fn metric_name(col: &str, stat: &str) -> String {
    if col.ends_with("_offset_um") {
        format!("Offsets/{col}/{stat}")
    } else {
        format!("Inputs/{col}/{stat}")
    }
}

#[test]
fn the_log_reaches_a_sparkplug_host_through_a_broker_restart_and_a_killed_service() {
    let dir = scratch("fleet-mqtt");
    let port = free_port();
    let url = format!("mqtt://127.0.0.1:{port}");
    let received = dir.join("received.jsonl");
    let db = dir.join("log.sqlite");
    let mut broker = start_broker(&dir, port);
    let _listener = start_listener(port, &received);
    // The subscription must be in the broker's persistence file before the broker is killed.
    std::thread::sleep(Duration::from_millis(2500));

    // 20 × real time: one NDATA per service second, so 20 a second of wall time, and the events.
    let service = truepos()
        .args([
            "run",
            "--source",
            "replay:examples/vmc3/run.csv@20",
            "--period-ms",
            "100",
        ])
        .args(["--duration-s", "3000", "--log"])
        .arg(&db)
        .args(["--mqtt", &url])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("run.err")).unwrap())
        .spawn()
        .unwrap();
    let mut service = Reaped(service);
    wait_for(&received, 60, "an NBIRTH and 40 NDATA", |m| {
        count(m, "NBIRTH") >= 1 && count(m, "NDATA") >= 40
    });

    // The broker dies without a word; the service goes on compensating and logging.
    broker.0.kill().unwrap();
    broker.0.wait().unwrap();
    std::thread::sleep(Duration::from_secs(3));
    let before_restart = count(&messages(&received), "NDATA");
    let _broker2 = start_broker(&dir, port);
    wait_for(
        &received,
        60,
        "a second NBIRTH and the replay after the restart",
        |m| count(m, "NBIRTH") >= 2 && count(m, "NDATA") >= before_restart + 120,
    );
    // The service killed: the broker publishes its will, NDEATH with the session's bdSeq.
    service.0.kill().unwrap();
    service.0.wait().unwrap();
    wait_for(&received, 30, "the will (NDEATH)", |m| {
        count(m, "NDEATH") >= 1
    });

    // What the killed service had not had acknowledged, forwarded from its log.
    let out = truepos()
        .args(["fleet", "publish", "--log"])
        .arg(&db)
        .args(["--mqtt", &url, "--timeout-s", "120"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "fleet publish failed: {err}");
    wait_for(&received, 30, "the clean NDEATH of fleet publish", |m| {
        count(m, "NDEATH") >= 2
    });
    drop(_listener);

    let m = messages(&received);
    let (log, events) = log_seconds(&db);
    check_sessions(&m);
    check_data(&m, &log, &events, &dir);
    check_replay_rate(&m);
    check_kept_compensating(&db);
}

/// The replay after a reconnect (session 2) and `fleet publish`'s (session 3) go at most 100
/// messages a second, the default: their payload timestamps (when each was made) span at least
/// 10 ms per message after the first.
fn check_replay_rate(m: &[serde_json::Value]) {
    let mut session = 0;
    let mut made: HashMap<usize, Vec<i64>> = HashMap::new();
    for x in m {
        match x["type"].as_str() {
            Some("NBIRTH") => session += 1,
            Some("NDATA") if x["metrics"][0][3] == true => made
                .entry(session)
                .or_default()
                .push(x["timestamp"].as_i64().unwrap()),
            _ => {}
        }
    }
    // Session 2 follows a 3 s outage at 20 messages a second: dozens to replay. What session 3
    // replays is what the killed service had not saved as acknowledged, anywhere from none to a
    // second's worth (its cursor is saved once a second): its rate is judged when it has two.
    for (s, least_messages) in [(2, 10), (3, 0)] {
        let none = Vec::new();
        let t = made.get(&s).unwrap_or(&none);
        assert!(
            t.len() >= least_messages,
            "session {s}: only {} historical messages",
            t.len()
        );
        if t.len() < 2 {
            continue;
        }
        let span = t.last().unwrap() - t[0];
        let least = (t.len() as i64 - 1) * 10;
        // 20 ms for the clock's and the scheduler's slack.
        assert!(
            span >= least - 20,
            "session {s}: {} historical messages in {span} ms, faster than 100/s",
            t.len()
        );
    }
}

/// Births, sequence numbers and deaths: each session (an NBIRTH) numbers its NDATA 1, 2, …
/// mod 256 in order, and each NDEATH carries the bdSeq of the birth before it.
fn check_sessions(m: &[serde_json::Value]) {
    let mut bd_seq = None;
    let mut seq = 0u64;
    let mut births = Vec::new();
    for x in m {
        match x["type"].as_str().unwrap() {
            "NBIRTH" => {
                let metrics = x["metrics"].as_array().unwrap();
                assert_eq!(x["seq"], 0);
                let b = metrics.iter().find(|v| v[0] == "bdSeq").unwrap()[1].as_u64();
                assert!(metrics.iter().any(|v| v[0] == "Node Control/Rebirth"));
                assert!(metrics
                    .iter()
                    .any(|v| v[0] == "Properties/Machine" && v[1] == "vmc-3axis"));
                bd_seq = b;
                births.push(b);
                seq = 0;
            }
            "NDATA" => {
                seq = (seq + 1) % 256;
                assert_eq!(
                    x["seq"].as_u64(),
                    Some(seq),
                    "NDATA out of sequence (message of {})",
                    x["timestamp"]
                );
            }
            "NDEATH" => assert_eq!(x["bdSeq"].as_u64(), bd_seq, "a death without its birth"),
            other => panic!("an unexpected message: {other}: {x}"),
        }
    }
    assert_eq!(
        births.len(),
        3,
        "births: the run, its reconnect, fleet publish"
    );
    assert!(
        births.windows(2).all(|w| w[0] != w[1]),
        "bdSeq repeats: {births:?}"
    );
}

fn check_data(m: &[serde_json::Value], log: &LogSeconds, events: &[(f64, String)], dir: &Path) {
    let start_ms = {
        let first = log.keys().next().copied().unwrap();
        // The timestamps of the first second, as sent: the run's start plus its service time.
        let x = m
            .iter()
            .find(|x| x["type"] == "NDATA" && x["metrics"][0][0] == "Cycles")
            .unwrap();
        x["metrics"][0][2].as_i64().unwrap() - first * 1000
    };
    let mut seconds: HashMap<i64, Vec<&serde_json::Value>> = HashMap::new();
    let mut got_events = Vec::new();
    let mut historical = 0;
    let mut sizes = Vec::new();
    for x in m.iter().filter(|x| x["type"] == "NDATA") {
        let metrics = x["metrics"].as_array().unwrap();
        sizes.push(x["size"].as_u64().unwrap());
        if metrics.iter().all(|v| v[3] == true) {
            historical += 1;
        }
        assert!(
            metrics.iter().all(|v| v[3] == metrics[0][3]),
            "a message half historical"
        );
        if metrics[0][0] == "Event/Kind" {
            got_events.push((metrics[0][2].as_i64().unwrap(), metrics[0][1].clone()));
            continue;
        }
        let ts = metrics[0][2].as_i64().unwrap();
        assert_eq!((ts - start_ms) % 1000, 0, "a second not on the second");
        seconds.entry((ts - start_ms) / 1000).or_default().push(x);
    }
    // Every second of the log arrived. QoS 1 is at least once: a message the broker delivered
    // but whose PUBACK the broker's death swallowed is sent again after the reconnect, marked
    // historical; the copy has the same timestamp and values, which is how a host drops it.
    let missing: Vec<_> = log.keys().filter(|s| !seconds.contains_key(s)).collect();
    assert!(
        missing.is_empty(),
        "seconds of the log never received: {missing:?}"
    );
    let extra: Vec<_> = seconds.keys().filter(|s| !log.contains_key(s)).collect();
    assert!(
        extra.is_empty(),
        "seconds received that the log has not: {extra:?}"
    );
    let mut duplicates = 0;
    for (s, copies) in &seconds {
        duplicates += copies.len() - 1;
        // A metric without its historical flag: [name, value, timestamp].
        let values = |c: &serde_json::Value| -> Vec<serde_json::Value> {
            let ms = c["metrics"].as_array().unwrap();
            ms.iter()
                .map(|v| serde_json::json!([v[0], v[1], v[2]]))
                .collect()
        };
        for c in copies {
            assert!(
                values(c) == values(copies[0]),
                "second {s} differs between copies"
            );
        }
        let (n, stats) = &log[s];
        let metrics = copies[0]["metrics"].as_array().unwrap();
        let value = |name: &str| metrics.iter().find(|v| v[0] == name).map(|v| v[1].clone());
        assert_eq!(
            value("Cycles").and_then(|v| v.as_u64()),
            Some(u64::from(*n)),
            "second {s}"
        );
        for (col, st) in stats {
            for (k, stat) in ["min", "mean", "max"].iter().enumerate() {
                let got = value(&metric_name(col, stat))
                    .unwrap_or_else(|| panic!("second {s}: no {}", metric_name(col, stat)));
                match st {
                    None => assert!(got.is_null(), "second {s} {col} {stat}: {got}"),
                    Some(v) => {
                        let g = got.as_f64().unwrap();
                        assert!(
                            (g - v[k]).abs() <= 1e-9 * v[k].abs().max(1.0),
                            "second {s} {col} {stat}: sent {g}, log {}",
                            v[k]
                        );
                    }
                }
            }
        }
    }
    // Copies come from the cursor file saved at most once a second (the kill: ~20 seconds of
    // data at 20×, and one save's lag) and from the window in flight at the broker's death (32).
    assert!(
        duplicates <= 20 + 20 + 32,
        "{duplicates} seconds sent twice"
    );
    got_events.sort_by_key(|e| e.0);
    got_events.dedup();
    assert_eq!(
        got_events.len(),
        events.len(),
        "events: {got_events:?} vs {events:?}"
    );
    assert!(historical > 0, "the replay was not marked historical");
    sizes.sort_unstable();
    std::fs::write(
        dir.join("figures.txt"),
        format!(
            "seconds {} events {} ndata {} historical {historical} duplicates {duplicates} size p50 {} max {}\n",
            log.len(),
            events.len(),
            sizes.len(),
            sizes[sizes.len() / 2],
            sizes[sizes.len() - 1]
        ),
    )
    .unwrap();
    eprintln!(
        "{}",
        std::fs::read_to_string(dir.join("figures.txt")).unwrap()
    );
}

/// The service compensated through the broker's outage: its log has a cycle record at least
/// every 0.2 s of service time from the start to the kill (the log keeps one every 0.1 s,
/// decimated on the cycle's clock, so 0.2 s where one falls between), all but the first
/// blend's active.
fn check_kept_compensating(db: &Path) {
    let c = rusqlite::Connection::open(db).unwrap();
    let rows: Vec<(f64, String)> = c
        .prepare("SELECT time_s, state FROM cycles ORDER BY rowid")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert!(rows.len() > 1000, "only {} cycles logged", rows.len());
    for w in rows.windows(2) {
        assert!(
            w[1].0 - w[0].0 < 0.25,
            "a gap in the cycles: {} → {}",
            w[0].0,
            w[1].0
        );
    }
    let inactive = rows.iter().filter(|r| r.1 != "active").count();
    assert!(inactive < 10, "{inactive} cycles without compensation");
}

/// A birth of node `poison`, then two events the database cannot take as sent, as (message
/// kind, Python bytes literal).
fn poison() -> Vec<(&'static str, String)> {
    use truepos_fleet::sparkplug::{Metric, Payload, Value};
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as u64;
    let metric = |name: &str, value: Value| Metric {
        name: name.into(),
        alias: None,
        timestamp_ms: None,
        value,
        historical: false,
    };
    let event = |t_ms: u64, detail: &str| Payload {
        timestamp_ms: t_ms,
        seq: Some(1),
        metrics: vec![
            metric("Event/Kind", Value::String("sensor-fault".into())),
            metric("Event/Subject", Value::String("x".into())),
            metric("Event/Detail", Value::String(detail.into())),
        ],
    };
    let birth = Payload {
        timestamp_ms: now_ms,
        seq: Some(0),
        metrics: vec![metric("bdSeq", Value::UInt64(0))],
    };
    let py = |p: Payload| p.encode().iter().map(|b| format!("\\x{b:02x}")).collect();
    vec![
        ("NBIRTH", py(birth)),
        ("NDATA", py(event(now_ms, "bad\0detail"))),
        ("NDATA", py(event(1 << 62, "far future"))),
    ]
}

/// Publishes one raw message with paho-mqtt (not with our client: a foreign publisher);
/// `payload` is the inside of a Python bytes literal.
fn publish_foreign(port: u16, topic: &str, payload: &str) {
    run_ok(
        Command::new(repo(".venv/bin/python")).args([
            "-c",
            &format!(
                "import paho.mqtt.publish as p; p.single('{topic}', b'{payload}', qos=1, port={port})"
            ),
        ]),
        "paho publish",
    );
}

#[test]
fn the_fleet_store_holds_each_second_once_through_a_database_outage_and_a_replay() {
    let dir = scratch("fleet-ingest");
    let port = free_port();
    let url = format!("mqtt://127.0.0.1:{port}");
    let db = dir.join("log.sqlite");
    let _broker = start_broker(&dir, port);
    let pg = Postgres::start(&dir);
    let ingest = truepos()
        .args(["fleet", "ingest", "--mqtt", &url, "--db", &pg.url()])
        .args(["--idle-exit-s", "8", "--duration-s", "180"])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("ingest.err")).unwrap())
        .spawn()
        .unwrap();
    let mut ingest = Reaped(ingest);
    // The ingester's subscription exists before anything is published.
    let deadline = Instant::now() + Duration::from_secs(30);
    while pg.query("SELECT count(*) FROM pg_tables WHERE tablename = 'fleet_seconds'") != "1" {
        assert!(Instant::now() < deadline, "no schema within 30 s");
        std::thread::sleep(Duration::from_millis(200));
    }
    std::thread::sleep(Duration::from_millis(500));
    // Bad input on the topics: not a payload, and NDATA of a node nobody knows.
    publish_foreign(
        port,
        "spBv1.0/truepos/NDATA/intruder",
        "not protobuf at all",
    );
    publish_foreign(port, "spBv1.0/other/NDATA/nobody", r"\x08\x01");
    // Valid Sparkplug the database cannot hold as sent: a NUL in an event's text (stored with
    // a replacement character) and a time 2^62 ms after 1970 (skipped). Either used to fail
    // its batch, which the broker sent again and again, stalling every machine behind it.
    for (kind, payload) in poison() {
        publish_foreign(port, &format!("spBv1.0/truepos/{kind}/poison"), &payload);
    }

    let mut service = Reaped(
        truepos()
            .args([
                "run",
                "--source",
                "replay:examples/vmc3/run.csv@20",
                "--period-ms",
                "100",
            ])
            .args(["--duration-s", "240", "--log"])
            .arg(&db)
            .args(["--mqtt", &url])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("run.err")).unwrap())
            .spawn()
            .unwrap(),
    );
    std::thread::sleep(Duration::from_secs(4));
    // PostgreSQL away for three seconds: the ingester stops taking messages, the broker keeps them.
    pg.stop();
    std::thread::sleep(Duration::from_secs(3));
    pg.pg_ctl_start();
    let status = service.0.wait().unwrap();
    assert!(
        status.success(),
        "{}",
        std::fs::read_to_string(dir.join("run.err")).unwrap()
    );
    // The whole log again from a new cursor: every row is there already.
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.to_string_lossy().ends_with(".mqtt-cursor") {
            std::fs::remove_file(p).unwrap();
        }
    }
    let out = truepos()
        .args(["fleet", "publish", "--log"])
        .arg(&db)
        .args(["--mqtt", &url, "--replay-per-s", "1000"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    while ingest.0.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "the ingester did not go idle");
        std::thread::sleep(Duration::from_millis(200));
    }
    let summary = std::fs::read_to_string(dir.join("ingest.err")).unwrap();
    eprintln!("{summary}");

    assert_eq!(
        pg.query("SELECT count(*), min(detail) FROM fleet_events WHERE node_id = 'poison'"),
        "1,bad\u{fffd}detail",
        "{summary}"
    );
    pg.query("DELETE FROM fleet_events WHERE node_id = 'poison'");
    let (log, events) = log_seconds(&db);
    let stored = pg.query("SELECT count(*), sum(cycles) FROM fleet_seconds");
    let cycles: u32 = log.values().map(|v| v.0).sum();
    assert_eq!(stored, format!("{},{cycles}", log.len()), "{summary}");
    assert_eq!(
        pg.query("SELECT count(*) FROM fleet_events"),
        events.len().to_string()
    );
    let rows = pg.query(
        "SELECT (extract(epoch FROM t) * 1000)::bigint, cycles, stats->'Offsets/Z_offset_um'->>1, \
         historical FROM fleet_seconds ORDER BY t",
    );
    let first_ms: i64 = rows
        .lines()
        .next()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let first_s = *log.keys().next().unwrap();
    for line in rows.lines() {
        let f: Vec<&str> = line.split(',').collect();
        let s = first_s + (f[0].parse::<i64>().unwrap() - first_ms) / 1000;
        let (n, stats) = &log[&s];
        assert_eq!(f[1], n.to_string(), "second {s}");
        let z = stats
            .iter()
            .find(|c| c.0 == "Z_offset_um")
            .unwrap()
            .1
            .unwrap()[1];
        let got: f64 = f[2].parse().unwrap();
        assert!(
            (got - z).abs() <= 1e-9 * z.abs().max(1.0),
            "second {s}: {got} vs {z}"
        );
    }
    assert!(summary.contains("already there"), "{summary}");
    let already: u64 = summary
        .split("written, ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!(
        already >= log.len() as u64,
        "the replay was not recognised: {summary}"
    );
    // The two foreign messages and the far-future event.
    assert!(summary.contains("3 skipped"), "{summary}");
    assert!(
        !summary.contains(" 0 database failure"),
        "the outage went unseen: {summary}"
    );
    assert_eq!(
        pg.query(
            "SELECT string_agg(version::text, ',' ORDER BY version) FROM fleet_schema_migrations"
        ),
        "1,2,3,4"
    );
    let partitions =
        pg.query("SELECT count(*) FROM pg_inherits WHERE inhparent = 'fleet_seconds'::regclass");
    assert_ne!(partitions, "0");
    assert_eq!(
        pg.query("SELECT machine FROM fleet_nodes WHERE node_id = 'vmc-3axis'"),
        "vmc-3axis"
    );
    check_kept_compensating(&db);
}
