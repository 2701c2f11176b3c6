//! Mosquitto for a test (Debian `mosquitto`, installed by scripts/install_system_deps.sh) on a
//! free loopback port, with its persistence in the scratch directory; killed when dropped.
//! A missing binary fails the test; it never skips.
#![allow(dead_code)] // each test file uses a part

use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Kills and reaps a child when dropped, so a failing assertion leaves nothing running.
pub struct Reaped(pub Child);

impl Drop for Reaped {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn mosquitto() -> PathBuf {
    for p in ["/usr/sbin/mosquitto", "/usr/bin/mosquitto"] {
        if Path::new(p).exists() {
            return p.into();
        }
    }
    panic!("mosquitto is missing: run scripts/install_system_deps.sh (Debian package mosquitto)");
}

/// A port nobody listens on now.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Starts Mosquitto on `port` with its persistence file in `dir` (saved every second) and no
/// limit on the messages it queues for a client that is away, waiting until it listens.
pub fn start(dir: &Path, port: u16) -> Reaped {
    let conf = config(dir, port, dir);
    let mut c = Command::new(mosquitto());
    c.arg("-c").arg(&conf);
    spawn(c, dir, port)
}

/// As [`start`], with the persistence directory `dir/full` a 1 MiB tmpfs filled to its last
/// block before the broker starts, in a mount namespace of the broker's own (`unshare`, as root
/// or as a user the kernel lets map itself to root). The directory as the broker sees it is
/// `/proc/<pid>/root/<dir>/full`.
pub fn start_on_full_disk(dir: &Path, port: u16) -> Reaped {
    let full = dir.join("full");
    std::fs::create_dir_all(&full).unwrap();
    let conf = config(dir, port, &full);
    let script = format!(
        "mount -t tmpfs -o size=1m tmpfs '{0}' && \
         (dd if=/dev/zero of='{0}/filler' bs=4k 2>/dev/null; true) && exec '{1}' -c '{2}'",
        full.display(),
        mosquitto().display(),
        conf.display()
    );
    let mut c = Command::new("unshare");
    c.args(["--mount", "--map-root-user", "sh", "-c", &script]);
    spawn(c, dir, port)
}

fn config(dir: &Path, port: u16, persistence: &Path) -> PathBuf {
    let conf = dir.join("mosquitto.conf");
    std::fs::write(
        &conf,
        format!(
            "listener {port} 127.0.0.1\nallow_anonymous true\npersistence true\n\
             persistence_location {}/\nautosave_interval 1\nmax_queued_messages 0\n\
             # As root Mosquitto would switch to its own user, who cannot write the scratch dir.\nuser root\n",
            persistence.display()
        ),
    )
    .unwrap();
    conf
}

fn spawn(mut c: Command, dir: &Path, port: u16) -> Reaped {
    let child = c
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("mosquitto.log")).unwrap())
        .spawn()
        .unwrap();
    let b = Reaped(child);
    let deadline = Instant::now() + Duration::from_secs(10);
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            Instant::now() < deadline,
            "mosquitto did not listen on {port} within 10 s: {}",
            std::fs::read_to_string(dir.join("mosquitto.log")).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    b
}
