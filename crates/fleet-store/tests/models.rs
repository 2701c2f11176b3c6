//! The store's model moves against a real PostgreSQL 15 (as `batches.rs`: initdb/pg_ctl on a
//! free loopback port, never skipped): `activate_if` and `rollback_if` move only while the
//! active version is the one the caller judged — one activated in between is a conflict and
//! nothing changes.

use truepos_fleet_store::models::{self, Change, ModelError, NewModel, State};
use truepos_fleet_store::postgres::{Client, NoTls};
use truepos_fleet_store::schema;

/// A PostgreSQL 15 cluster of the test's own on a free loopback port (the CLI's tests' harness).
#[path = "../../cli/tests/support/postgres.rs"]
mod postgres_cluster;
use postgres_cluster::Postgres;

/// The cluster in a scratch directory of this test, and a connection to it.
fn start_postgres() -> (Postgres, Client) {
    let dir =
        std::env::temp_dir().join(format!("truepos-fleet-{}-{}", "models", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let pg = Postgres::start(&dir);
    let db = Client::connect(&pg.url(), NoTls).unwrap();
    (pg, db)
}

const BY: Change<'static> = Change {
    by: Some("test"),
    reason: "test",
};

fn register(db: &mut Client, text: &str) -> i32 {
    let m = NewModel {
        machine: "vmc",
        file_name: "model.toml",
        bytes: text.as_bytes(),
        signature: "sig",
        public_key: &"0".repeat(64),
        provenance: serde_json::json!({}),
        validation: serde_json::json!({}),
    };
    models::register(db, &m, &BY).unwrap().version
}

fn active(db: &mut Client) -> Option<i32> {
    models::list(db, Some("vmc"))
        .unwrap()
        .iter()
        .find(|m| m.state == State::Active)
        .map(|m| m.version)
}

#[test]
fn a_move_judged_on_another_active_model_is_refused_and_changes_nothing() {
    let (_pg, mut db) = start_postgres();
    schema::migrate(&mut db).unwrap();
    let a = register(&mut db, "a");
    models::activate(&mut db, "vmc", a, &BY).unwrap();
    let b = register(&mut db, "b");
    let x = register(&mut db, "x");
    // A follower judged b against a; a person activated x in between.
    models::activate(&mut db, "vmc", x, &BY).unwrap();
    let changes = models::history(&mut db, "vmc").unwrap().len();
    match models::activate_if(&mut db, "vmc", b, Some(a), &BY) {
        Err(ModelError::Conflict {
            expected, active, ..
        }) => assert_eq!((expected, active), (a, Some(x))),
        other => panic!("{other:?}"),
    }
    // The follower watched b against a, rolled back while x is active: refused too.
    match models::rollback_if(&mut db, "vmc", Some(b), &BY) {
        Err(e @ ModelError::Conflict { .. }) => {
            assert!(e.to_string().contains("is 3 now, not 2"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(active(&mut db), Some(x));
    assert_eq!(models::history(&mut db, "vmc").unwrap().len(), changes);
    // Judged on the active one: they move.
    assert_eq!(
        models::activate_if(&mut db, "vmc", b, Some(x), &BY).unwrap(),
        Some(x)
    );
    assert_eq!(
        models::rollback_if(&mut db, "vmc", Some(b), &BY).unwrap(),
        (b, x)
    );
    assert_eq!(active(&mut db), Some(x));
    // Without an expected version, as before.
    assert!(models::rollback_if(&mut db, "vmc", None, &BY).is_ok());
    assert_eq!(active(&mut db), Some(a));
}
