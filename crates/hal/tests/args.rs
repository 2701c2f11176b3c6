//! `truepos-hal`'s numbers are checked at the door (issue 11): an out-of-range or non-finite
//! option is refused by name and range before anything starts — no panic, no hang.

mod support;

/// Runs `truepos-hal` with `args`, killed after 10 s (a hang); the exit code and stderr.
fn bounded(args: &[&str]) -> (i32, String) {
    support::bounded(env!("CARGO_BIN_EXE_truepos-hal"), "truepos-hal", args)
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

/// The live view beyond loopback without a token is refused before the machine file is read
/// or HAL is touched (docs/live_view.md).
#[test]
fn a_live_view_beyond_loopback_without_a_token_is_refused_first() {
    std::env::remove_var("TRUEPOS_HTTP_TOKEN");
    let (code, err) = bounded(&[
        "run",
        "--machine",
        "no-such-machine.toml",
        "--model",
        "k",
        "--http",
        "0.0.0.0:8080",
    ]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("TRUEPOS_HTTP_TOKEN"), "{err}");
    assert!(!err.contains("no-such-machine"), "checked first: {err}");
}

/// `--mqtt` without a log, with a URL that is no broker or a node id MQTT would read as topic
/// levels, is refused before HAL is touched (docs/fleet.md): the telemetry is forwarded from the
/// log.
#[test]
fn mqtt_without_a_log_or_with_a_bad_url_is_refused_first() {
    for (extra, says) in [
        (&["--mqtt", "mqtt://127.0.0.1:1883"][..], "give --log"),
        (
            &["--mqtt", "http://broker", "--log", "x.sqlite"][..],
            "mqtt://HOST",
        ),
        (
            &["--mqtt", "mqtt://b", "--mqtt-node", "cell/7", "--log", "x"][..],
            "--mqtt-node `cell/7`",
        ),
    ] {
        let mut args = vec!["run", "--machine", "no-such-machine.toml", "--model", "k"];
        args.extend_from_slice(extra);
        let (code, err) = bounded(&args);
        assert_ne!(code, 0, "{err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!err.contains("no-such-machine"), "checked first: {err}");
    }
}
