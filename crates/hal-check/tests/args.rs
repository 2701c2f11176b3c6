//! `truepos-hal-check`'s numbers are checked at the door (issue 11): an out-of-range or non-finite
//! option is refused by name and range before anything starts — no panic, no hang.

#[path = "../../hal/tests/support/mod.rs"]
mod support;

/// Runs `truepos-hal-check` with `args`, killed after 10 s (a hang); the exit code and stderr.
fn bounded(args: &[&str]) -> (i32, String) {
    support::bounded(
        env!("CARGO_BIN_EXE_truepos-hal-check"),
        "truepos-hal-check",
        args,
    )
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
