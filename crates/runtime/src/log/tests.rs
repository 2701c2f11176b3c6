//! The logger's own tests: its layout, its buffer while failing, an older log appended to.

use super::*;
use crate::output::CompensationState;
use truepos_model::MAX_AXES;

/// A one-axis machine without sensors: the log's layout is all this test needs of it.
fn machine() -> MachineConfig {
    use crate::config::{AxisConfig, DEFAULT_MAX_OFFSET_UM, DEFAULT_MAX_RATE_UM_PER_S};
    use truepos_model::{Axis, AxisKind, Carriage, Machine};
    MachineConfig {
        machine: Machine {
            name: "one-axis".into(),
            axes: vec![Axis {
                name: "X".into(),
                kind: AxisKind::Linear,
                travel_min: 0.0,
                travel_max: 500.0,
                carried_by: None,
                carriage: Carriage::Cantilever,
            }],
            temperatures: vec![],
            differences: vec![],
            operating: vec![],
        },
        description: String::new(),
        operating_units: vec![],
        axes: vec![AxisConfig {
            max_offset_um: DEFAULT_MAX_OFFSET_UM,
            max_rate_um_per_s: DEFAULT_MAX_RATE_UM_PER_S,
            path: 1,
            number: 1,
        }],
        sensor_checks: vec![],
    }
}

fn record(time_s: f64) -> CycleRecord {
    CycleRecord {
        time_s,
        state: CompensationState::Active,
        positions: [0.0; MAX_AXES],
        offsets_um: [0.0; MAX_AXES],
        targets_um: [0.0; MAX_AXES],
        temperatures_c: [20.0; MAX_LOG_TEMPERATURES],
        operating: [0.0; MAX_LOG_OPERATING],
        model_per_path: [0; MAX_PATHS],
    }
}

/// Each cycle row carries the axes' targets beside their offsets; a log written before
/// targets were logged is appended to with the columns added, its old rows without one.
#[test]
fn targets_are_logged_and_an_older_log_gets_their_column() {
    let dir = std::env::temp_dir().join(format!("truepos-logtarget-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let db = dir.join("log.sqlite");
    let machine = machine();
    {
        // The layout of the earlier version: no target column.
        let c = Connection::open(&db).unwrap();
        c.execute_batch(
            "CREATE TABLE cycles (\"time_s\" REAL, \"state\" TEXT, \"model_path1\" REAL, \
             \"X_mm\" REAL, \"X_offset_um\" REAL); \
             INSERT INTO cycles VALUES (0.5, 'active', 0, 10.0, 1.5); \
             CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL); \
             INSERT INTO meta VALUES ('service', '{\"machine\": \"one-axis\"}');",
        )
        .unwrap();
    }
    let setup = LogSetup {
        path: &db,
        machine: &machine,
        models: vec!["m".into()],
        sources: vec![],
        sinks: vec![],
        paths: 1,
        commit_every: Duration::from_millis(250),
    };
    let mut w = Writer::open(&setup).unwrap();
    let events = EventQueue::new(4);
    let records = ArrayQueue::new(4);
    let probes = ArrayQueue::new(1);
    let mut r = record(1.0);
    r.offsets_um[0] = 2.0;
    r.targets_um[0] = 3.25;
    records.push(r).unwrap();
    w.collect(Queues {
        events: &events,
        records: &records,
        probes: &probes,
    });
    w.attempt();
    assert!(
        w.failure.is_none(),
        "{:?}",
        w.failure.as_ref().map(|f| &f.reason)
    );
    let (names, rows) = read_cycles(&db, None).unwrap();
    assert_eq!(names.last().map(String::as_str), Some("X_target_um"));
    assert_eq!(rows[0].last().map(String::as_str), Some(""));
    assert_eq!(rows[1].last().map(String::as_str), Some("3.25"));
    // A layout that is neither is still refused.
    drop(w);
    let c = Connection::open(&db).unwrap();
    c.execute_batch("ALTER TABLE cycles ADD COLUMN \"other\" REAL")
        .unwrap();
    assert!(Writer::open(&setup).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

/// While the log fails, the buffer keeps what fits; the rest is counted, and the count is
/// logged with the failure once writing resumes. (The failure here is a connection set
/// `query_only`; tests/log_faults.rs has the full disk.)
#[test]
fn what_does_not_fit_the_buffer_while_failing_is_counted_and_logged_on_resumption() {
    let dir = std::env::temp_dir().join(format!("truepos-logbuf-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let db = dir.join("log.sqlite");
    let machine = machine();
    let setup = LogSetup {
        path: &db,
        machine: &machine,
        models: vec!["m".into()],
        sources: vec![],
        sinks: vec!["csv out.csv".into()],
        paths: 1,
        commit_every: Duration::from_millis(250),
    };
    let mut w = Writer::open(&setup).unwrap();
    w.max_records = 5;
    w.max_events = 2;
    let events = EventQueue::new(64);
    let records = ArrayQueue::new(64);
    let probes = ArrayQueue::new(1);
    let queues = Queues {
        events: &events,
        records: &records,
        probes: &probes,
    };
    w.conn.pragma_update(None, "query_only", true).unwrap();
    for i in 0..8 {
        records.push(record(f64::from(i))).unwrap();
    }
    for _ in 0..3 {
        events.push(Event {
            time_s: 1.0,
            kind: EventKind::SinkFailed {
                sink: 0,
                reason: crate::events::Reason::new("disk full"),
            },
        });
    }
    w.collect(queues);
    w.attempt();
    assert!(w.failure.is_some());
    records.push(record(8.0)).unwrap();
    records.push(record(9.0)).unwrap();
    w.collect(queues);
    w.attempt();
    assert_eq!((w.health.records_dropped, w.health.events_dropped), (5, 1));
    w.conn.pragma_update(None, "query_only", false).unwrap();
    w.attempt();
    assert!(w.failure.is_none());
    assert_eq!(w.health.resumed, 1);
    let logged = read_events(&db).unwrap();
    let kinds: Vec<&str> = logged.iter().map(|e| e.kind.as_str()).collect();
    assert_eq!(
        kinds,
        ["sink-failed", "sink-failed", "log-failed", "log-resumed"]
    );
    assert_eq!(logged[0].detail, "disk full");
    assert!(logged[2].detail.contains("readonly"), "{logged:?}");
    assert!(
        logged[3]
            .detail
            .contains("5 records and 1 events dropped meanwhile"),
        "{logged:?}"
    );
    assert_eq!(read_cycles(&db, None).unwrap().1.len(), 5);
    std::fs::remove_dir_all(&dir).ok();
}
