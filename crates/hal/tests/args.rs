//! `truepos-hal`'s numbers are checked at the door (issue 11): an out-of-range or non-finite
//! option is refused by name and range before anything starts — no panic, no hang.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `truepos-hal` with `args`, killed after 10 s (a hang); the exit code and stderr.
fn bounded(args: &[&str]) -> (i32, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_truepos-hal"))
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
            panic!("`truepos-hal {}` still running after 10 s", args.join(" "));
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
            &[
                "run",
                "--machine",
                "m",
                "--model",
                "k",
                "--blend-s",
                "1e300",
            ][..],
            "--blend-s",
            "[0, 3600]",
        ),
        (
            &["run", "--machine", "m", "--model", "k", "--period-ms", "0"][..],
            "--period-ms",
            "[0.1, 1000]",
        ),
    ] {
        let (code, err) = bounded(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(name) && err.contains(range), "{args:?}: {err}");
    }
}
