//! Issue 31's faults beyond a broker restart and a database outage (fleet_mqtt.rs has those):
//! - one service cut off for 10 minutes (its outbound traffic blocked) and then back:
//!   `truepos run --mqtt` reaches Mosquitto through a relay that drops everything for ten
//!   minutes of the service's time (10 s at 60× real time) and then drops the connections the
//!   cut left hanging. The service keeps compensating and logging; when the path is back it
//!   replays what the broker never acknowledged, marked historical, and `truepos fleet ingest`
//!   stores every second of the log exactly once in PostgreSQL 15;
//! - the broker's disk full: Mosquitto's persistence directory is a tmpfs filled to the last
//!   block before the broker starts (in a mount namespace of its own, `unshare`); the fleet
//!   flows through it unchanged.
//!
//! And the fleet in small: fifty services, each replaying the example machine's run at
//! 60× real time under its own Sparkplug node id (`--mqtt-node`: they share one machine file),
//! publish through one broker into the store; each machine's stored seconds equal its own log.

use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

#[path = "support/cutoff.rs"]
mod cutoff;
#[path = "support/mosquitto.rs"]
mod mosquitto;
#[path = "support/postgres.rs"]
mod postgres_cluster;
mod support;

use cutoff::Cutoff;
use mosquitto::Reaped;
use postgres_cluster::Postgres;
use support::{command as truepos, scratch};

/// Per second of service time in the log: how many cycles it logged.
fn log_seconds(db: &Path) -> Vec<(i64, i64)> {
    let c = rusqlite::Connection::open(db).unwrap();
    let mut st = c
        .prepare("SELECT CAST(time_s AS INTEGER) AS s, count(*) FROM cycles GROUP BY s ORDER BY s")
        .unwrap();
    let rows = st.query_map([], |r| Ok((r.get(0)?, r.get(1)?))).unwrap();
    rows.map(Result::unwrap).collect()
}

/// The service compensated throughout its `seconds`: a cycle logged at least every 0.25 s of
/// its time, every one active after the first blend.
fn check_kept_compensating(db: &Path, seconds: f64) {
    let c = rusqlite::Connection::open(db).unwrap();
    let rows: Vec<(f64, String)> = c
        .prepare("SELECT time_s, state FROM cycles ORDER BY rowid")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert!(
        rows.len() as f64 > 5.0 * seconds,
        "only {} cycles logged in {seconds} s",
        rows.len()
    );
    for w in rows.windows(2) {
        assert!(w[1].0 - w[0].0 < 0.25, "a gap: {} → {}", w[0].0, w[1].0);
    }
    let inactive = rows.iter().filter(|r| r.1 != "active").count();
    assert!(inactive < 10, "{inactive} cycles without compensation");
}

fn wait_until(secs: u64, what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(secs);
    while !done() {
        assert!(Instant::now() < deadline, "{what} within {secs} s");
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn a_machine_cut_off_for_ten_minutes_loses_nothing_and_duplicates_nothing() {
    let dir = scratch("fleet-cutoff");
    let port = mosquitto::free_port();
    let _broker = mosquitto::start(&dir, port);
    let path = Cutoff::start(port);
    let pg = Postgres::start(&dir);
    let mut ingest = start_ingest(&dir, &pg, port);
    // 1500 s of the example run at 60×: 25 s, of which 10 s (600 s of its time) cut off.
    let db = dir.join("log.sqlite");
    let mut service = start_service(&dir, &db, path.port, 1500);
    std::thread::sleep(Duration::from_secs(5));
    let stored = || -> i64 {
        let n = pg.query("SELECT count(*) FROM fleet_seconds");
        n.parse().unwrap()
    };
    let before_cut = stored();
    path.cut();
    std::thread::sleep(Duration::from_secs(10));
    let during_cut = stored() - before_cut;
    path.restore();
    let (run_err, summary) = finish(&dir, &mut service, &mut ingest);

    // The cut was real: the store stopped growing while it lasted (but for what was in
    // flight when it began).
    assert!(before_cut > 100, "{before_cut} seconds before the cut");
    assert!(during_cut < 60, "{during_cut} seconds through a cut path");
    assert!(
        !run_err.contains("not caught up"),
        "the service did not catch up after the cut: {run_err}"
    );
    // Every second of the log once; the cut's seconds came historical.
    let log = check_stored_as_logged(&pg, &db, &summary);
    let historical: i64 = pg
        .query("SELECT count(*) FROM fleet_seconds WHERE historical")
        .parse()
        .unwrap();
    assert!(
        historical >= 500,
        "only {historical} seconds replayed historical after a 600 s cut"
    );
    eprintln!(
        "cut-off: {before_cut} seconds stored before the cut, {during_cut} during it, {} in all, \
         {historical} of them historical",
        log.len()
    );
    check_kept_compensating(&db, 1500.0);
}

#[test]
fn a_broker_whose_disk_is_full_still_carries_every_second() {
    let dir = scratch("fleet-disk-full");
    let port = mosquitto::free_port();
    let broker = mosquitto::start_on_full_disk(&dir, port);
    let full = Path::new("/proc")
        .join(broker.0.id().to_string())
        .join("root")
        .join(dir.join("full").strip_prefix("/").unwrap());
    let pg = Postgres::start(&dir);
    let mut ingest = start_ingest(&dir, &pg, port);
    let db = dir.join("log.sqlite");
    let mut service = start_service(&dir, &db, port, 600);
    let (run_err, summary) = finish(&dir, &mut service, &mut ingest);
    // The broker's disk was full all along: not a block more fits.
    let more = std::fs::write(full.join("one-more-block"), [0u8; 4096]);
    assert_eq!(
        more.as_ref().map_err(std::io::Error::kind),
        Err(std::io::ErrorKind::StorageFull),
        "{more:?} in {}",
        full.display()
    );
    assert!(!run_err.contains("not caught up"), "{run_err}");
    let log = check_stored_as_logged(&pg, &db, &summary);
    assert!(log.len() >= 600, "{} seconds logged", log.len());
    eprintln!("disk full: {} seconds stored as logged", log.len());
    check_kept_compensating(&db, 600.0);
}

/// Waits for the service to finish and the ingester to go idle: (the run's stderr, the
/// ingester's summary).
fn finish(dir: &Path, service: &mut Reaped, ingest: &mut Reaped) -> (String, String) {
    let status = service.0.wait().unwrap();
    let run_err = std::fs::read_to_string(dir.join("run.err")).unwrap();
    assert!(status.success(), "{run_err}");
    wait_until(60, "the ingester going idle", || {
        ingest.0.try_wait().unwrap().is_some()
    });
    let summary = std::fs::read_to_string(dir.join("ingest.err")).unwrap();
    let broker = std::fs::read_to_string(dir.join("mosquitto.log")).unwrap_or_default();
    eprintln!("run: {run_err}\ningest: {summary}\nbroker: {broker}");
    (run_err, summary)
}

/// The store holds every second of the log once, with its cycle count, and every event; the
/// log's seconds are returned.
fn check_stored_as_logged(pg: &Postgres, db: &Path, summary: &str) -> Vec<(i64, i64)> {
    let log = check_seconds_of(pg, db, "vmc-3axis", summary);
    let c = rusqlite::Connection::open(db).unwrap();
    let events: i64 = c
        .query_row("SELECT count(*) FROM events", [], |r| r.get(0))
        .unwrap();
    assert_eq!(
        pg.query("SELECT count(*) FROM fleet_events"),
        events.to_string()
    );
    log
}

/// The store holds every second of `node`'s log once, with its cycle count.
fn check_seconds_of(pg: &Postgres, db: &Path, node: &str, summary: &str) -> Vec<(i64, i64)> {
    let log = log_seconds(db);
    let stored = pg.query(&format!(
        "SELECT string_agg((extract(epoch FROM t - first))::bigint::text || ':' || cycles, ',' \
         ORDER BY t) FROM fleet_seconds, \
         (SELECT min(t) AS first FROM fleet_seconds WHERE node_id = '{node}') f \
         WHERE node_id = '{node}'"
    ));
    let first = log[0].0;
    let want: Vec<String> = log
        .iter()
        .map(|(s, n)| format!("{}:{n}", s - first))
        .collect();
    assert_eq!(stored, want.join(","), "{node}: {summary}");
    log
}

/// The ingester on `broker`, started once the store's schema exists.
fn start_ingest(dir: &Path, pg: &Postgres, broker: u16) -> Reaped {
    let url = format!("mqtt://127.0.0.1:{broker}");
    let ingest = Reaped(
        truepos()
            .args(["fleet", "ingest", "--mqtt", &url, "--db", &pg.url()])
            .args(["--idle-exit-s", "8", "--duration-s", "240"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("ingest.err")).unwrap())
            .spawn()
            .unwrap(),
    );
    wait_until(30, "the store's schema", || {
        pg.query("SELECT count(*) FROM pg_tables WHERE tablename = 'fleet_seconds'") == "1"
    });
    std::thread::sleep(Duration::from_millis(500));
    ingest
}

/// `truepos run` replaying the example at 60× for `seconds` of its time, logging to `db` and
/// publishing to the broker on `port`.
fn start_service(dir: &Path, db: &Path, port: u16, seconds: u32) -> Reaped {
    let url = format!("mqtt://127.0.0.1:{port}");
    Reaped(
        truepos()
            .args(["run", "--source", "replay:examples/vmc3/run.csv@60"])
            .args(["--period-ms", "100", "--duration-s", &seconds.to_string()])
            .arg("--log")
            .arg(db)
            .args(["--mqtt", &url])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("run.err")).unwrap())
            .spawn()
            .unwrap(),
    )
}

#[test]
fn fifty_machines_each_stored_as_its_own_log() {
    const MACHINES: usize = 50;
    let dir = scratch("fleet-fifty");
    let port = mosquitto::free_port();
    let _broker = mosquitto::start(&dir, port);
    let pg = Postgres::start(&dir);
    let mut ingest = start_ingest(&dir, &pg, port);
    let url = format!("mqtt://127.0.0.1:{port}");
    let started = Instant::now();
    let mut services: Vec<Reaped> = (0..MACHINES)
        .map(|i| {
            Reaped(
                truepos()
                    .args(["run", "--source", "replay:examples/vmc3/run.csv@60"])
                    .args(["--period-ms", "1000"])
                    .args(["--duration-s", "600", "--log"])
                    .arg(dir.join(format!("m{i:02}.sqlite")))
                    .args(["--mqtt", &url, "--mqtt-node", &format!("machine-{i:02}")])
                    .stdout(Stdio::null())
                    .stderr(std::fs::File::create(dir.join(format!("m{i:02}.err"))).unwrap())
                    .spawn()
                    .unwrap(),
            )
        })
        .collect();
    for (i, s) in services.iter_mut().enumerate() {
        let status = s.0.wait().unwrap();
        let err = std::fs::read_to_string(dir.join(format!("m{i:02}.err"))).unwrap();
        assert!(status.success(), "machine {i}: {err}");
        assert!(!err.contains("not caught up"), "machine {i}: {err}");
    }
    let ran = started.elapsed();
    wait_until(90, "the ingester going idle", || {
        ingest.0.try_wait().unwrap().is_some()
    });
    let summary = std::fs::read_to_string(dir.join("ingest.err")).unwrap();
    let mut seconds = 0;
    for i in 0..MACHINES {
        let db = dir.join(format!("m{i:02}.sqlite"));
        seconds += check_seconds_of(&pg, &db, &format!("machine-{i:02}"), &summary).len();
    }
    // The offsets the model applied reached the store as the logs hold them.
    let z: f64 = pg
        .query(
            "SELECT min((stats->'Offsets/Z_offset_um'->>0)::float8) FROM fleet_seconds \
             WHERE node_id = 'machine-07'",
        )
        .parse()
        .unwrap();
    let c = rusqlite::Connection::open(dir.join("m07.sqlite")).unwrap();
    let logged: f64 = c
        .query_row("SELECT min(Z_offset_um) FROM cycles", [], |r| r.get(0))
        .unwrap();
    assert!(
        logged < -1.0 && (z - logged).abs() < 1e-9,
        "{z} vs {logged}"
    );
    assert_eq!(
        pg.query("SELECT count(DISTINCT node_id) FROM fleet_nodes WHERE node_id LIKE 'machine-%'"),
        MACHINES.to_string()
    );
    eprintln!(
        "fifty machines: {seconds} seconds stored as logged, the services ran {:.1} s; {summary}",
        ran.as_secs_f64()
    );
}
