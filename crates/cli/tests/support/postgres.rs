//! PostgreSQL 15 for a test (Debian `postgresql`, installed by scripts/install_system_deps.sh):
//! a cluster of its own in the scratch directory on a free loopback port (`initdb`/`pg_ctl`,
//! as the `postgres` user when run as root), stopped and removed when dropped. Missing binaries
//! fail the test; it never skips. (The same steps as `fleet_mqtt.rs`'s.)
#![allow(dead_code)] // each test file uses a part

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A running cluster.
pub struct Postgres {
    data: PathBuf,
    pub port: u16,
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn pg_bin(name: &str) -> PathBuf {
    let p = PathBuf::from("/usr/lib/postgresql/15/bin").join(name);
    assert!(
        p.exists(),
        "{} is missing: run scripts/install_system_deps.sh (Debian package postgresql)",
        p.display()
    );
    p
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0\n"))
}

/// PostgreSQL refuses to run as root: as root, its commands run as the `postgres` user.
fn as_postgres(program: &Path) -> Command {
    if is_root() {
        let mut c = Command::new("runuser");
        c.args(["-u", "postgres", "--"]).arg(program);
        c
    } else {
        Command::new(program)
    }
}

pub fn run_ok(c: &mut Command, what: &str) {
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{what}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Postgres {
    /// initdb and start (pg_ctl waits until it accepts connections).
    pub fn start(dir: &Path) -> Self {
        let data = dir.join("pg");
        std::fs::create_dir_all(&data).unwrap();
        if is_root() {
            run_ok(
                Command::new("chown")
                    .args(["-R", "postgres:postgres"])
                    .arg(&data),
                "chown",
            );
        }
        let mut init = as_postgres(&pg_bin("initdb"));
        init.args(["-A", "trust", "-U", "postgres", "--no-sync", "-D"])
            .arg(&data);
        run_ok(&mut init, "initdb");
        let pg = Postgres {
            data,
            port: free_port(),
        };
        pg.pg_ctl_start();
        pg
    }

    /// Starts the cluster (again, after [`Postgres::stop`]); pg_ctl waits until it accepts
    /// connections, at most 60 s.
    pub fn pg_ctl_start(&self) {
        let mut c = as_postgres(&pg_bin("pg_ctl"));
        c.arg("-D").arg(&self.data).arg("-o").arg(format!(
            "-p {} -k {} -c listen_addresses=127.0.0.1 -c fsync=off",
            self.port,
            self.data.display()
        ));
        c.arg("-l")
            .arg(self.data.join("log"))
            .args(["-w", "-t", "60", "start"]);
        run_ok(&mut c, "pg_ctl start");
    }

    /// Stops the cluster (a fast shutdown), keeping its data.
    pub fn stop(&self) {
        let mut c = as_postgres(&pg_bin("pg_ctl"));
        c.arg("-D")
            .arg(&self.data)
            .args(["-m", "fast", "-w", "stop"]);
        run_ok(&mut c, "pg_ctl stop");
    }

    /// The URL `--db` takes.
    pub fn url(&self) -> String {
        format!("postgres://postgres@127.0.0.1:{}/postgres", self.port)
    }

    /// One query's rows through psql, fields joined by `,`, rows by newlines.
    pub fn query(&self, sql: &str) -> String {
        let out = Command::new("psql")
            .args([
                "-h",
                "127.0.0.1",
                "-U",
                "postgres",
                "-d",
                "postgres",
                "-At",
                "-F",
                ",",
            ])
            .args(["-p", &self.port.to_string(), "-c", sql])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{sql}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let mut c = as_postgres(&pg_bin("pg_ctl"));
        c.arg("-D")
            .arg(&self.data)
            .args(["-m", "immediate", "stop"]);
        let _ = c.output();
        // A cluster is ~40 MB: not left behind in the scratch directory.
        let _ = std::fs::remove_dir_all(&self.data);
    }
}
