//! The ingester's batches against a real PostgreSQL 15 (initdb/pg_ctl on a free loopback port,
//! as the `postgres` user when run as root; Debian's `postgresql`, installed by
//! scripts/install_system_deps.sh; never skipped): a batch's rows are written together, a row
//! the database refuses (here: a CHECK constraint the test adds) undoes only its own message,
//! and a message sent twice — in a later batch or twice in one — is written once.

use truepos_fleet::publisher::{birth_payload, unit_payload};
use truepos_fleet::sparkplug::{topic, MessageType};
use truepos_fleet::store::{Event, Second, Unit};
use truepos_fleet_store::ingest::Ingester;
use truepos_fleet_store::postgres::{Client, NoTls};
use truepos_fleet_store::schema;

/// A PostgreSQL 15 cluster of the test's own on a free loopback port (the CLI's tests' harness).
#[path = "../../cli/tests/support/postgres.rs"]
mod postgres_cluster;
use postgres_cluster::Postgres;

/// The cluster in a scratch directory of this test, and a connection to it.
fn start_postgres() -> (Postgres, Client) {
    let dir = std::env::temp_dir().join(format!(
        "truepos-fleet-{}-{}",
        "batches",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let pg = Postgres::start(&dir);
    let db = Client::connect(&pg.url(), NoTls).unwrap();
    (pg, db)
}

const T0_MS: u64 = 1_764_000_000_000;

fn columns() -> Vec<String> {
    ["t1", "spindle_rpm", "X_offset_um"]
        .map(String::from)
        .to_vec()
}

/// NDATA of node `n` for second `k` with `cycles` cycles, as a service sends it.
fn second(n: &str, k: u64, cycles: u32) -> (String, Vec<u8>) {
    let s = Unit::Second(Second {
        second: k as f64,
        last_row: k as i64,
        cycles,
        active: cycles,
        stats: vec![Some((20.0, 20.5, 21.0)), None, Some((-1.0, -0.5, 0.0))],
        new_run: false,
    });
    let t = T0_MS + 1000 * k;
    (
        topic("g", MessageType::NData, n),
        unit_payload(&s, 3, t, k % 256, false, t).encode(),
    )
}

fn event(n: &str, k: u64) -> (String, Vec<u8>) {
    let e = Unit::Event(Event {
        row: k as i64,
        time_s: k as f64,
        kind: "fault".into(),
        subject: "t1".into(),
        detail: "stuck".into(),
    });
    let t = T0_MS + 1000 * k + 500;
    (
        topic("g", MessageType::NData, n),
        unit_payload(&e, 3, t, k % 256, false, t).encode(),
    )
}

fn birth(n: &str) -> (String, Vec<u8>) {
    (
        topic("g", MessageType::NBirth, n),
        birth_payload(1, n, "m.json", &columns(), T0_MS).encode(),
    )
}

fn count(db: &mut Client, sql: &str) -> i64 {
    db.query_one(sql, &[]).unwrap().get(0)
}

#[test]
fn a_batch_is_written_together_and_a_refused_row_undoes_only_its_own_message() {
    let (_pg, mut db) = start_postgres();
    schema::migrate(&mut db).unwrap();
    // A value the database refuses (SQLSTATE 23514, check violation): 13 cycles.
    db.batch_execute(
        "ALTER TABLE fleet_seconds ADD CONSTRAINT unlucky CHECK (cycles IS DISTINCT FROM 13)",
    )
    .unwrap();
    let mut ingester = Ingester::default();

    // Two machines born and sending in one batch, with the same second twice in it.
    let mut batch = vec![birth("a"), birth("b")];
    for k in 0..5 {
        batch.push(second("a", k, 10));
        batch.push(second("b", k, 11));
    }
    batch.push(second("a", 4, 10));
    batch.push(event("a", 2));
    let s = ingester.store(&mut db, &batch).unwrap();
    assert_eq!((s.messages, s.seconds, s.events), (14, 10, 1));
    assert_eq!((s.duplicates, s.skipped), (1, 0));
    assert_eq!(count(&mut db, "SELECT count(*) FROM fleet_seconds"), 10);
    assert_eq!(count(&mut db, "SELECT count(*) FROM fleet_nodes"), 2);

    // The same again, with a new second among them whose value the database refuses and one
    // it takes: the refused message alone is skipped; the rest are there already or new.
    let mut again = batch.clone();
    again.push(second("b", 5, 13));
    again.push(second("b", 6, 12));
    let s = ingester.store(&mut db, &again).unwrap();
    assert_eq!((s.messages, s.seconds, s.events), (16, 1, 0));
    assert_eq!((s.duplicates, s.skipped), (12, 1));
    assert!(
        s.last_skip
            .as_deref()
            .is_some_and(|w| w.contains("refused by the database")),
        "{:?}",
        s.last_skip
    );
    assert_eq!(count(&mut db, "SELECT count(*) FROM fleet_seconds"), 11);
    assert_eq!(
        count(
            &mut db,
            "SELECT count(*) FROM fleet_seconds WHERE node_id = 'b' AND cycles = 12 \
             AND stats->'Inputs/t1'->>1 = '20.5' AND stats->'Inputs/spindle_rpm'->>0 IS NULL \
             AND stats->'Offsets/X_offset_um'->>0 = '-1.0'"
        ),
        1
    );
    assert_eq!(count(&mut db, "SELECT count(*) FROM fleet_events"), 1);

    // An ingester restarted mid-session reads NDATA with the aliases its births stored.
    let mut restarted = Ingester::default();
    let s = restarted.store(&mut db, &[second("a", 7, 9)]).unwrap();
    assert_eq!((s.seconds, s.skipped), (1, 0));
}
