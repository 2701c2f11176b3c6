//! Issue 31's fault "one service cut off for 10 minutes (its outbound traffic blocked) and then
//! back": `truepos run --mqtt` reaches Mosquitto through a relay that drops everything for ten
//! minutes of the service's time (10 s at 60× real time) and then drops the connections the
//! cut left hanging. The service keeps compensating and logging; when the path is back it
//! replays what the broker never acknowledged, marked historical, and `truepos fleet ingest`
//! stores every second of the log exactly once in PostgreSQL 15.

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

/// The service compensated throughout: a cycle logged at least every 0.25 s of its time, every
/// one active after the first blend.
fn check_kept_compensating(db: &Path) {
    let c = rusqlite::Connection::open(db).unwrap();
    let rows: Vec<(f64, String)> = c
        .prepare("SELECT time_s, state FROM cycles ORDER BY rowid")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert!(rows.len() > 5000, "only {} cycles logged", rows.len());
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
    let direct = format!("mqtt://127.0.0.1:{port}");
    let mut ingest = Reaped(
        truepos()
            .args(["fleet", "ingest", "--mqtt", &direct, "--db", &pg.url()])
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

    // 1500 s of the example run at 60×: 25 s, of which 10 s (600 s of its time) cut off.
    let db = dir.join("log.sqlite");
    let relayed = format!("mqtt://127.0.0.1:{}", path.port);
    let mut service = Reaped(
        truepos()
            .args(["run", "--source", "replay:examples/vmc3/run.csv@60"])
            .args(["--period-ms", "100", "--duration-s", "1500", "--log"])
            .arg(&db)
            .args(["--mqtt", &relayed])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join("run.err")).unwrap())
            .spawn()
            .unwrap(),
    );
    std::thread::sleep(Duration::from_secs(5));
    let before_cut: i64 = pg
        .query("SELECT count(*) FROM fleet_seconds")
        .parse()
        .unwrap();
    path.cut();
    std::thread::sleep(Duration::from_secs(10));
    let during_cut: i64 = pg
        .query("SELECT count(*) FROM fleet_seconds")
        .parse()
        .unwrap();
    path.restore();
    let status = service.0.wait().unwrap();
    let run_err = std::fs::read_to_string(dir.join("run.err")).unwrap();
    assert!(status.success(), "{run_err}");
    wait_until(60, "the ingester going idle", || {
        ingest.0.try_wait().unwrap().is_some()
    });
    let summary = std::fs::read_to_string(dir.join("ingest.err")).unwrap();
    eprintln!("run: {run_err}\ningest: {summary}");

    // The cut was real: the store stopped growing while it lasted (but for what was in
    // flight when it began).
    assert!(before_cut > 100, "{before_cut} seconds before the cut");
    assert!(
        during_cut - before_cut < 60,
        "{} seconds arrived through a cut path",
        during_cut - before_cut
    );
    assert!(
        !run_err.contains("not caught up"),
        "the service did not catch up after the cut: {run_err}"
    );
    // Every second of the log once, with its cycle count; the cut's seconds came historical.
    let log = log_seconds(&db);
    let stored = pg.query(
        "SELECT string_agg((extract(epoch FROM t - first))::bigint::text || ':' || cycles, ',' \
         ORDER BY t) FROM fleet_seconds, (SELECT min(t) AS first FROM fleet_seconds) f",
    );
    let first = log[0].0;
    let want: Vec<String> = log
        .iter()
        .map(|(s, n)| format!("{}:{n}", s - first))
        .collect();
    assert_eq!(stored, want.join(","), "{summary}");
    let historical: i64 = pg
        .query("SELECT count(*) FROM fleet_seconds WHERE historical")
        .parse()
        .unwrap();
    assert!(
        historical >= 500,
        "only {historical} seconds replayed historical after a 600 s cut"
    );
    eprintln!(
        "cut-off: {before_cut} seconds stored before the cut, {} during it, {} in all, \
         {historical} of them historical",
        during_cut - before_cut,
        log.len()
    );
    let c = rusqlite::Connection::open(&db).unwrap();
    let events: i64 = c
        .query_row("SELECT count(*) FROM events", [], |r| r.get(0))
        .unwrap();
    assert_eq!(
        pg.query("SELECT count(*) FROM fleet_events"),
        events.to_string()
    );
    check_kept_compensating(&db);
}
