//! Running one of the HAL binaries with a bound on its time, for `truepos-hal`'s tests and, by
//! path, `truepos-hal-check`'s: both refuse bad options at the door and must not hang instead.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs the binary `exe` (called `name` in messages) with `args` from the repository root,
/// killed after 10 s (a hang); the exit code and stderr.
pub fn bounded(exe: &str, name: &str, args: &[&str]) -> (i32, String) {
    let mut child = Command::new(exe)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            panic!("`{name} {}` still running after 10 s", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let code = out.status.code().unwrap_or(-1);
    (code, String::from_utf8_lossy(&out.stderr).into_owned())
}
