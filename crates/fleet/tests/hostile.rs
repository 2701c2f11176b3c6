//! Bad input never crashes the publisher: a "broker" that answers with bytes that are no MQTT,
//! one that refuses the connection, a log that is not a truepos log or holds text where numbers
//! belong, a cursor file that is not one. Each is refused with a sentence or survived by
//! reconnecting, and `stop` always returns. The brokers here are plain TCP listeners in the
//! test; the real broker is Mosquitto in crates/cli/tests/fleet_mqtt.rs.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use truepos_fleet::store::LogReader;
use truepos_fleet::{BrokerUrl, Config, Publisher};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("truepos-fleet-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A log as the service lays it out: meta, events, cycles (a hand-made one: the runtime's
/// logger is tested in its own crate).
fn log(dir: &Path, rows: &[(f64, &str, &str)]) -> PathBuf {
    let p = dir.join("log.sqlite");
    let c = rusqlite::Connection::open(&p).unwrap();
    c.execute_batch(
        "PRAGMA journal_mode=WAL;
         CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
         CREATE TABLE events (time_s REAL NOT NULL, kind TEXT NOT NULL, subject TEXT NOT NULL, detail TEXT NOT NULL);
         CREATE TABLE cycles (time_s REAL, state TEXT, model_path1 REAL, t1 REAL, X_offset_um REAL);
         INSERT INTO meta VALUES ('service', '{\"machine\":\"m/1\",\"started_unix_s\":1000,\"models\":[\"a\"]}');
         INSERT INTO events VALUES (0.5, 'model-selected', 'path 1', 'a');",
    )
    .unwrap();
    for (t, state, v) in rows {
        c.execute(
            "INSERT INTO cycles VALUES (?1, ?2, 1, ?3, 2.0)",
            rusqlite::params![t, state, v],
        )
        .unwrap();
    }
    p
}

/// A listener that answers every connection with `answer` and counts connections.
fn fake_broker(answer: &'static [u8]) -> (BrokerUrl, Arc<AtomicUsize>, Arc<AtomicBool>) {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port();
    l.set_nonblocking(true).unwrap();
    let count = Arc::new(AtomicUsize::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let (c, s) = (Arc::clone(&count), Arc::clone(&stop));
    std::thread::spawn(move || {
        while !s.load(Ordering::Relaxed) {
            match l.accept() {
                Ok((mut conn, _)) => {
                    c.fetch_add(1, Ordering::Relaxed);
                    let _ = conn.set_read_timeout(Some(Duration::from_millis(200)));
                    let mut buf = [0u8; 4096];
                    let _ = conn.read(&mut buf);
                    let _ = conn.write_all(answer);
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    });
    (
        BrokerUrl::parse(&format!("mqtt://127.0.0.1:{port}")).unwrap(),
        count,
        stop,
    )
}

#[test]
fn a_broker_that_talks_nonsense_is_left_and_tried_again() {
    let dir = scratch("nonsense");
    let db = log(&dir, &[(0.0, "active", "20"), (1.0, "active", "21")]);
    for answer in [
        &b"HTTP/1.1 400 Bad Request\r\n\r\n"[..],
        &[0x20, 2, 0, 5][..], // CONNACK: not authorised
        &[0x20, 2, 0, 0, 0x30, 0xff, 0xff, 0xff, 0xff][..], // accepted, then a broken length
        &[0x20, 2, 0, 0, 0x90, 3, 0, 1, 0][..], // accepted, then a SUBACK nobody asked for
        &[][..],              // closes at once
    ] {
        let (url, count, stop) = fake_broker(answer);
        let p = Publisher::start(Config::new(url, db.clone())).unwrap();
        std::thread::sleep(Duration::from_millis(1200));
        let s = p.stop(Duration::from_millis(300));
        stop.store(true, Ordering::Relaxed);
        assert!(
            count.load(Ordering::Relaxed) >= 2,
            "{answer:02x?}: not tried again"
        );
        assert!(!s.caught_up);
        assert_eq!(s.acknowledged, 0);
        assert!(s.last_error.is_some(), "{answer:02x?}: no error said");
    }
}

#[test]
fn no_broker_at_all_leaves_everything_in_the_log() {
    let dir = scratch("nobroker");
    let db = log(&dir, &[(0.0, "active", "20"), (1.0, "active", "21")]);
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = BrokerUrl::parse(&format!("mqtt://127.0.0.1:{port}")).unwrap();
    let p = Publisher::start(Config::new(url, db)).unwrap();
    let s = p.stop(Duration::from_millis(500));
    assert!(!s.caught_up);
    assert_eq!(s.cursor, truepos_fleet::Rows::default());
}

#[test]
fn text_where_numbers_belong_counts_as_no_value() {
    let dir = scratch("text");
    let db = log(
        &dir,
        &[
            (0.0, "active", "20"),
            (0.5, "hold", "not a number"),
            (0.7, "active", "22"),
            (1.2, "active", "x"),
            (2.0, "active", "23"),
        ],
    );
    let r = LogReader::open(&db).unwrap();
    assert_eq!(r.columns(), ["t1", "X_offset_um"]);
    let s = r.seconds(0, true, 100).unwrap();
    assert_eq!(s.len(), 3);
    assert_eq!((s[0].cycles, s[0].active), (3, 2));
    assert_eq!(s[0].stats[0], Some((20.0, 21.0, 22.0)));
    assert_eq!(s[1].stats[0], None, "a second of text only has no value");
    assert_eq!(s[1].stats[1], Some((2.0, 2.0, 2.0)));
    // Not final: the last second may still grow, so it waits.
    assert_eq!(r.seconds(0, false, 100).unwrap().len(), 2);
    // A limit reads no further than it needs.
    let one = r.seconds(0, true, 1).unwrap();
    assert_eq!((one.len(), one[0].last_row), (1, s[0].last_row));
    assert_eq!(r.seconds(one[0].last_row, true, 1).unwrap(), &s[1..2]);
    assert_eq!(r.seconds(s[1].last_row, true, 100).unwrap().len(), 1);
}

#[test]
fn a_run_appended_to_the_log_is_seen_at_any_read_boundary() {
    let dir = scratch("runs");
    // Two runs in one log: the second restarts its service time at 0.
    let db = log(
        &dir,
        &[
            (0.0, "active", "1"),
            (1.0, "active", "2"),
            (2.0, "active", "3"),
            (0.0, "active", "4"),
            (1.0, "active", "5"),
        ],
    );
    let r = LogReader::open(&db).unwrap();
    let all = r.seconds(0, true, 100).unwrap();
    let new: Vec<bool> = all.iter().map(|s| s.new_run).collect();
    assert_eq!(new, [false, false, false, true, false]);
    // Read one at a time, the boundary falls between two reads and is still seen.
    let mut cursor = 0;
    let mut one_by_one = Vec::new();
    while let Some(s) = r.seconds(cursor, true, 1).unwrap().pop() {
        cursor = s.last_row;
        one_by_one.push(s.new_run);
    }
    assert_eq!(one_by_one, new);
}

#[test]
fn what_is_not_a_truepos_log_or_cursor_is_refused_by_name() {
    let dir = scratch("notalog");
    let url = BrokerUrl::parse("mqtt://127.0.0.1:9").unwrap();
    let junk = dir.join("junk.sqlite");
    std::fs::write(&junk, b"this is not SQLite at all, not even close").unwrap();
    let e = Publisher::start(Config::new(url.clone(), junk))
        .err()
        .unwrap();
    assert!(e.contains("junk.sqlite"), "{e}");
    let e = Publisher::start(Config::new(url.clone(), dir.join("absent.sqlite")))
        .err()
        .unwrap();
    assert!(e.contains("no such log"), "{e}");
    let empty = dir.join("empty.sqlite");
    rusqlite::Connection::open(&empty)
        .unwrap()
        .execute_batch("CREATE TABLE t (x)")
        .unwrap();
    let e = Publisher::start(Config::new(url.clone(), empty))
        .err()
        .unwrap();
    assert!(e.contains("not a truepos log"), "{e}");
    let db = log(&dir, &[(0.0, "active", "20")]);
    let cursor = truepos_fleet::cursor::path_for(&db, &url);
    std::fs::write(&cursor, b"{\"broker\": 3").unwrap();
    let e = Publisher::start(Config::new(url, db)).err().unwrap();
    assert!(e.contains("not a cursor file"), "{e}");
}
