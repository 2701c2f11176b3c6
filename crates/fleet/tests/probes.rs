//! Probe events of the log as units of forwarding, without a broker: only accepted ones, in
//! time order among the seconds and events, after the cursor; their NDATA carries every probe
//! column under the alias the birth declared; a log without a probe table has none.

use std::path::{Path, PathBuf};

use truepos_fleet::publisher::{birth_payload_with_probes, unit_payload};
use truepos_fleet::sparkplug::Value;
use truepos_fleet::store::{LogReader, Rows, Unit};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("truepos-fleet-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A log as the service writes it: cycles every 0.5 s for 4 s, one event at 1.2 s, probes at
/// 0.7 s (accepted), 1.2 s (rejected), 2.6 s (accepted, Z not measured).
fn log(dir: &Path, with_probes: bool) -> PathBuf {
    let path = dir.join("log.sqlite");
    let c = rusqlite::Connection::open(&path).unwrap();
    c.execute_batch(
        "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
         CREATE TABLE events (time_s REAL NOT NULL, kind TEXT NOT NULL, subject TEXT NOT NULL, detail TEXT NOT NULL);
         CREATE TABLE cycles (time_s REAL, state TEXT, model_path1 REAL, t1 REAL, X_offset_um REAL);
         INSERT INTO meta VALUES ('service', '{\"machine\":\"m\",\"started_unix_s\":1764400000.0,\"models\":[\"a.toml\"]}');
         INSERT INTO events VALUES (1.2, 'sensor-fault', 't1', 'stuck');",
    )
    .unwrap();
    for i in 0..8 {
        c.execute(
            "INSERT INTO cycles VALUES (?1, 'active', 0, 20.0, -1.5)",
            [f64::from(i) * 0.5],
        )
        .unwrap();
    }
    if with_probes {
        c.execute_batch(
            "CREATE TABLE probes (time_s REAL, status TEXT, reason TEXT, state TEXT, model_path1 REAL,
                 probe_z_mm REAL, probe_dz_um REAL, predicted_dz_um REAL, Z_mm REAL, t1 REAL);
             INSERT INTO probes VALUES (0.7, 'accepted', '', 'active', 0, -50.0, -3.25, -3.0, -50.0, 20.0);
             INSERT INTO probes VALUES (1.2, 'rejected', 'beyond travel', 'active', 0, 9999.0, -1.0, -3.0, -50.0, 20.0);
             INSERT INTO probes VALUES (2.6, 'accepted', '', 'holding', NULL, -40.0, NULL, -2.0, -40.0, 20.1);",
        )
        .unwrap();
    }
    path
}

fn kinds(units: &[Unit]) -> Vec<String> {
    units
        .iter()
        .map(|u| match u {
            Unit::Second(s) => format!("s{}", s.second),
            Unit::Event(e) => format!("e{}", e.time_s),
            Unit::Probe(p) => format!("p{}", p.time_s),
        })
        .collect()
}

#[test]
fn accepted_probes_go_in_time_order_after_the_cursor() {
    let dir = scratch("probes-order");
    let r = LogReader::open(&log(&dir, true)).unwrap();
    assert_eq!(
        r.probe_columns(),
        ["probe_z_mm", "probe_dz_um", "predicted_dz_um", "Z_mm", "t1"]
    );
    let all = r.units(Rows::default(), 100, true).unwrap();
    // The rejected probe at 1.2 s is not forwarded; the event at 1.2 s is.
    assert_eq!(
        kinds(&all),
        ["p0.7", "s0", "e1.2", "s1", "p2.6", "s2", "s3"]
    );
    let Unit::Probe(p) = &all[0] else { panic!() };
    assert_eq!(p.state, "active");
    assert_eq!(
        p.values,
        [
            Some(-50.0),
            Some(-3.25),
            Some(-3.0),
            Some(-50.0),
            Some(20.0)
        ]
    );
    let Unit::Probe(q) = &all[4] else { panic!() };
    assert_eq!(q.values[1], None, "Z not measured");
    // The cursor after each unit; reading on from it gives the rest.
    let mut cursor = Rows::default();
    for u in &all[..3] {
        cursor = u.after(cursor);
    }
    assert_eq!(cursor.probes, 1);
    let rest = r.units(cursor, 100, true).unwrap();
    assert_eq!(kinds(&rest), ["s1", "p2.6", "s2", "s3"]);
    assert_eq!(r.last_rows().unwrap().probes, 3);
}

#[test]
fn a_probe_ndata_names_its_columns_through_the_birth() {
    let dir = scratch("probes-ndata");
    let r = LogReader::open(&log(&dir, true)).unwrap();
    let birth = birth_payload_with_probes(1, "m", "a.toml", r.columns(), r.probe_columns(), 0);
    let units = r.units(Rows::default(), 100, true).unwrap();
    let data = unit_payload(&units[0], r.columns().len(), 1_764_400_000_700, 1, true, 5);
    let name = |alias: u64| {
        birth
            .metrics
            .iter()
            .find(|m| m.alias == Some(alias))
            .map(|m| m.name.clone())
            .unwrap()
    };
    let named: Vec<(String, Value)> = data
        .metrics
        .iter()
        .map(|m| (name(m.alias.unwrap()), m.value.clone()))
        .collect();
    assert_eq!(
        named[0],
        ("Probe/state".into(), Value::String("active".into()))
    );
    assert_eq!(named[2], ("Probe/probe_dz_um".into(), Value::Double(-3.25)));
    assert_eq!(named.len(), 1 + r.probe_columns().len());
    assert!(data
        .metrics
        .iter()
        .all(|m| m.historical && m.timestamp_ms == Some(1_764_400_000_700)));
}

#[test]
fn a_log_without_a_probe_table_has_no_probes() {
    let dir = scratch("probes-none");
    let r = LogReader::open(&log(&dir, false)).unwrap();
    assert!(r.probe_columns().is_empty());
    let all = r.units(Rows::default(), 100, true).unwrap();
    assert!(all.iter().all(|u| !matches!(u, Unit::Probe(_))));
    assert_eq!(r.last_rows().unwrap().probes, 0);
    // Its birth is the one without probe metrics.
    let birth = birth_payload_with_probes(1, "m", "a.toml", r.columns(), r.probe_columns(), 0);
    assert!(birth.metrics.iter().all(|m| !m.name.starts_with("Probe/")));
}
