//! The store's model moves against a real PostgreSQL 15 (as `batches.rs`: initdb/pg_ctl on a
//! free loopback port, never skipped): `activate_if` and `rollback_if` move only while the
//! active version is the one the caller judged — one activated in between is a conflict and
//! nothing changes.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;

use truepos_fleet_store::models::{self, Change, ModelError, NewModel, State};
use truepos_fleet_store::postgres::{Client, NoTls};
use truepos_fleet_store::schema;

fn pg_bin(name: &str) -> PathBuf {
    let p = PathBuf::from("/usr/lib/postgresql/15/bin").join(name);
    assert!(
        p.exists(),
        "{} is missing: run scripts/install_system_deps.sh (Debian package postgresql)",
        p.display()
    );
    p
}

/// PostgreSQL refuses to run as root: as root, its commands run as the `postgres` user.
fn as_postgres(program: &Path) -> Command {
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0\n"));
    if root {
        let mut c = Command::new("runuser");
        c.args(["-u", "postgres", "--"]).arg(program);
        c
    } else {
        Command::new(program)
    }
}

fn run_ok(c: &mut Command, what: &str) {
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{what}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A cluster of its own, stopped and removed when dropped.
struct Postgres {
    dir: PathBuf,
    port: u16,
}

impl Postgres {
    fn start() -> Self {
        let dir = std::env::temp_dir().join(format!("truepos-fleet-models-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let root = Command::new("id")
            .arg("-u")
            .output()
            .is_ok_and(|o| o.stdout.starts_with(b"0\n"));
        if root {
            run_ok(
                Command::new("chown").args(["postgres:postgres"]).arg(&dir),
                "chown",
            );
        }
        run_ok(
            as_postgres(&pg_bin("initdb"))
                .args(["-A", "trust", "-U", "postgres", "--no-sync", "-D"])
                .arg(&dir),
            "initdb",
        );
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        run_ok(
            as_postgres(&pg_bin("pg_ctl"))
                .arg("-D")
                .arg(&dir)
                .arg("-o")
                .arg(format!(
                    "-p {port} -k {} -c listen_addresses=127.0.0.1 -c fsync=off",
                    dir.display()
                ))
                .arg("-l")
                .arg(dir.join("log"))
                .args(["-w", "start"]),
            "pg_ctl start",
        );
        Postgres { dir, port }
    }

    fn connect(&self) -> Client {
        let url = format!("postgres://postgres@127.0.0.1:{}/postgres", self.port);
        Client::connect(&url, NoTls).unwrap()
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let _ = as_postgres(&pg_bin("pg_ctl"))
            .arg("-D")
            .arg(&self.dir)
            .args(["-m", "immediate", "stop"])
            .output();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
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
    let pg = Postgres::start();
    let mut db = pg.connect();
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
