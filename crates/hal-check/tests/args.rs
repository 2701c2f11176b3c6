//! `truepos-hal-check`'s numbers are checked at the door (issue 11): an out-of-range or non-finite
//! option is refused by name and range before anything starts — no panic, no hang.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `truepos-hal-check` with `args`, killed after 10 s (a hang); the exit code and stderr.
fn bounded(args: &[&str]) -> (i32, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_truepos-hal-check"))
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
            panic!(
                "`truepos-hal-check {}` still running after 10 s",
                args.join(" ")
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let code = out.status.code().unwrap_or(-1);
    (code, String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn non_finite_and_out_of_range_options_are_refused_by_name() {
    for (args, name, range) in [
        (
            &["timing", "--period-ms", "1e300"][..],
            "--period-ms",
            "[0.1, 1000]",
        ),
        (
            &["timing", "--duration-s", "nan"][..],
            "--duration-s",
            "[0.001, 86400]",
        ),
        (
            &["timing", "--sample-ms=-inf"][..],
            "--sample-ms",
            "[0.1, 60000]",
        ),
        (&["timing", "--cpu", "5000"][..], "--cpu", "from 0 to 1023"),
        (
            &[
                "check",
                "--machine",
                "m",
                "--model",
                "k",
                "--motion",
                "a",
                "--temperatures",
                "b",
                "--period-ms",
                "0",
            ][..],
            "--period-ms",
            "[0.1, 1000]",
        ),
    ] {
        let (code, err) = bounded(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(name) && err.contains(range), "{args:?}: {err}");
    }
}
